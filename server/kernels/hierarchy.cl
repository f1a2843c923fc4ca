#include "shared/hierarchy.h"

/* The fine and the coarse active sets on their lattices (shared/solver.h VdActive): the same five
 * arguments as solver.cl's VD_ACTIVE_ARGS, once per level, the brick buffers shared. */
#define VD_LEVELS_ARGS                                                                         \
  VdLattice lat_f, __global const int *list_f, __global const int *compact_f, VdLattice lat_c, \
      __global const int *list_c, __global const int *compact_c, __global const int *lat_nbr,  \
      __global const uint *slot_keys
#define VD_FINE vd_active(lat_f, lat_nbr, slot_keys, list_f, compact_f)
#define VD_COARSE vd_active(lat_c, lat_nbr, slot_keys, list_c, compact_c)

/* One work item per fine active point: flags the 8 corners of its coarse cell (all writers store
 * 1, so the race is benign; a corner whose brick is not allocated is skipped). */
__kernel void vd_level_mark(VdLattice fine, __global const int* lat_nbr, __global const int* list_f, int s,
                            VdLattice coarse, __global uchar* member, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int slot, x, y, z;
  vd_lattice_point(fine, list_f[get_global_id(0)], &slot, &x, &y, &z);
  int cx, cy, cz, e[8];
  vd_lattice_coarse_cell(coarse, s, x, y, z, &cx, &cy, &cz);
  vd_lattice_cell_entries(coarse, lat_nbr, slot, cx, cy, cz, e);
  for (int o = 0; o < 8; ++o)
    if (e[o] >= 0) member[e[o]] = 1;
}

/* One work item per row of `row` entries (a dense grid's x rows, or a brick's rows): members per
 * row, for the compaction scan. */
__kernel void vd_level_row_count(__global const uchar* member, int row, __global uint* row_count, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int r = get_global_id(0);
  uint n = 0u;
  for (int x = 0; x < row; ++x) n += member[r * row + x];
  row_count[r] = n;
}

/* One work item per coarse active point: its 6 compact neighbours (-x, +x, -y, +y, -z, +z). */
__kernel void vd_level_neighbours(VdLattice lat, __global const int* lat_nbr, __global const int* list,
                                  __global const int* compact, __global int* neighbours, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int k = get_global_id(0);
  int slot, x, y, z;
  vd_lattice_point(lat, list[k], &slot, &x, &y, &z);
  for (int d = 0; d < 6; ++d) {
    int s = (d & 1) ? 1 : -1;
    neighbours[6 * k + d] = vd_lattice_compact(lat, lat_nbr, compact, slot, x + (d >> 1 == 0 ? s : 0),
                                               y + (d >> 1 == 1 ? s : 0), z + (d >> 1 == 2 ? s : 0));
  }
}

/* One work item per coarse active point. */
__kernel void vd_level_restrict_kernel(VD_LEVELS_ARGS, int s, __global const float4* x_f, __global const float4* rot_f,
                                       __global float4* x0_c, __global float4* rot_c, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int k = get_global_id(0);
  float4 r;
  x0_c[k] = vd_level_restrict(k, VD_COARSE, s, VD_FINE, x_f, rot_f, &r);
  rot_c[k] = r;
}

/* One work item per sorted fine constraint (cell_f: each one's fine cell). */
__kernel void vd_level_constraints(VD_LEVELS_ARGS, int s, __global const VdCorrespondence* cons_f,
                                   __global const int* cell_f, __global const float4* x_f, __global const float4* x0_c,
                                   __global VdCorrespondence* cons_c, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int c = get_global_id(0);
  cons_c[c] = vd_level_constraint(cons_f[c], cell_f[c], VD_FINE, x_f, s, VD_COARSE, x0_c);
}

/* One work item per fine active point; adds to x_f. */
__kernel void vd_level_prolongate_kernel(VD_LEVELS_ARGS, int s, __global const float4* x_c, __global const float4* x0_c,
                                         __global float4* x_f, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int k = get_global_id(0);
  x_f[k] = x_f[k] + vd_level_prolongate(k, VD_FINE, s, VD_COARSE, x_c, x0_c);
}

/* One work item per coarse active point, as the first corner of a cell. */
__kernel void vd_level_moments_kernel(VD_LEVELS_ARGS, int s, __global const VdCorrespondence* cons,
                                      __global const uint* cell_start, __global const float4* x_f,
                                      __global float* moments_c, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  vd_level_moments(get_global_id(0), VD_COARSE, s, VD_FINE, cons, cell_start, x_f, moments_c);
}

/* One work item per active point of the upper level (VD_COARSE), as the first corner of a cell;
 * VD_FINE is the level below it (spacing ratio 2). */
__kernel void vd_level_moments_up_kernel(VD_LEVELS_ARGS, __global const float* moments_f, __global float* moments_c,
                                         int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  vd_level_moments_up(get_global_id(0), VD_COARSE, VD_FINE, moments_f, moments_c);
}

/* One work item per fine active point on the bricks: the bricks its coarse corners need (the
 * slots it hands out are read by later passes only). */
__kernel void vd_brick_level_alloc(__global const int* list_f, int s, __global const int* lat_nbr, __global uint* keys,
                                   __global int* slots, __global uint* slot_keys, uint capacity, uint pool,
                                   __global uint* counters, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  vd_brick_level_allocate(list_f[get_global_id(0)], s, lat_nbr, keys, slots, slot_keys, capacity, pool, counters);
}
