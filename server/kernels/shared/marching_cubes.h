/* Marching cubes on the TSDF grid with welded vertices.
 * Cell (x, y, z) has corners (x + i&1, y + (i>>1)&1, z + (i>>2)&1), i = 0..7; a corner is inside
 * when its distance is < 0. The cell is valid when all 8 corners were observed (weight > 0).
 * Edge e = axis * 4 + b0 + 2 * b1 starts at the corner with 0 along `axis` and (b0, b1) along the
 * other two axes in x, y, z order. Each grid point owns the vertices on the three edges leaving it
 * along +x, +y, +z; a vertex exists when its edge has a sign change and one of the up to four
 * cells sharing the edge is valid, which is exactly when some triangle uses it. The triangle table
 * (16 signed chars per cube index, -1 terminated) is generated on the host
 * (server/src/ocl/mc_table.cpp) and passed in. */
#ifndef VD_MARCHING_CUBES_H
#define VD_MARCHING_CUBES_H

#include "vd_types.h"

/* Cell codes: bit 8 = valid, bits 0..7 = cube index. */
#define VD_MC_VALID 0x100u

/* Cube index and validity from the distances d and weights w of a cell's 8 corners (corner i as
 * above): the one rule the dense grid and the brick pool (shared/sparse_mesh.h) share. */
VD_INLINE vd_uint vd_mc_code_from(const float* d, const float* w) {
  vd_uint code = 0u;
  for (int i = 0; i < 8; ++i) {
    if (!(w[i] > 0.0f)) return 0u;
    if (d[i] < 0.0f) code |= 1u << i;
  }
  return code | VD_MC_VALID;
}

VD_INLINE vd_uint vd_mc_cell_code(VD_GLOBAL const float* tsdf, VD_GLOBAL const float* weight, VdVolume vol, int x,
                                  int y, int z) {
  if (x >= vol.dim_x - 1 || y >= vol.dim_y - 1 || z >= vol.dim_z - 1) return 0u;
  float d[8], w[8];
  for (int i = 0; i < 8; ++i) {
    int idx = vd_grid_index(vol, x + (i & 1), y + ((i >> 1) & 1), z + ((i >> 2) & 1));
    d[i] = tsdf[idx];
    w[i] = weight[idx];
  }
  return vd_mc_code_from(d, w);
}

/* vd_mc_cell_code for the cells x0 .. x1 - 1 of row (y, z), written to codes[row_base + x]; returns
 * their triangles (tri_counts). Neighbouring cells share a face: each x column's four distances and
 * weights are read once and kept for the cell after it, half the reads of cell by cell. */
VD_INLINE vd_uint vd_mc_classify_run(VD_GLOBAL const float* tsdf, VD_GLOBAL const float* weight, VdVolume vol, int x0,
                                     int x1, int y, int z, VD_GLOBAL const vd_uchar* tri_counts,
                                     VD_GLOBAL vd_ushort* codes, int row_base) {
  vd_uint total = 0u;
  if (y >= vol.dim_y - 1 || z >= vol.dim_z - 1) {
    for (int x = x0; x < x1; ++x) codes[row_base + x] = (vd_ushort)0;
    return 0u;
  }
  /* Column x's corners r = dy + 2 dz (corner i of the cell: x offset i & 1, r = i >> 1). */
  int col[4];
  for (int r = 0; r < 4; ++r) col[r] = vd_grid_index(vol, 0, y + (r & 1), z + (r >> 1));
  float d0[4], w0[4];
  for (int r = 0; r < 4; ++r) {
    d0[r] = tsdf[col[r] + x0];
    w0[r] = weight[col[r] + x0];
  }
  for (int x = x0; x < x1; ++x) {
    if (x >= vol.dim_x - 1) {
      codes[row_base + x] = (vd_ushort)0;
      continue;
    }
    float d[8], w[8];
    for (int r = 0; r < 4; ++r) {
      d[2 * r] = d0[r];
      w[2 * r] = w0[r];
      d0[r] = d[2 * r + 1] = tsdf[col[r] + x + 1];
      w0[r] = w[2 * r + 1] = weight[col[r] + x + 1];
    }
    vd_uint code = vd_mc_code_from(d, w);
    codes[row_base + x] = (vd_ushort)code;
    total += (code & VD_MC_VALID) ? (vd_uint)tri_counts[code & 255u] : 0u;
  }
  return total;
}

/* Offsets from a grid point of the k-th (0..3) of the four cells sharing its edge along axis a:
 * -1 or 0 along each of the two other axes. */
VD_INLINE void vd_mc_edge_cell(int a, int k, int* ox, int* oy, int* oz) {
  int o0 = -(k & 1), o1 = -((k >> 1) & 1);
  *ox = a == 0 ? 0 : o0;
  *oy = a == 1 ? 0 : (a == 0 ? o0 : o1);
  *oz = a == 2 ? 0 : o1;
}

