/* The points a hierarchy level of the non-rigid solver lives on (docs/SPARSE_VOLUME.md "The
 * solver on a lattice"): one dense grid, or the bricks of the sparse volume's pool. The solver's
 * and the hierarchy's per-item math (shared/solver.h, shared/hierarchy.h) name points only through
 * these functions, so the same kernels run on both.
 *  - An *entry* indexes the per-point arrays (the field, the active set's grid -> compact map):
 *    on a dense grid the grid index x + dim_x (y + dim_y z); on bricks slot * n^3 + local, n the
 *    points per brick side at this level (8 on the fine level, 8 / s on a level of spacing s).
 *  - A point is addressed as (slot, x, y, z): local coordinates in the brick in `slot`. A dense grid
 *    is one brick (slot 0) as large as the grid, so local coordinates are grid coordinates.
 *  - Neighbours across brick faces come through the per-brick table of the 27 neighbours' slots
 *    (shared/sparse_mesh.h), shared by every level, since a coarse level's bricks are the fine
 *    level's (s divides 8, so each coarse point lies in exactly one brick); a dense grid passes a
 *    table that is never read.
 *  - Global coordinates (the frame of the constraints' canonical positions at this level): grid
 *    coordinates on a dense grid, the brick's coordinates times n plus local ones on bricks. */
#ifndef VD_LATTICE_H
#define VD_LATTICE_H

#include "brick_hash.h"
#include "vd_types.h"

typedef struct {
  /* Position of global coordinates (0, 0, 0): the dense grid's origin; 0 on bricks, which tile
   * space from the world origin. */
  vd_float4 origin;
  /* Dense: the grid's points per axis. Bricks: points per brick side at this level, all three. */
  int dim_x, dim_y, dim_z;
  /* Metres between neighbouring points (the voxel size times the level's spacing). */
  float spacing;
  /* 0: one dense grid; 1: the pool's bricks. */
  int bricks;
  /* Bricks: log2 of the points a side (a power of two), so that an entry splits into slot and local
   * coordinates by shifts and masks: an integer division by a kernel argument is scalar on a CPU
   * device, and every solver kernel splits entries. 0 on a dense grid, which divides. */
  int log2_dim;
  /* Padding keeps the struct a multiple of 16 bytes on both sides. */
  int pad1, pad2;
} VdLattice;

/* The lattice of a dense grid (its own spacing). */
VD_INLINE VdLattice vd_lattice_dense(VdVolume vol) {
  VdLattice l;
  l.origin = vol.origin;
  l.dim_x = vol.dim_x;
  l.dim_y = vol.dim_y;
  l.dim_z = vol.dim_z;
  l.spacing = vol.voxel_size;
  l.bricks = 0;
  l.log2_dim = 0;
  l.pad1 = l.pad2 = 0;
  return l;
}

/* The lattice of the pool's bricks at spacing s (1: the fine level) for voxels of voxel_size. */
VD_INLINE VdLattice vd_lattice_bricks(float voxel_size, int s) {
  VdLattice l;
  l.origin = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  l.dim_x = l.dim_y = l.dim_z = VD_BRICK / s;
  l.spacing = voxel_size * (float)s;
  l.bricks = 1;
  l.log2_dim = 0;
  while ((1 << l.log2_dim) < l.dim_x) ++l.log2_dim;
  l.pad1 = l.pad2 = 0;
  return l;
}

/* Level s (a power of two; at most 8 on bricks) above fine lattice l: a dense grid of s times the
 * spacing over the same extent with enough points that every fine point lies in a coarse cell, or
 * the same bricks with n / s points a side. */
VD_INLINE VdLattice vd_lattice_level(VdLattice l, int s) {
  VdLattice c = l;
  c.spacing = l.spacing * (float)s;
  if (l.bricks) {
    c.dim_x = l.dim_x / s;
    c.dim_y = l.dim_y / s;
    c.dim_z = l.dim_z / s;
    c.log2_dim = 0;
    while ((1 << c.log2_dim) < c.dim_x) ++c.log2_dim;
  } else {
    c.dim_x = (l.dim_x - 1) / s + 2;
    c.dim_y = (l.dim_y - 1) / s + 2;
    c.dim_z = (l.dim_z - 1) / s + 2;
  }
  return c;
}

/* Points per brick (the whole grid on a dense one). */
VD_INLINE int vd_lattice_brick_points(VdLattice l) { return l.dim_x * l.dim_y * l.dim_z; }

/* The brick slot and local coordinates of an entry. */
VD_INLINE void vd_lattice_point(VdLattice l, int entry, int* slot, int* x, int* y, int* z) {
  if (l.bricks) {
    int sh = l.log2_dim, mask = (1 << sh) - 1;
    *slot = entry >> (3 * sh);
    *x = entry & mask;
    *y = (entry >> sh) & mask;
    *z = (entry >> (2 * sh)) & mask;
    return;
  }
  int per = vd_lattice_brick_points(l);
  *slot = entry / per;
  int i = entry - *slot * per;
  *x = i % l.dim_x;
  *y = (i / l.dim_x) % l.dim_y;
  *z = i / (l.dim_x * l.dim_y);
}

/* The entry of the point at local coordinates (x, y, z) of the brick in `slot`, -1 where there is
 * none: outside a dense grid, or in a neighbour brick that is not allocated. On bricks each
 * coordinate must lie within one brick side of the brick (-n .. 2n - 1). */
