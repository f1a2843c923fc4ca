/* Marching cubes over the brick pool of the sparse volume (issue 17; docs/SPARSE_VOLUME.md), with
 * the dense grid's rules (shared/marching_cubes.h): cell codes, welded vertices owned by the grid
 * point their edge leaves along +x, +y, +z, and the same vertex and normal math.
 *  - Neighbours: each pool slot keeps the slots of the 27 bricks around its own (itself at 13,
 *    -1 where none is allocated), built once per meshing from the table
 *    (vd_brick_neighbours_of), so the per-voxel passes read arrays instead of probing the hash.
 *  - A voxel of a brick that is not allocated reads as the dense grid's unobserved voxel: distance
 *    1 (at rest), weight 0, no colour. A cell with such a corner is therefore invalid, as a dense
 *    cell with an unobserved corner is, and the mesh over a pool equals the dense grid's over the
 *    same lattice wherever that grid's box holds the bricks with a voxel to spare (one-sided
 *    gradients at a dense grid's faces are the one difference).
 *  - Work items: one per row of 8 cells of a slot (slot * 64 + y + 8 z), as fusion's; positions are
 *    global grid coordinates (the bricks tile space from the world origin). */
#ifndef VD_SPARSE_MESH_H
#define VD_SPARSE_MESH_H

#include "marching_cubes.h"
#include "sparse_tsdf.h"

#define VD_BRICK_NEIGHBOURS 27
/* The brick itself among its neighbours. */
#define VD_BRICK_SELF 13
#define VD_BRICK_ROWS (VD_BRICK * VD_BRICK)

/* Index among the 27 of the brick at offset (dx, dy, dz), each -1..1. */
VD_INLINE int vd_brick_neighbour_index(int dx, int dy, int dz) { return (dx + 1) + 3 * (dy + 1) + 9 * (dz + 1); }

/* Writes the slots of the 27 bricks around the brick in `slot` (all -1 for a slot without one). */
VD_INLINE void vd_brick_neighbours_of(int slot, VD_GLOBAL const vd_uint* slot_keys, VD_GLOBAL const vd_uint* keys,
                                      VD_GLOBAL const int* slots, vd_uint capacity, VD_GLOBAL int* nbr) {
  vd_uint key = slot_keys[slot];
  int bx = 0, by = 0, bz = 0;
  if (key != VD_BRICK_EMPTY) vd_brick_unpack(key, &bx, &by, &bz);
  for (int n = 0; n < VD_BRICK_NEIGHBOURS; ++n) {
    int x = bx + n % 3 - 1, y = by + (n / 3) % 3 - 1, z = bz + n / 9 - 1;
    int s = -1;
    if (key != VD_BRICK_EMPTY && vd_brick_coords_valid(x, y, z))
      s = n == VD_BRICK_SELF ? slot : vd_brick_find(keys, slots, capacity, vd_brick_pack(x, y, z));
    nbr[VD_BRICK_NEIGHBOURS * slot + n] = s;
  }
}

/* Brick offset (-1, 0, 1) of a local coordinate -8..15 of a brick. */
VD_INLINE int vd_brick_step(int c) { return c < 0 ? -1 : (c >= VD_BRICK ? 1 : 0); }

/* Pool index of the voxel at local coordinates (x, y, z) of the brick in `slot`, each -8..15 (so
 * in that brick or one of its 26 neighbours), or -1 when its brick is not allocated. `slot` holds a
 * brick (every caller takes it from a member, a listed brick or the table), so a voxel of the brick
 * itself, most of them, needs no table read. */
VD_INLINE int vd_brick_voxel_at(VD_GLOBAL const int* nbr, int slot, int x, int y, int z) {
  int dx = vd_brick_step(x), dy = vd_brick_step(y), dz = vd_brick_step(z);
  int s = (dx | dy | dz) == 0 ? slot : nbr[VD_BRICK_NEIGHBOURS * slot + vd_brick_neighbour_index(dx, dy, dz)];
  if (s < 0) return -1;
  return s * VD_BRICK_VOXELS + (x - VD_BRICK * dx) + VD_BRICK * (y - VD_BRICK * dy) +
         VD_BRICK_ROWS * (z - VD_BRICK * dz);
}