/* The axis of cube edge e, and the offsets from the cell's first corner of the grid point owning it. */
VD_INLINE int vd_mc_edge_owner(int e, int* ox, int* oy, int* oz) {
  int axis = e >> 2;
  int b0 = e & 1, b1 = (e >> 1) & 1;
  *ox = axis == 0 ? 0 : b0;
  *oy = axis == 1 ? 0 : (axis == 0 ? b0 : b1);
  *oz = axis == 2 ? 0 : b1;
  return axis;
}

/* Cell code of a neighbouring cell, 0 outside the grid. */
VD_INLINE vd_uint vd_mc_code_at(VD_GLOBAL const vd_ushort* codes, VdVolume vol, int x, int y, int z) {
  if (x < 0 || y < 0 || z < 0) return 0u;
  return codes[vd_grid_index(vol, x, y, z)];
}

/* Whether any cell row incident to grid row (y, z) (cell rows y-1..y, z-1..z) has triangles
 * (row_tris from vd_mc_classify). When none has, no edge of the row's points carries a vertex (a
 * valid cell with a sign change on an edge always emits triangles) and no point of the row is a
 * corner of a surface cell: the later passes write zeros without reading the grid. */
VD_INLINE int vd_mc_row_has_cells(VD_GLOBAL const vd_uint* row_tris, VdVolume vol, int y, int z) {
  for (int dz = -1; dz <= 0; ++dz)
    for (int dy = -1; dy <= 0; ++dy) {
      int cy = y + dy, cz = z + dz;
      if (cy < 0 || cz < 0 || cy >= vol.dim_y || cz >= vol.dim_z) continue;
      if (row_tris[cy + vol.dim_y * cz] > 0u) return 1;
    }
  return 0;
}

/* Chunks: the dense grid's per-row passes also keep one flag per VD_MC_CHUNK consecutive points of
 * a row (chunk c of row (y, z) at chunks[(y + dim_y z) * vd_mc_chunks_x + c]), so a later pass skips
 * the chunks far from any flagged one without reading the grid: a row that crosses the surface
 * crosses it in a few places. */
#define VD_MC_CHUNK 8
VD_INLINE int vd_mc_chunks_x(VdVolume vol) { return (vol.dim_x + VD_MC_CHUNK - 1) / VD_MC_CHUNK; }

/* Whether a flagged chunk holds a point of [xa, xb] x [ya, yb] x [za, zb] (clamped to the grid). */
VD_INLINE int vd_mc_chunks_any(VD_GLOBAL const vd_uchar* chunks, VdVolume vol, int xa, int xb, int ya, int yb, int za,
                               int zb) {
  xa = vd_max_i(xa, 0);
  xb = vd_min_i(xb, vol.dim_x - 1);
  ya = vd_max_i(ya, 0);
  yb = vd_min_i(yb, vol.dim_y - 1);
  za = vd_max_i(za, 0);
  zb = vd_min_i(zb, vol.dim_z - 1);
  int nc = vd_mc_chunks_x(vol);
  for (int z = za; z <= zb; ++z)
    for (int y = ya; y <= yb; ++y)
      for (int c = xa / VD_MC_CHUNK; c <= xb / VD_MC_CHUNK && xa <= xb; ++c)
        if (chunks[(y + vol.dim_y * z) * nc + c]) return 1;
  return 0;
}

/* Whether a point of chunk [x0, x1) of row (y, z) may be a corner of a cell with triangles (chunk
 * flags from vd_mc_classify): those cells' first corners lie in [x0 - 1, x1 - 1] x [y - 1, y] x
 * [z - 1, z]. Vertex owners and the active set's surface points are such corners. */
VD_INLINE int vd_mc_chunk_near_cells(VD_GLOBAL const vd_uchar* chunk_tris, VdVolume vol, int x0, int x1, int y, int z) {
  return vd_mc_chunks_any(chunk_tris, vol, x0 - 1, x1 - 1, y - 1, y, z - 1, z);
}

/* Bit a set when grid point (x, y, z) owns a vertex on its edge along axis a. */
VD_INLINE vd_uint vd_mc_vertex_mask(VD_GLOBAL const float* tsdf, VD_GLOBAL const vd_ushort* codes, VdVolume vol,
                                    int x, int y, int z) {
  int idx = vd_grid_index(vol, x, y, z);
  float d0 = tsdf[idx];
  vd_uint mask = 0u;
  for (int a = 0; a < 3; ++a) {
    int nx = x + (a == 0), ny = y + (a == 1), nz = z + (a == 2);
    if (nx >= vol.dim_x || ny >= vol.dim_y || nz >= vol.dim_z) continue;
    float d1 = tsdf[vd_grid_index(vol, nx, ny, nz)];
    if ((d0 < 0.0f) == (d1 < 0.0f)) continue;
    vd_uint any_valid = 0u;
    for (int k = 0; k < 4; ++k) {
      int ox, oy, oz;
      vd_mc_edge_cell(a, k, &ox, &oy, &oz);
      any_valid |= vd_mc_code_at(codes, vol, x + ox, y + oy, z + oz) & VD_MC_VALID;
    }
    if (any_valid) mask |= 1u << a;
  }
  return mask;
}

