#include "shared/deformation.h"

__kernel void vd_deformation_reset(__global float4* def_pos, __global float4* def_rot, VdVolume vol, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int yz = get_global_id(0);
  vd_deformation_reset_row(def_pos, def_rot, yz % vol.dim_y, yz / vol.dim_y, vol);
}

/* Live (deformed) positions of the marching-cubes vertices. */
__kernel void vd_deform_vertices(__global const float4* grid_pos, __global const float4* def_pos, VdVolume vol,
                                 __global float4* out, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int i = get_global_id(0);
  out[i] = vd_deform_point(grid_pos[i], def_pos, vol);
}
