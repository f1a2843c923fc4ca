#include "shared/hierarchy.h"

/* One work item per fine active point: flags the 8 corners of its coarse cell (all writers store
 * 1, so the race is benign). */
__kernel void vd_level_mark(__global const int* list_f, VdVolume fine, int s, VdVolume coarse,
                            __global uchar* member, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int x, y, z;
  vd_grid_coords(list_f[get_global_id(0)], fine, &x, &y, &z);
  for (int o = 0; o < 8; ++o) member[vd_level_corner_index(x, y, z, s, coarse, o)] = 1;
}

/* One work item per coarse grid row: members per row, for the compaction scan. */
__kernel void vd_level_row_count(__global const uchar* member, VdVolume coarse, __global uint* row_count,
                                 int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int yz = get_global_id(0);
  uint n = 0u;
  for (int x = 0; x < coarse.dim_x; ++x) n += member[yz * coarse.dim_x + x];
  row_count[yz] = n;
}

__kernel void vd_level_restrict_kernel(__global const int* list_c, VdVolume coarse, int s,
                                       __global const int* compact_f, VdVolume fine, __global const float4* x_f,
                                       __global const float4* rot_f, __global float4* x0_c, __global float4* rot_c,
                                       int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int k = get_global_id(0);
  float4 r;
  x0_c[k] = vd_level_restrict(k, list_c, coarse, s, compact_f, fine, x_f, rot_f, &r);
  rot_c[k] = r;
}

__kernel void vd_level_constraints(__global const VdCorrespondence* cons_f, __global const int* compact_f,
                                   VdVolume fine, __global const float4* x_f, int s, __global const int* compact_c,
                                   VdVolume coarse, __global const float4* x0_c, __global VdCorrespondence* cons_c,
                                   int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int c = get_global_id(0);
  cons_c[c] = vd_level_constraint(cons_f[c], compact_f, fine, x_f, s, compact_c, coarse, x0_c);
}

__kernel void vd_level_prolongate_kernel(__global const int* list_f, VdVolume fine, int s,
                                         __global const int* compact_c, VdVolume coarse,
                                         __global const float4* x_c, __global const float4* x0_c,
                                         __global float4* x_f, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int k = get_global_id(0);
  x_f[k] = x_f[k] + vd_level_prolongate(k, list_f, fine, s, compact_c, coarse, x_c, x0_c);
}

/* One work item per coarse active point, as the first corner of a cell. */
__kernel void vd_level_moments_kernel(__global const int* list_c, VdVolume coarse, int s, __global const int* compact_f,
                                      VdVolume fine, __global const VdCorrespondence* cons,
                                      __global const uint* cell_start, __global const float4* x_f,
                                      __global float* moments_c, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  vd_level_moments(get_global_id(0), list_c, coarse, s, compact_f, fine, cons, cell_start, x_f, moments_c);
}
