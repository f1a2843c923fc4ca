#include "shared/sparse_mesh.h"

/* Marching cubes over the brick pool (shared/sparse_mesh.h): one work item per row of 8 cells of
 * a slot (slot * 64 + y + 8 z), the dense passes' order within a row; a slot without a brick, or
 * with one that holds no weight, writes nothing but zero codes, masks and totals. */

/* One item per slot: 1 where an allocated brick holds weight (vd_sparse_brick_weighted), the only
 * bricks the passes below read. */
__kernel void vd_sparse_mc_weighted(__global const float* weight, __global const int* nbr, __global uchar* weighted,
                                    int vd_items) {
  int slot = get_global_id(0);
  if (slot >= vd_items) return;
  weighted[slot] =
      (uchar)(nbr[VD_BRICK_NEIGHBOURS * slot + VD_BRICK_SELF] >= 0 && vd_sparse_brick_weighted(weight, slot));
}

__kernel void vd_sparse_mc_classify(__global const float* tsdf, __global const float* weight, __global const int* nbr,
                                    __global const uchar* weighted, __global const uchar* tri_counts,
                                    __global ushort* codes, __global uint* row_tris, int vd_items) {
  int i = get_global_id(0);
  if (i >= vd_items) return;
  int slot = i / VD_BRICK_ROWS, y = i % VD_BRICK, z = (i / VD_BRICK) % VD_BRICK;
  if (!weighted[slot]) {
    int base = slot * VD_BRICK_VOXELS + (i % VD_BRICK_ROWS) * VD_BRICK;
    for (int x = 0; x < VD_BRICK; ++x) codes[base + x] = (ushort)0;
    row_tris[i] = 0u;
    return;
  }
  row_tris[i] = vd_sparse_classify_row(tsdf, weight, nbr, slot, y, z, tri_counts, codes);
}

__kernel void vd_sparse_mc_masks(__global const float* tsdf, __global const ushort* codes, __global const int* nbr,
                                 __global const uchar* weighted, __global const uint* row_tris, __global uchar* masks,
                                 __global uint* row_verts, int vd_items) {
  int i = get_global_id(0);
  if (i >= vd_items) return;
  int slot = i / VD_BRICK_ROWS, y = i % VD_BRICK, z = (i / VD_BRICK) % VD_BRICK;
  int base = slot * VD_BRICK_VOXELS + (i % VD_BRICK_ROWS) * VD_BRICK;
  int present = weighted[slot] && vd_sparse_row_may_own_vertices(row_tris, nbr, slot, y, z);
  uint total = 0u;
  for (int x = 0; x < VD_BRICK; ++x) {
    uint m = present ? vd_sparse_vertex_mask(tsdf, codes, nbr, slot, x, y, z) : 0u;
    masks[base + x] = (uchar)m;
    total += (uint)vd_popcount3(m);
  }
  row_verts[i] = total;
}

/* The triangle pass finds each vertex again from the row offsets and the masks (vd_sparse_edge_vertex). */
__kernel void vd_sparse_mc_vertices(__global const float* tsdf, __global const uint* color, __global const int* nbr,
                                    __global const uint* slot_keys, __global const uchar* masks,
                                    __global const uint* row_verts, __global const uint* row_vert_offset,
                                    __global float4* positions, __global float4* normals, __global uint* colors,
                                    __global int* owners, int vd_items) {
  int i = get_global_id(0);
  if (i >= vd_items || row_verts[i] == 0u) return;
  int slot = i / VD_BRICK_ROWS, y = i % VD_BRICK, z = (i / VD_BRICK) % VD_BRICK;
  int base = slot * VD_BRICK_VOXELS + (i % VD_BRICK_ROWS) * VD_BRICK;
  uint key = slot_keys[slot];
  uint out = row_vert_offset[i];
  for (int x = 0; x < VD_BRICK; ++x) {
    uint m = masks[base + x];
    if (m == 0u) continue;
    for (int a = 0; a < 3; ++a) {
      if (!(m & (1u << a))) continue;
      float4 p, n;
      uint c;
      vd_sparse_make_vertex(tsdf, color, nbr, slot, key, x, y, z, a, &p, &n, &c);
      positions[out] = p;
      normals[out] = n;
      colors[out] = c;
      owners[out] = slot;
      ++out;
    }
  }
}