/* Pool indices of the 8 corners (lx + ox, ly + oy, lz + oz), o = ox + 2 oy + 4 oz, of the cell whose
 * first corner is local point (lx, ly, lz) of `slot` (vd_brick_voxel_at's; all -1 for slot -1). A
 * cell inside the brick (most of them) takes its first corner's index plus fixed offsets. */
VD_INLINE void vd_brick_cell_voxels(VD_GLOBAL const int* nbr, int slot, int lx, int ly, int lz, int* v) {
  if (slot < 0) {
    for (int o = 0; o < 8; ++o) v[o] = -1;
    return;
  }
  if (lx >= 0 && ly >= 0 && lz >= 0 && lx < VD_BRICK - 1 && ly < VD_BRICK - 1 && lz < VD_BRICK - 1) {
    int v0 = slot * VD_BRICK_VOXELS + lx + VD_BRICK * ly + VD_BRICK_ROWS * lz;
    for (int o = 0; o < 8; ++o) v[o] = v0 + (o & 1) + VD_BRICK * ((o >> 1) & 1) + VD_BRICK_ROWS * (o >> 2);
    return;
  }
  for (int o = 0; o < 8; ++o) v[o] = vd_brick_voxel_at(nbr, slot, lx + (o & 1), ly + ((o >> 1) & 1), lz + (o >> 2));
}

/* The distance at a pool index, 1 (unobserved, at rest) for -1. */
VD_INLINE float vd_pool_tsdf(VD_GLOBAL const float* tsdf, int i) { return i < 0 ? 1.0f : tsdf[i]; }

/* 1 when the brick in `slot` holds weight in any of its 512 voxels. Every cell of a brick has its
 * origin corner there, so a brick without weight has only invalid cells (code 0), and every edge
 * leaving its points borders only those cells (mask 0): marching cubes writes zeros for it without
 * reading its neighbours. Such bricks are the non-rigid active set's ring and the coarse levels'
 * corners, allocated for the field and never fused. */
VD_INLINE int vd_sparse_brick_weighted(VD_GLOBAL const float* weight, int slot) {
  int base = slot * VD_BRICK_VOXELS;
  for (int i = 0; i < VD_BRICK_VOXELS; ++i)
    if (weight[base + i] > 0.0f) return 1;
  return 0;
}

/* Cell code of local cell (x, y, z) of `slot` (coordinates -1..7). */
VD_INLINE vd_uint vd_sparse_cell_code(VD_GLOBAL const float* tsdf, VD_GLOBAL const float* weight,
                                      VD_GLOBAL const int* nbr, int slot, int x, int y, int z) {
  float d[8], w[8];
  for (int i = 0; i < 8; ++i) {
    int idx = vd_brick_voxel_at(nbr, slot, x + (i & 1), y + ((i >> 1) & 1), z + ((i >> 2) & 1));
    d[i] = vd_pool_tsdf(tsdf, idx);
    w[i] = idx < 0 ? 0.0f : weight[idx];
  }
  return vd_mc_code_from(d, w);
}

/* vd_sparse_cell_code for the 8 cells of row (y, z) of `slot`, written to codes[slot's row]; returns
 * their triangles (tri_counts). The cells' corners are 4 rows of 9 points (the row, the row above
 * it, and both one layer up; the 9th point in the brick across the +x face): each is read once
 * instead of once per cell that shares it, and each row's brick is resolved once. */
