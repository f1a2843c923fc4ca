/* 64-bit atomic min of the packed depth and id (the host requires the extension, ocl.cpp). */
#pragma OPENCL EXTENSION cl_khr_int64_base_atomics : enable
#pragma OPENCL EXTENSION cl_khr_int64_extended_atomics : enable
#include "shared/raster.h"

__kernel void vd_raster_pass(__global const float4* pos, __global const int* tris, VdPose T, VdCamera cam,
                             __global ulong* depth_id, __global VdRasterSetup* setups, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  vd_raster_triangle(pos, tris, get_global_id(0), T, cam, depth_id, setups);
}

__kernel void vd_raster_resolve(__global const float4* pos, __global const float4* nrm, __global const int* tris,
                                __global const VdRasterSetup* setups, VdPose T, VdCamera cam,
                                __global const ulong* depth_id, __global uint* ids, __global float4* vmap,
                                __global float4* nmap, __global float4* bary, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int i = get_global_id(0);
  const uint t = vd_raster_id(depth_id[i]);
  float4 v, n, b;
  vd_raster_resolve_pixel(pos, nrm, tris, setups, T, cam, i, t, &v, &n, &b);
  ids[i] = t;
  vmap[i] = v;
  nmap[i] = n;
  bary[i] = b;
}
