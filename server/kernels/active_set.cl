#include "shared/active_set.h"

/* One work item per grid row (fixed y, z). Rows whose incident cell rows hold no triangles
 * (row_tris from marching cubes) are written as zeros without looking at the cells: most of the
 * grid is empty space. row_surface receives each row's surface point count. */
__kernel void vd_active_surface(__global const ushort* codes, __global const uchar* tri_counts,
                                __global const uint* row_tris, __global const uchar* chunk_tris, VdVolume vol,
                                __global uchar* surface, __global uint* row_surface, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int yz = get_global_id(0);
  int y = yz % vol.dim_y, z = yz / vol.dim_y;
  if (!vd_mc_row_has_cells(row_tris, vol, y, z)) {
    for (int x = 0; x < vol.dim_x; ++x) surface[yz * vol.dim_x + x] = 0;
    row_surface[yz] = 0u;
    return;
  }
  uint n = 0u;
  for (int x0 = 0; x0 < vol.dim_x; x0 += VD_MC_CHUNK) {
    int x1 = vd_min_i(x0 + VD_MC_CHUNK, vol.dim_x);
    if (!vd_mc_chunk_near_cells(chunk_tris, vol, x0, x1, y, z)) {
      for (int x = x0; x < x1; ++x) surface[yz * vol.dim_x + x] = 0;
      continue;
    }
    for (int x = x0; x < x1; ++x) {
      vd_uchar s = vd_active_surface_point(codes, tri_counts, vol, x, y, z);
      surface[yz * vol.dim_x + x] = s;
      n += s;
    }
  }
  row_surface[yz] = n;
}

/* One work item per row of row_len points (a dense grid row, or 8 points of a brick). */
__kernel void vd_active_in_view(__global const uchar* surface, __global const uint* row_surface,
                                __global const float4* def_pos, int row_len, VdCamera cam, VdPose world_to_cam,
                                float margin, __global uchar* solved, __global uint* row_solved, int vd_items) {
  int r = get_global_id(0);
  if (r >= vd_items) return;
  row_solved[r] = vd_active_in_view_row(r, row_len, surface, row_surface, def_pos, cam, world_to_cam, margin, solved);
}

__kernel void vd_active_dilate(__global const uchar* surface, __global const uint* row_surface, VdVolume vol,
                               __global uchar* member, __global uint* row_count, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int yz = get_global_id(0);
  int y = yz % vol.dim_y, z = yz / vol.dim_y;
  if (!vd_active_row_near_surface(row_surface, vol, y, z)) {
    for (int x = 0; x < vol.dim_x; ++x) member[yz * vol.dim_x + x] = 0;
    row_count[yz] = 0u;
    return;
  }
  uint n = 0u;
  for (int x = 0; x < vol.dim_x; ++x) {
    uchar m = vd_active_dilate_point(surface, vol, x, y, z);
    member[yz * vol.dim_x + x] = m;
    n += m;
  }
  row_count[yz] = n;
}

/* Writes the compact list (grid indices in row-major order) and the dense grid -> compact map; with
 * members_only, where compact already holds -1 at every non-member (the old members cleared by
 * vd_active_unmark), only the members are written and rows without any are skipped. */
__kernel void vd_active_compact(__global const uchar* member, __global const uint* row_offset, VdVolume vol,
                                int members_only, __global int* list, __global int* compact, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int yz = get_global_id(0);
  uint out = row_offset[yz];
  if (members_only && row_offset[yz + 1] == out) return;
  for (int x = 0; x < vol.dim_x; ++x) {
    int i = yz * vol.dim_x + x;
    if (member[i]) {
      list[out] = i;
      compact[i] = (int)out;
      ++out;
    } else if (!members_only) {
      compact[i] = -1;
    }
  }
}

/* compact[list[k]] = -1: one work item per member of the previous active set. */
__kernel void vd_active_unmark(__global const int* list, __global int* compact, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  compact[list[get_global_id(0)]] = -1;
}

/* One work item per active point. */
__kernel void vd_active_neighbours(__global const int* list, __global const int* compact, VdVolume vol,
                                   __global int* neighbours, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int k = get_global_id(0);
  int i = list[k];
  int x = i % vol.dim_x, yz = i / vol.dim_x;
  vd_active_neighbours_of(compact, vol, x, yz % vol.dim_y, yz / vol.dim_y, neighbours + 6 * k);
}