VD_INLINE vd_uint vd_sparse_classify_row(VD_GLOBAL const float* tsdf, VD_GLOBAL const float* weight,
                                         VD_GLOBAL const int* nbr, int slot, int y, int z,
                                         VD_GLOBAL const vd_uchar* tri_counts, VD_GLOBAL vd_ushort* codes) {
  /* Corner row r = dy + 2 dz: distances and weights at x = 0..8 (unallocated: 1 and 0). */
  float d[4][VD_BRICK + 1], w[4][VD_BRICK + 1];
  for (int r = 0; r < 4; ++r) {
    int yy = y + (r & 1), zz = z + (r >> 1), by = yy >= VD_BRICK, bz = zz >= VD_BRICK;
    int row = (yy - VD_BRICK * by) * VD_BRICK + (zz - VD_BRICK * bz) * VD_BRICK_ROWS;
    int s = (by | bz) ? nbr[VD_BRICK_NEIGHBOURS * slot + vd_brick_neighbour_index(0, by, bz)] : slot;
    for (int x = 0; x < VD_BRICK; ++x) {
      d[r][x] = s < 0 ? 1.0f : tsdf[s * VD_BRICK_VOXELS + row + x];
      w[r][x] = s < 0 ? 0.0f : weight[s * VD_BRICK_VOXELS + row + x];
    }
    int s8 = nbr[VD_BRICK_NEIGHBOURS * slot + vd_brick_neighbour_index(1, by, bz)];
    d[r][VD_BRICK] = s8 < 0 ? 1.0f : tsdf[s8 * VD_BRICK_VOXELS + row];
    w[r][VD_BRICK] = s8 < 0 ? 0.0f : weight[s8 * VD_BRICK_VOXELS + row];
  }
  int base = slot * VD_BRICK_VOXELS + y * VD_BRICK + z * VD_BRICK_ROWS;
  vd_uint total = 0u;
  for (int x = 0; x < VD_BRICK; ++x) {
    float cd[8], cw[8];
    for (int i = 0; i < 8; ++i) {
      cd[i] = d[i >> 1][x + (i & 1)];
      cw[i] = w[i >> 1][x + (i & 1)];
    }
    vd_uint code = vd_mc_code_from(cd, cw);
    codes[base + x] = (vd_ushort)code;
    total += (code & VD_MC_VALID) ? (vd_uint)tri_counts[code & 255u] : 0u;
  }
  return total;
}

/* Vertex mask (bit a: a vertex on the edge along +a) of local point (x, y, z) of `slot`, from the
 * cell codes of every allocated brick (codes: one per pool voxel). */
VD_INLINE vd_uint vd_sparse_vertex_mask(VD_GLOBAL const float* tsdf, VD_GLOBAL const vd_ushort* codes,
                                        VD_GLOBAL const int* nbr, int slot, int x, int y, int z) {
  float d0 = tsdf[vd_brick_voxel_at(nbr, slot, x, y, z)];
  vd_uint mask = 0u;
  for (int a = 0; a < 3; ++a) {
    float d1 = vd_pool_tsdf(tsdf, vd_brick_voxel_at(nbr, slot, x + (a == 0), y + (a == 1), z + (a == 2)));
    if ((d0 < 0.0f) == (d1 < 0.0f)) continue;
    vd_uint any_valid = 0u;
    for (int k = 0; k < 4; ++k) {
      int ox, oy, oz;
      vd_mc_edge_cell(a, k, &ox, &oy, &oz);
      int c = vd_brick_voxel_at(nbr, slot, x + ox, y + oy, z + oz);
      if (c >= 0) any_valid |= (vd_uint)codes[c] & VD_MC_VALID;
    }
    if (any_valid) mask |= 1u << a;
  }
  return mask;
}

/* 0 when no point of row (y, z) of `slot` can own a vertex, from the triangle counts of the rows of
 * cells (row_tris, one per row of 8 cells of a slot, as vd_sparse_mc_classify writes them): a vertex
 * on an edge leaving point (x, y, z) borders only the cells with origins in [x-1, x] x [y-1, y] x
 * [z-1, z], and it is there only where one of them is valid, and a valid cell whose corners change
 * sign along an edge has triangles. So the rows (y-1..y, z-1..z) of this brick and of the brick
 * across its -x face (whose last cell is the x - 1 of point 0) decide; rows below 0 are the
 * neighbour bricks' last. Most rows of a brick hold no surface, and skipping them leaves the masks
 * exactly as computed (zero). */
VD_INLINE int vd_sparse_row_may_own_vertices(VD_GLOBAL const vd_uint* row_tris, VD_GLOBAL const int* nbr, int slot,
                                             int y, int z) {
  for (int dz = -1; dz <= 0; ++dz)
    for (int dy = -1; dy <= 0; ++dy) {
      int yy = y + dy, zz = z + dz, by = yy < 0 ? -1 : 0, bz = zz < 0 ? -1 : 0;
      int row = (yy - VD_BRICK * by) + VD_BRICK * (zz - VD_BRICK * bz);
      for (int bx = -1; bx <= 0; ++bx) {
        int s = nbr[VD_BRICK_NEIGHBOURS * slot + vd_brick_neighbour_index(bx, by, bz)];
        if (s >= 0 && row_tris[s * VD_BRICK_ROWS + row] != 0u) return 1;
      }
    }
  return 0;
}

