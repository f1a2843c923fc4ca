#include "shared/marching_cubes.h"
#include "shared/tsdf.h"

/* vd_mc_classify walks a row by bricks and flags its cells by chunks: the two widths are one. */
#if VD_MC_CHUNK != VD_BRICK
#error "VD_MC_CHUNK must equal VD_BRICK"
#endif

/* All marching-cubes kernels run one work item per grid row (fixed y, z) looping over x. Offsets
 * within a row are running sums in that loop, so only the per-row totals need a device scan. */

/* A cell is valid only when its first corner holds weight, so the cells whose first corners lie
 * in an untouched brick (shared/tsdf.h) get code 0 without reading the grid. */
__kernel void vd_mc_classify(__global const float* tsdf, __global const float* weight, __global const uchar* touched,
                             VdVolume vol, __global const uchar* tri_counts, __global ushort* codes,
                             __global uint* row_tris, __global uchar* chunk_tris, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int yz = get_global_id(0);
  int y = yz % vol.dim_y, z = yz / vol.dim_y;
  int brick_row = vd_grid_brick(vol, 0, y, z);
  uint total = 0u;
  for (int x0 = 0; x0 < vol.dim_x; x0 += VD_BRICK) {
    int x1 = vd_min_i(x0 + VD_BRICK, vol.dim_x);
    uint chunk = 0u;
    if (!touched[brick_row + x0 / VD_BRICK]) {
      for (int x = x0; x < x1; ++x) codes[yz * vol.dim_x + x] = (ushort)0;
    } else {
      chunk = vd_mc_classify_run(tsdf, weight, vol, x0, x1, y, z, tri_counts, codes, yz * vol.dim_x);
    }
    chunk_tris[yz * vd_mc_chunks_x(vol) + x0 / VD_MC_CHUNK] = chunk > 0u ? (uchar)1 : (uchar)0;
    total += chunk;
  }
  row_tris[yz] = total;
}

__kernel void vd_mc_masks(__global const float* tsdf, __global const ushort* codes, __global const uint* row_tris,
                          __global const uchar* chunk_tris, VdVolume vol, __global uchar* masks,
                          __global uint* row_verts, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int yz = get_global_id(0);
  int y = yz % vol.dim_y, z = yz / vol.dim_y;
  if (!vd_mc_row_has_cells(row_tris, vol, y, z)) {
    for (int x = 0; x < vol.dim_x; ++x) masks[yz * vol.dim_x + x] = 0;
    row_verts[yz] = 0u;
    return;
  }
  uint total = 0u;
  for (int x0 = 0; x0 < vol.dim_x; x0 += VD_MC_CHUNK) {
    int x1 = vd_min_i(x0 + VD_MC_CHUNK, vol.dim_x);
    if (!vd_mc_chunk_near_cells(chunk_tris, vol, x0, x1, y, z)) {
      for (int x = x0; x < x1; ++x) masks[yz * vol.dim_x + x] = 0;
      continue;
    }
    for (int x = x0; x < x1; ++x) {
      uint m = vd_mc_vertex_mask(tsdf, codes, vol, x, y, z);
      masks[yz * vol.dim_x + x] = (uchar)m;
      total += (uint)vd_popcount3(m);
    }
  }
  row_verts[yz] = total;
}

/* Also records each vertex-owning grid point's first vertex index for the triangle pass. */
__kernel void vd_mc_vertices(__global const float* tsdf, __global const uint* color, VdVolume vol,
                             __global const uchar* masks, __global const uint* row_verts,
                             __global const uint* row_vert_offset, __global uint* vert_offset,
                             __global float4* positions, __global float4* normals, __global uint* colors,
                             int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int yz = get_global_id(0);
  if (row_verts[yz] == 0u) return;
  int y = yz % vol.dim_y, z = yz / vol.dim_y;
  uint out = row_vert_offset[yz];
  for (int x = 0; x < vol.dim_x; ++x) {
    int i = yz * vol.dim_x + x;
    uint m = masks[i];
    if (m == 0u) continue;
    vert_offset[i] = out;
    for (int a = 0; a < 3; ++a) {
      if (!(m & (1u << a))) continue;
      float4 p, n;
      uint c;
      vd_mc_make_vertex(tsdf, color, vol, x, y, z, a, &p, &n, &c);
      positions[out] = p;
      normals[out] = n;
      colors[out] = c;
      ++out;
    }
  }
}

__kernel void vd_mc_triangles(__global const ushort* codes, __global const uint* row_tris,
                              __global const uint* row_tri_offset, __global const char* tri_table,
                              __global const uchar* masks, __global const uint* vert_offset, VdVolume vol,
                              __global int* tris, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int yz = get_global_id(0);
  if (row_tris[yz] == 0u) return;
  int y = yz % vol.dim_y, z = yz / vol.dim_y;
  uint out = row_tri_offset[yz];
  for (int x = 0; x < vol.dim_x; ++x) {
    uint code = codes[yz * vol.dim_x + x];
    if (!(code & VD_MC_VALID)) continue;
    __global const char* row = tri_table + 16 * (code & 255u);
    for (int k = 0; row[k] >= 0; k += 3) {
      for (int c = 0; c < 3; ++c) tris[3 * out + c] = vd_mc_edge_vertex(masks, vert_offset, vol, x, y, z, row[k + c]);
      ++out;
    }
  }
}

/* Grid units to world metres: the rigid (undeformed) placement of marching-cubes vertices. */
__kernel void vd_grid_to_world(__global const float4* grid_pos, VdVolume vol, __global float4* world, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int i = get_global_id(0);
  float4 g = grid_pos[i];
  world[i] = (float4)(vol.origin.x + vol.voxel_size * g.x, vol.origin.y + vol.voxel_size * g.y,
                      vol.origin.z + vol.voxel_size * g.z, 1.0f);
}
