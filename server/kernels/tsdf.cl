#include "shared/tsdf.h"

__kernel void vd_tsdf_integrate(__global float* tsdf, __global float* weight, __global uint* color, VdVolume vol,
                                VdCamera cam, VdPose world_to_cam, __global const float* depth,
                                __global const uint* rgba) {
  vd_tsdf_integrate_voxel(tsdf, weight, color, get_global_id(0), vol, cam, world_to_cam, depth, rgba);
}