/* Central-difference gradient of the distance at local point (x, y, z) of `slot`. */
VD_INLINE vd_float4 vd_sparse_gradient(VD_GLOBAL const float* tsdf, VD_GLOBAL const int* nbr, int slot, int x, int y,
                                       int z) {
  return VD_F4((vd_pool_tsdf(tsdf, vd_brick_voxel_at(nbr, slot, x + 1, y, z)) -
                vd_pool_tsdf(tsdf, vd_brick_voxel_at(nbr, slot, x - 1, y, z))) *
                   0.5f,
               (vd_pool_tsdf(tsdf, vd_brick_voxel_at(nbr, slot, x, y + 1, z)) -
                vd_pool_tsdf(tsdf, vd_brick_voxel_at(nbr, slot, x, y - 1, z))) *
                   0.5f,
               (vd_pool_tsdf(tsdf, vd_brick_voxel_at(nbr, slot, x, y, z + 1)) -
                vd_pool_tsdf(tsdf, vd_brick_voxel_at(nbr, slot, x, y, z - 1))) *
                   0.5f,
               0.0f);
}

/* The vertex on the edge along `axis` of local point (x, y, z) of `slot`, whose brick's key is
 * `key`: position in global grid coordinates, normal and colour (vd_mc_vertex_from). */
VD_INLINE void vd_sparse_make_vertex(VD_GLOBAL const float* tsdf, VD_GLOBAL const vd_uint* color,
                                     VD_GLOBAL const int* nbr, int slot, vd_uint key, int x, int y, int z, int axis,
                                     vd_float4* pos_grid, vd_float4* normal, vd_uint* rgba) {
  int nx = x + (axis == 0), ny = y + (axis == 1), nz = z + (axis == 2);
  int i0 = vd_brick_voxel_at(nbr, slot, x, y, z), i1 = vd_brick_voxel_at(nbr, slot, nx, ny, nz);
  int gx, gy, gz;
  vd_brick_voxel(key, x + VD_BRICK * (y + VD_BRICK * z), &gx, &gy, &gz);
  vd_mc_vertex_from(tsdf[i0], vd_pool_tsdf(tsdf, i1), vd_sparse_gradient(tsdf, nbr, slot, x, y, z),
                    vd_sparse_gradient(tsdf, nbr, slot, nx, ny, nz), color[i0], i1 < 0 ? 0u : color[i1], gx, gy, gz,
                    axis, pos_grid, normal, rgba);
}

/* Index of the welded vertex on cube edge e of local cell (x, y, z) of `slot`: the first vertex of
 * the owning point's row of 8 (row_vert_offset, the scan of the rows' vertex counts), then the
 * vertices of the points before it in that row and of its lower axes. Counted from the row's
 * masks rather than stored per point, which took 4 bytes per pool voxel (39 MB for a kitchen's
 * 16k bricks at 8 mm). */
VD_INLINE int vd_sparse_edge_vertex(VD_GLOBAL const vd_uchar* masks, VD_GLOBAL const vd_uint* row_vert_offset,
                                    VD_GLOBAL const int* nbr, int slot, int x, int y, int z, int e) {
  int ox, oy, oz;
  int axis = vd_mc_edge_owner(e, &ox, &oy, &oz);
  int owner = vd_brick_voxel_at(nbr, slot, x + ox, y + oy, z + oz);
  int row_start = owner - (owner % VD_BRICK);
  /* The row's 8 masks as one word (a row starts at a multiple of 8 bytes); a mask holds only its 3
   * low bits, so the word's bit count below the owner's byte is the vertices before it. */
  vd_ulong below_owner = (((vd_ulong)1) << (8 * (owner - row_start))) - 1; /* shift <= 56 */
#ifdef __OPENCL_C_VERSION__
  int before = (int)popcount(*(VD_GLOBAL const vd_ulong*)(masks + row_start) & below_owner);
#else
  vd_ulong row;
  memcpy(&row, masks + row_start, sizeof row);
  int before = __builtin_popcountll(row & below_owner);
#endif
  return (int)row_vert_offset[owner / VD_BRICK] + before + vd_popcount3((vd_uint)masks[owner] & ((1u << axis) - 1u));
}