__kernel void vd_sparse_mc_triangles(__global const ushort* codes, __global const uint* row_tris,
                                     __global const uint* row_tri_offset, __global const char* tri_table,
                                     __global const uchar* masks, __global const uint* row_vert_offset,
                                     __global const int* nbr, __global int* tris, int vd_items) {
  int i = get_global_id(0);
  if (i >= vd_items || row_tris[i] == 0u) return;
  int slot = i / VD_BRICK_ROWS, y = i % VD_BRICK, z = (i / VD_BRICK) % VD_BRICK;
  int base = slot * VD_BRICK_VOXELS + (i % VD_BRICK_ROWS) * VD_BRICK;
  uint out = row_tri_offset[i];
  for (int x = 0; x < VD_BRICK; ++x) {
    uint code = codes[base + x];
    if (!(code & VD_MC_VALID)) continue;
    __global const char* row = tri_table + 16 * (code & 255u);
    for (int k = 0; row[k] >= 0; k += 3) {
      for (int c = 0; c < 3; ++c)
        tris[3 * out + c] = vd_sparse_edge_vertex(masks, row_vert_offset, nbr, slot, x, y, z, row[k + c]);
      ++out;
    }
  }
}

/* The active set over the pool (shared/sparse_mesh.h), one work item per row of 8 points of a slot
 * as above, then one per member: surface and member start zeroed and are marked from the few cells
 * with triangles and the few surface points (vd_sparse_mark_*), then each row's members counted.
 * Slots without a brick mark nothing. */
__kernel void vd_sparse_active_surface(__global const ushort* codes, __global const uchar* tri_counts,
                                       __global const uint* row_tris, __global const int* nbr, __global uchar* surface,
                                       int vd_items) {
  int i = get_global_id(0);
  /* A row of cells without triangles marks nothing. */
  if (i >= vd_items || row_tris[i] == 0u) return;
  int slot = i / VD_BRICK_ROWS, y = i % VD_BRICK, z = (i / VD_BRICK) % VD_BRICK;
  if (nbr[VD_BRICK_NEIGHBOURS * slot + VD_BRICK_SELF] < 0) return;
  for (int x = 0; x < VD_BRICK; ++x) vd_sparse_mark_cell_corners(codes, tri_counts, nbr, slot, x, y, z, surface);
}

__kernel void vd_sparse_active_dilate(__global const uchar* surface, __global const int* nbr, __global uchar* member,
                                      int vd_items) {
  int i = get_global_id(0);
  if (i >= vd_items) return;
  int slot = i / VD_BRICK_ROWS, y = i % VD_BRICK, z = (i / VD_BRICK) % VD_BRICK;
  if (nbr[VD_BRICK_NEIGHBOURS * slot + VD_BRICK_SELF] < 0) return;
  for (int x = 0; x < VD_BRICK; ++x) vd_sparse_mark_dilated(surface, nbr, slot, x, y, z, member);
}

__kernel void vd_sparse_active_rows(__global const uchar* member, __global uint* row_count, int vd_items) {
  int i = get_global_id(0);
  if (i >= vd_items) return;
  uint n = 0u;
  for (int x = 0; x < VD_BRICK; ++x) n += member[i * VD_BRICK + x];
  row_count[i] = n;
}

/* The member list (pool voxel indices, in pool order) and the pool -> compact map. */
__kernel void vd_sparse_active_compact(__global const uchar* member, __global const uint* row_offset,
                                       __global int* list, __global int* compact, int vd_items) {
  int i = get_global_id(0);
  if (i >= vd_items) return;
  uint out = row_offset[i];
  for (int x = 0; x < VD_BRICK; ++x) {
    int v = i * VD_BRICK + x;
    if (member[v]) {
      list[out] = v;
      compact[v] = (int)out;
      ++out;
    } else {
      compact[v] = -1;
    }
  }
}

/* One work item per member. */
__kernel void vd_sparse_active_neighbours(__global const int* list, __global const int* compact,
                                          __global const int* nbr, __global int* neighbours, int vd_items) {
  int k = get_global_id(0);
  if (k >= vd_items) return;
  int v = list[k], slot = v / VD_BRICK_VOXELS, in_brick = v % VD_BRICK_VOXELS;
  vd_sparse_neighbours_of(compact, nbr, slot, in_brick % VD_BRICK, (in_brick / VD_BRICK) % VD_BRICK,
                          in_brick / VD_BRICK_ROWS, neighbours + 6 * k);
}

/* One work item per slot in use (the slots it hands out are read by later passes only). */
__kernel void vd_brick_ring_alloc(__global const uchar* surface, __global const int* nbr, __global uint* keys,
                                  __global int* slots, __global uint* slot_keys, uint capacity, uint pool,
                                  __global uint* counters, int vd_items) {
  int s = get_global_id(0);
  if (s >= vd_items) return;
  vd_brick_ring_allocate(s, surface, nbr, keys, slots, slot_keys, capacity, pool, counters);
}
