#include "shared/correspondence.h"

__kernel void vd_correspondences(__global const float4* model_v, __global const float4* model_n,
                                 __global const uint* ids, __global const float4* bary, __global const float4* obs_v,
                                 __global const float4* obs_n, __global const float4* canon, __global const int* tris,
                                 __global const int* owners, VdCorrParams prm, __global VdCorrespondence* out, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int i = get_global_id(0);
  out[i] = vd_correspondence_pixel(i, model_v, model_n, ids, bary, obs_v, obs_n, canon, tris, owners, prm);
}

/* The colour rows after the image's n depth rows: one item per 2x2 block b, out[n + b] from the
 * depth row of its first pixel (vd_photo_pixel). */
__kernel void vd_photometric_correspondences(__global const float4* model_v, __global const float4* obs_v,
                                             __global const uint* ids, __global const float4* bary,
                                             __global const uint* colors, __global const int* tris,
                                             __global const float* intensity, VdPhotoParams prm,
                                             __global VdCorrespondence* out, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int b = get_global_id(0), n = prm.cam.width * prm.cam.height;
  int i = vd_photo_pixel(b, prm.cam.width);
  out[n + b] = vd_photometric_pixel(i, out[i], model_v, obs_v, ids, bary, colors, tris, intensity, prm);
}