VD_INLINE int vd_lattice_entry(VdLattice l, VD_GLOBAL const int* nbr, int slot, int x, int y, int z) {
  if (!l.bricks) {
    if (x < 0 || y < 0 || z < 0 || x >= l.dim_x || y >= l.dim_y || z >= l.dim_z) return -1;
    return x + l.dim_x * (y + l.dim_y * z);
  }
  int dx = x < 0 ? -1 : (x >= l.dim_x ? 1 : 0), dy = y < 0 ? -1 : (y >= l.dim_y ? 1 : 0),
      dz = z < 0 ? -1 : (z >= l.dim_z ? 1 : 0);
  /* Most points lie in the brick itself, which needs no table read. */
  int s = (dx | dy | dz) == 0 ? slot : nbr[27 * slot + (dx + 1) + 3 * (dy + 1) + 9 * (dz + 1)];
  if (s < 0) return -1;
  int sh = l.log2_dim;
  return (s << (3 * sh)) + (x - dx * l.dim_x) + (((y - dy * l.dim_y) + ((z - dz * l.dim_z) << sh)) << sh);
}

/* 1 when every point within r of local point (x, y, z) (each coordinate +-r) lies in the same
 * brick (the same dense grid): their entries are then the point's plus vd_lattice_offset, with
 * no table read and no bounds test. */
VD_INLINE int vd_lattice_interior(VdLattice l, int x, int y, int z, int r) {
  return x >= r && y >= r && z >= r && x < l.dim_x - r && y < l.dim_y - r && z < l.dim_z - r;
}

/* Entry of the point (dx, dy, dz) away from another of the same brick (vd_lattice_interior). */
VD_INLINE int vd_lattice_offset(VdLattice l, int dx, int dy, int dz) { return dx + l.dim_x * (dy + l.dim_y * dz); }

/* The entries of the 8 corners (x + ox, y + oy, z + oz), o = ox + 2 oy + 4 oz, of the cell whose
 * first corner is local point (x, y, z) of the brick in `slot` (vd_lattice_entry's, -1 where there
 * is none); a cell inside the brick (most of them) by offsets from its first corner. */
VD_INLINE void vd_lattice_cell_entries(VdLattice l, VD_GLOBAL const int* nbr, int slot, int x, int y, int z, int* e) {
  if (x >= 0 && y >= 0 && z >= 0 && x < l.dim_x - 1 && y < l.dim_y - 1 && z < l.dim_z - 1) {
    int e0 = vd_lattice_entry(l, nbr, slot, x, y, z);
    for (int o = 0; o < 8; ++o) e[o] = e0 + vd_lattice_offset(l, o & 1, (o >> 1) & 1, (o >> 2) & 1);
    return;
  }
  for (int o = 0; o < 8; ++o)
    e[o] = vd_lattice_entry(l, nbr, slot, x + (o & 1), y + ((o >> 1) & 1), z + ((o >> 2) & 1));
}

/* The last x of the run that starts at local x and ends at most at x_last, over which entries are
 * consecutive (entry(x + i) = entry(x) + i, all present or all absent): runs break where a brick
 * (or a dense grid) begins and ends, at 0 and dim_x. Walking a window by runs looks up one entry
 * per run instead of one per point, in the same point order. */
VD_INLINE int vd_lattice_run_end(VdLattice l, int x, int x_last) {
  int end = x < 0 ? -1 : (x < l.dim_x ? l.dim_x - 1 : x_last);
  return end < x_last ? end : x_last;
}

/* The active (compact) index of that point, -1 outside M or where there is no point. */
VD_INLINE int vd_lattice_compact(VdLattice l, VD_GLOBAL const int* nbr, VD_GLOBAL const int* compact, int slot, int x,
                                 int y, int z) {
  int e = vd_lattice_entry(l, nbr, slot, x, y, z);
  return e < 0 ? -1 : compact[e];
}

/* Global coordinates of local point (x, y, z) of the brick in `slot`. */
VD_INLINE void vd_lattice_global(VdLattice l, VD_GLOBAL const vd_uint* slot_keys, int slot, int x, int y, int z,
                                 int* gx, int* gy, int* gz) {
  *gx = x;
  *gy = y;
  *gz = z;
  if (!l.bricks) return;
  int bx, by, bz;
  vd_brick_unpack(slot_keys[slot], &bx, &by, &bz);
  *gx += bx * l.dim_x;
  *gy += by * l.dim_y;
  *gz += bz * l.dim_z;
}

/* Rest position (metres) of local point (x, y, z) of the brick in `slot`; w = 0. */
VD_INLINE vd_float4 vd_lattice_position(VdLattice l, VD_GLOBAL const vd_uint* slot_keys, int slot, int x, int y,
                                        int z) {
  int gx, gy, gz;
  vd_lattice_global(l, slot_keys, slot, x, y, z, &gx, &gy, &gz);
  return VD_F4(l.origin.x + l.spacing * (float)gx, l.origin.y + l.spacing * (float)gy,
               l.origin.z + l.spacing * (float)gz, 0.0f);
}

/* The first corner of the cell of a coarse lattice (spacing ratio s) that holds fine point
 * (x, y, z) of a brick, in local coordinates of the same brick: x / s, on a dense grid kept one
 * point inside the last row so that the cell's far corners exist. */
VD_INLINE void vd_lattice_coarse_cell(VdLattice coarse, int s, int x, int y, int z, int* cx, int* cy, int* cz) {
  if (coarse.bricks) {
    /* Local coordinates are not negative and s is a power of two: a shift (see log2_dim). */
    int k = 0;
    while ((1 << k) < s) ++k;
    *cx = x >> k;
    *cy = y >> k;
    *cz = z >> k;
    return;
  }
  *cx = x / s;
  *cy = y / s;
  *cz = z / s;
  *cx = vd_min_i(*cx, coarse.dim_x - 2);
  *cy = vd_min_i(*cy, coarse.dim_y - 2);
  *cz = vd_min_i(*cz, coarse.dim_z - 2);
}

#endif /* VD_LATTICE_H */
