#include "shared/preprocess.h"

__kernel void vd_depth_convert(__global const ushort* raw, __global float* depth, float inv_scale, float min_depth,
                               float max_depth, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int i = get_global_id(0);
  depth[i] = vd_depth_convert_pixel(raw[i], inv_scale, min_depth, max_depth);
}

__kernel void vd_bilateral(__global const float* in, __global float* out, int width, int height, int radius,
                           float inv_2sigma_space2, float inv_2sigma_depth2, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int i = get_global_id(0);
  out[i] = vd_bilateral_pixel(in, width, height, i % width, i / width, radius, inv_2sigma_space2, inv_2sigma_depth2);
}

__kernel void vd_pyr_down(__global const float* in, __global float* out, int in_width, int out_width, float max_diff,
                          int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int i = get_global_id(0);
  out[i] = vd_pyr_down_pixel(in, in_width, i % out_width, i / out_width, max_diff);
}

__kernel void vd_vertex_map(__global const float* depth, __global float4* vmap, VdCamera cam, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int i = get_global_id(0);
  vmap[i] = vd_vertex_pixel(depth, cam, i % cam.width, i / cam.width);
}

__kernel void vd_normal_map(__global const float4* vmap, __global float4* nmap, int width, int height, float max_jump,
                            int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int i = get_global_id(0);
  nmap[i] = vd_normal_pixel(vmap, width, height, i % width, i / width, max_jump);
}
