#include "shared/raster.h"

__kernel void vd_raster_depth_pass(__global const float4* pos, __global const int* tris, VdPose T, VdCamera cam,
                                   __global uint* depth_bits, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  vd_raster_depth_triangle(pos, tris, get_global_id(0), T, cam, depth_bits);
}

__kernel void vd_raster_id_pass(__global const float4* pos, __global const int* tris, VdPose T, VdCamera cam,
                                __global const uint* depth_bits, __global uint* ids, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  vd_raster_id_triangle(pos, tris, get_global_id(0), T, cam, depth_bits, ids);
}

__kernel void vd_raster_resolve(__global const float4* pos, __global const float4* nrm, __global const int* tris,
                                VdPose T, VdCamera cam, __global const uint* ids, __global float4* vmap,
                                __global float4* nmap, __global float4* bary, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int i = get_global_id(0);
  float4 v, n, b;
  vd_raster_resolve_pixel(pos, nrm, tris, T, cam, i, ids, &v, &n, &b);
  vmap[i] = v;
  nmap[i] = n;
  bary[i] = b;
}