/* The active set M over the pool (shared/active_set.h's rules: the corners of cells with triangles
 * and their 6-neighbourhood), pool voxel indices for grid indices. A member whose brick is not
 * allocated cannot hold a deformation: it is left out, and the neighbour pointing at it is -1. */

/* 1 when local point (x, y, z) of `slot` is a corner of a cell with triangles. */
VD_INLINE vd_uchar vd_sparse_surface_point(VD_GLOBAL const vd_ushort* codes, VD_GLOBAL const vd_uchar* tri_counts,
                                           VD_GLOBAL const int* nbr, int slot, int x, int y, int z) {
  for (int k = 0; k < 8; ++k) {
    int c = vd_brick_voxel_at(nbr, slot, x - (k & 1), y - ((k >> 1) & 1), z - ((k >> 2) & 1));
    if (c < 0) continue;
    vd_uint code = codes[c];
    if ((code & VD_MC_VALID) && tri_counts[code & 255u] > 0) return 1;
  }
  return 0;
}

/* Pool index of the d-th 6-neighbour (-x, +x, -y, +y, -z, +z) of local point (x, y, z) of `slot`,
 * -1 when its brick is not allocated. Only the coordinate along d's axis moves: inside the brick
 * one stride away, across its face the same point of the brick there with that coordinate wrapped
 * (vd_brick_voxel_at's index, without testing the two axes that stay). */
VD_INLINE int vd_sparse_face_neighbour(VD_GLOBAL const int* nbr, int slot, int x, int y, int z, int d) {
  int axis = d >> 1, s = (d & 1) ? 1 : -1;
  int c = axis == 0 ? x : (axis == 1 ? y : z), stride = axis == 0 ? 1 : (axis == 1 ? VD_BRICK : VD_BRICK_ROWS);
  int v = slot * VD_BRICK_VOXELS + x + VD_BRICK * y + VD_BRICK_ROWS * z;
  if (c + s >= 0 && c + s < VD_BRICK) return v + s * stride;
  int other = nbr[VD_BRICK_NEIGHBOURS * slot +
                  vd_brick_neighbour_index(axis == 0 ? s : 0, axis == 1 ? s : 0, axis == 2 ? s : 0)];
  return other < 0 ? -1 : v + (other - slot) * VD_BRICK_VOXELS - s * (VD_BRICK - 1) * stride;
}

/* 1 when local point (x, y, z) of `slot` is a surface point or a 6-neighbour of one. */
VD_INLINE vd_uchar vd_sparse_dilate_point(VD_GLOBAL const vd_uchar* surface, VD_GLOBAL const int* nbr, int slot, int x,
                                          int y, int z) {
  if (surface[vd_brick_voxel_at(nbr, slot, x, y, z)]) return 1;
  for (int d = 0; d < 6; ++d) {
    int i = vd_sparse_face_neighbour(nbr, slot, x, y, z, d);
    if (i >= 0 && surface[i]) return 1;
  }
  return 0;
}

/* The same two sets written from the other side, for passes that visit every point but find the
 * surface at few: a cell with triangles marks its 8 corners in `surface` (whose bricks exist), and
 * a surface point marks itself and its 6-neighbours in `member` (both start zeroed). Equal to the
 * sets above (the sparse mesh parity test holds the kernels to the CPU reference's gather). */
VD_INLINE void vd_sparse_mark_cell_corners(VD_GLOBAL const vd_ushort* codes, VD_GLOBAL const vd_uchar* tri_counts,
                                           VD_GLOBAL const int* nbr, int slot, int x, int y, int z,
                                           VD_GLOBAL vd_uchar* surface) {
  vd_uint code = codes[slot * VD_BRICK_VOXELS + x + VD_BRICK * y + VD_BRICK_ROWS * z];
  if (!((code & VD_MC_VALID) && tri_counts[code & 255u] > 0)) return;
  for (int k = 0; k < 8; ++k) {
    int c = vd_brick_voxel_at(nbr, slot, x + (k & 1), y + ((k >> 1) & 1), z + ((k >> 2) & 1));
    if (c >= 0) surface[c] = 1;
  }
}

