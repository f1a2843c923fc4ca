#include "shared/tsdf.h"

/* One work item per grid row (fixed y, z): the inner loop walks contiguous memory, which a CPU
 * device runs like a plain loop and a GPU still spreads over dim_y * dim_z items. */
__kernel void vd_tsdf_integrate(__global float* tsdf, __global float* weight, __global uint* color, VdVolume vol,
                                VdCamera cam, VdPose world_to_cam, __global const float* depth,
                                __global const uint* rgba, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int yz = get_global_id(0);
  vd_tsdf_integrate_row(tsdf, weight, color, yz % vol.dim_y, yz / vol.dim_y, vol, cam, world_to_cam, depth, rgba);
}

/* Non-rigid fusion: one work item per active grid point. */
__kernel void vd_tsdf_integrate_active(__global float* tsdf, __global float* weight, __global uint* color,
                                       __global const int* list, __global const float4* def_pos, float k_min,
                                       VdVolume vol, VdCamera cam, VdPose world_to_cam, __global const float* depth,
                                       __global const uint* rgba, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int gi = list[get_global_id(0)];
  vd_tsdf_integrate_deformed(tsdf, weight, color, gi, def_pos[gi], k_min, vol, cam, world_to_cam, depth, rgba);
}