VD_INLINE int vd_popcount3(vd_uint m) { return (int)(m & 1u) + (int)((m >> 1) & 1u) + (int)((m >> 2) & 1u); }

/* Central-difference gradient of the distance at a grid point (one-sided at the border). */
VD_INLINE vd_float4 vd_tsdf_gradient(VD_GLOBAL const float* tsdf, VdVolume vol, int x, int y, int z) {
  int xm = vd_max_i(x - 1, 0), xp = vd_min_i(x + 1, vol.dim_x - 1);
  int ym = vd_max_i(y - 1, 0), yp = vd_min_i(y + 1, vol.dim_y - 1);
  int zm = vd_max_i(z - 1, 0), zp = vd_min_i(z + 1, vol.dim_z - 1);
  return VD_F4((tsdf[vd_grid_index(vol, xp, y, z)] - tsdf[vd_grid_index(vol, xm, y, z)]) / (float)(xp - xm),
               (tsdf[vd_grid_index(vol, x, yp, z)] - tsdf[vd_grid_index(vol, x, ym, z)]) / (float)(yp - ym),
               (tsdf[vd_grid_index(vol, x, y, zp)] - tsdf[vd_grid_index(vol, x, y, zm)]) / (float)(zp - zm), 0.0f);
}

/* The vertex on the edge along `axis` from grid point (x, y, z) (distance d0, TSDF gradient g0,
 * colour c0) to its next point (d1, g1, c1): position in grid units (x + t, ...), so a vertex
 * knows its cell and trilinear weights; outward normal; colour. */
VD_INLINE void vd_mc_vertex_from(float d0, float d1, vd_float4 g0, vd_float4 g1, vd_uint c0_packed, vd_uint c1_packed,
                                 int x, int y, int z, int axis, vd_float4* pos_grid, vd_float4* normal, vd_uint* rgba) {
  float t = d0 / (d0 - d1);
  t = vd_clampf(t, 0.0f, 1.0f);
  *pos_grid = VD_F4((float)x + (axis == 0 ? t : 0.0f), (float)y + (axis == 1 ? t : 0.0f),
                    (float)z + (axis == 2 ? t : 0.0f), 1.0f);
  *normal = vd_normalize3(g0 * (1.0f - t) + g1 * t);
  vd_float4 c0 = vd_unpack_rgba(c0_packed);
  vd_float4 c1 = vd_unpack_rgba(c1_packed);
  /* A corner never coloured contributes nothing; if neither is, the vertex is mid grey. */
  float w0 = c0.w > 0.0f ? (1.0f - t) : 0.0f;
  float w1 = c1.w > 0.0f ? t : 0.0f;
  vd_float4 c = (w0 + w1) > 0.0f ? (c0 * w0 + c1 * w1) / (w0 + w1) : VD_F4(128.0f, 128.0f, 128.0f, 255.0f);
  *rgba = vd_pack_rgba(c.x, c.y, c.z, 255.0f);
}

/* Writes the vertex on edge `axis` of grid point (x, y, z) (vd_mc_vertex_from). */
VD_INLINE void vd_mc_make_vertex(VD_GLOBAL const float* tsdf, VD_GLOBAL const vd_uint* color, VdVolume vol, int x,
                                 int y, int z, int axis, vd_float4* pos_grid, vd_float4* normal, vd_uint* rgba) {
  int nx = x + (axis == 0), ny = y + (axis == 1), nz = z + (axis == 2);
  int i0 = vd_grid_index(vol, x, y, z), i1 = vd_grid_index(vol, nx, ny, nz);
  vd_mc_vertex_from(tsdf[i0], tsdf[i1], vd_tsdf_gradient(tsdf, vol, x, y, z), vd_tsdf_gradient(tsdf, vol, nx, ny, nz),
                    color[i0], color[i1], x, y, z, axis, pos_grid, normal, rgba);
}

/* Index of the welded vertex on cube edge e of cell (x, y, z). */
VD_INLINE int vd_mc_edge_vertex(VD_GLOBAL const vd_uchar* masks, VD_GLOBAL const vd_uint* vert_offset, VdVolume vol,
                                int x, int y, int z, int e) {
  int ox, oy, oz;
  int axis = vd_mc_edge_owner(e, &ox, &oy, &oz);
  int owner = vd_grid_index(vol, x + ox, y + oy, z + oz);
  vd_uint below = (vd_uint)masks[owner] & ((1u << axis) - 1u);
  return (int)vert_offset[owner] + vd_popcount3(below);
}

#endif /* VD_MARCHING_CUBES_H */