VD_INLINE void vd_sparse_mark_dilated(VD_GLOBAL const vd_uchar* surface, VD_GLOBAL const int* nbr, int slot, int x,
                                      int y, int z, VD_GLOBAL vd_uchar* member) {
  int v = slot * VD_BRICK_VOXELS + x + VD_BRICK * y + VD_BRICK_ROWS * z;
  if (!surface[v]) return;
  member[v] = 1;
  for (int d = 0; d < 6; ++d) {
    int i = vd_sparse_face_neighbour(nbr, slot, x, y, z, d);
    if (i >= 0) member[i] = 1;
  }
}

/* Compact indices of the 6-neighbours of local point (x, y, z) of `slot` (-1 outside M or the
 * allocated bricks), in the order -x, +x, -y, +y, -z, +z. compact: pool voxel -> compact index. */
VD_INLINE void vd_sparse_neighbours_of(VD_GLOBAL const int* compact, VD_GLOBAL const int* nbr, int slot, int x, int y,
                                       int z, VD_GLOBAL int* out) {
  /* A point inside its brick (42 % of them) has its 6 neighbours there too. */
  if (x > 0 && y > 0 && z > 0 && x < VD_BRICK - 1 && y < VD_BRICK - 1 && z < VD_BRICK - 1) {
    int v = slot * VD_BRICK_VOXELS + x + VD_BRICK * y + VD_BRICK_ROWS * z;
    out[0] = compact[v - 1];
    out[1] = compact[v + 1];
    out[2] = compact[v - VD_BRICK];
    out[3] = compact[v + VD_BRICK];
    out[4] = compact[v - VD_BRICK_ROWS];
    out[5] = compact[v + VD_BRICK_ROWS];
    return;
  }
  for (int d = 0; d < 6; ++d) {
    int i = vd_sparse_face_neighbour(nbr, slot, x, y, z, d);
    out[d] = i >= 0 ? compact[i] : -1;
  }
}

/* Allocation for the one-ring (issue 17): a surface point on a face of its brick has a 6-neighbour
 * in the brick across that face, which the active set can hold only if that brick exists. For the
 * brick in `slot`, every face whose neighbour brick is missing and that holds a surface point gets
 * that brick allocated (vd_brick_allocate; it starts at rest, unobserved). Returns the failures. */
VD_INLINE int vd_brick_ring_allocate(int slot, VD_GLOBAL const vd_uchar* surface, VD_GLOBAL const int* nbr,
                                     VD_GLOBAL vd_uint* keys, VD_GLOBAL int* slots, VD_GLOBAL vd_uint* slot_keys,
                                     vd_uint capacity, vd_uint pool, VD_GLOBAL vd_uint* counters) {
  vd_uint key = slot_keys[slot];
  if (key == VD_BRICK_EMPTY) return 0;
  int bx, by, bz;
  vd_brick_unpack(key, &bx, &by, &bz);
  int failures = 0;
  for (int d = 0; d < 6; ++d) {
    int axis = d >> 1, side = (d & 1) ? 1 : -1;
    int ox = axis == 0 ? side : 0, oy = axis == 1 ? side : 0, oz = axis == 2 ? side : 0;
    if (nbr[VD_BRICK_NEIGHBOURS * slot + vd_brick_neighbour_index(ox, oy, oz)] >= 0) continue;
    /* The face's 64 points: the fixed coordinate is 0 or 7. */
    int fixed = side > 0 ? VD_BRICK - 1 : 0, any = 0;
    for (int a = 0; a < VD_BRICK && !any; ++a)
      for (int b = 0; b < VD_BRICK && !any; ++b) {
        int x = axis == 0 ? fixed : a, y = axis == 1 ? fixed : (axis == 0 ? a : b), z = axis == 2 ? fixed : b;
        any = surface[slot * VD_BRICK_VOXELS + x + VD_BRICK * (y + VD_BRICK * z)];
      }
    if (!any) continue;
    failures += vd_brick_allocate_at(keys, slots, slot_keys, capacity, pool, counters, bx + ox, by + oy, bz + oz);
  }
  return failures;
}

#endif /* VD_SPARSE_MESH_H */
