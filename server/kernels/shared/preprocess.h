/* Per-pixel depth preprocessing: conversion with clipping, bilateral filter, pyramid, vertex and
 * normal maps. Depth maps are float metres with 0 for invalid. Vertex/normal maps are float4
 * with w = 1 where valid and w = 0 where not. */
#ifndef VD_PREPROCESS_H
#define VD_PREPROCESS_H

#include "vd_types.h"

/* Raw uint16 depth to metres, invalid outside [min_depth, max_depth]. */
VD_INLINE float vd_depth_convert_pixel(vd_ushort raw, float inv_scale, float min_depth, float max_depth) {
  float d = (float)raw * inv_scale;
  return (raw != 0 && d >= min_depth && d <= max_depth) ? d : 0.0f;
}

/* The weight of a tap at squared pixel distance ds whose depth differs by dd from the centre's; a
 * macro so that the laned kernel (vd_lf dd) and the per-pixel reference share it. */
#define VD_BILATERAL_WEIGHT(dd, ds, inv_2sigma_space2, inv_2sigma_depth2) \
  exp(-(ds) * (inv_2sigma_space2) - (dd) * (dd) * (inv_2sigma_depth2))

/* Edge-preserving smoothing of one pixel (radius in pixels; sigmas in pixels and metres). */
VD_INLINE float vd_bilateral_pixel(VD_GLOBAL const float* depth, int width, int height, int x, int y, int radius,
                                   float inv_2sigma_space2, float inv_2sigma_depth2) {
  float d0 = depth[y * width + x];
  if (d0 <= 0.0f) return 0.0f;
  float sum = 0.0f;
  float wsum = 0.0f;
  int y0 = vd_max_i(y - radius, 0), y1 = vd_min_i(y + radius, height - 1);
  int x0 = vd_max_i(x - radius, 0), x1 = vd_min_i(x + radius, width - 1);
  for (int yy = y0; yy <= y1; ++yy) {
    for (int xx = x0; xx <= x1; ++xx) {
      float d = depth[yy * width + xx];
      float dd = d - d0;
      float ds = (float)((xx - x) * (xx - x) + (yy - y) * (yy - y));
      float w = (d > 0.0f) ? VD_BILATERAL_WEIGHT(dd, ds, inv_2sigma_space2, inv_2sigma_depth2) : 0.0f;
      sum += w * d;
      wsum += w;
    }
  }
  return sum / wsum;
}

/* Half-resolution pixel: mean of the 2x2 block's valid depths within max_diff of the block's
 * first valid depth, so averages never straddle a depth edge. */
VD_INLINE float vd_pyr_down_pixel(VD_GLOBAL const float* depth, int width, int x, int y, float max_diff) {
  int sx = 2 * x, sy = 2 * y;
  float ref = 0.0f;
  float sum = 0.0f;
  float n = 0.0f;
  for (int k = 0; k < 4; ++k) {
    float d = depth[(sy + (k >> 1)) * width + sx + (k & 1)];
    if (d > 0.0f && ref == 0.0f) ref = d;
    if (d > 0.0f && fabs(d - ref) <= max_diff) {
      sum += d;
      n += 1.0f;
    }
  }
  return n > 0.0f ? sum / n : 0.0f;
}

VD_INLINE vd_float4 vd_vertex_pixel(VD_GLOBAL const float* depth, VdCamera cam, int x, int y) {
  float d = depth[y * cam.width + x];
  if (d <= 0.0f) return VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  return VD_F4(((float)x - cam.cx) * d / cam.fx, ((float)y - cam.cy) * d / cam.fy, d, 1.0f);
}

/* Normal from the cross product of central differences, facing the camera; invalid at the border,
 * next to invalid pixels, and across depth jumps larger than max_jump (relative to depth). */
VD_INLINE vd_float4 vd_normal_pixel(VD_GLOBAL const vd_float4* vmap, int width, int height, int x, int y,
                                    float max_jump) {
  vd_float4 invalid = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  if (x < 1 || y < 1 || x >= width - 1 || y >= height - 1) return invalid;
  vd_float4 c = vmap[y * width + x];
  vd_float4 l = vmap[y * width + x - 1];
  vd_float4 r = vmap[y * width + x + 1];
  vd_float4 u = vmap[(y - 1) * width + x];
  vd_float4 d = vmap[(y + 1) * width + x];
  if (c.w == 0.0f || l.w == 0.0f || r.w == 0.0f || u.w == 0.0f || d.w == 0.0f) return invalid;
  float lim = max_jump * c.z;
  if (fabs(r.z - l.z) > lim || fabs(d.z - u.z) > lim) return invalid;
  vd_float4 n = vd_cross3(r - l, d - u);
  float len = vd_length3(n);
  if (!(len > 0.0f)) return invalid;
  n = n / len;
  /* Face the camera (which sits at the origin). */
  if (vd_dot3(n, c) > 0.0f) n = -n;
  n.w = 1.0f;
  return n;
}

/* Luma of a packed colour pixel (R in the low byte, then G and B, as frames are uploaded and the
 * volume's colour is fused), in [0, 1] (ITU-R BT.601 weights). */
VD_INLINE float vd_rgba_luma(vd_uint c) {
  return (0.299f * (float)(c & 255u) + 0.587f * (float)((c >> 8) & 255u) + 0.114f * (float)((c >> 16) & 255u)) *
         (1.0f / 255.0f);
}

/* The intensity image of the dense colour term (shared/correspondence.h vd_photometric_pixel), at
 * half resolution: the luma of each 2x2 block, smoothed by the 5-tap binomial (1 4 6 4 1) / 16
 * along each axis (sigma 1 half-resolution pixel, 2 px of the image), taps clamped at the edge.
 * The model's colour is a 4 mm grid's, about 2.3 px at 0.9 m: an image sharper than that leaves
 * residuals the model cannot explain. Measured at full resolution (docs/BENCHMARKS.md "Session
 * 28"): sigma 1 px gave tube drift 1.31 mm and cloth 1.33, sqrt(3) px 0.93 / 1.44, sqrt(5) px
 * 0.96 / 1.61 (no colour term: 1.09 / 2.23); half resolution costs a twelfth of the sqrt(3) px
 * passes. */
VD_INLINE float vd_luma_half_pixel(VD_GLOBAL const vd_uint* rgba, int width, int x, int y) {
  int i = 2 * y * width + 2 * x;
  return 0.25f * (vd_rgba_luma(rgba[i]) + vd_rgba_luma(rgba[i + 1]) + vd_rgba_luma(rgba[i + width]) +
                  vd_rgba_luma(rgba[i + width + 1]));
}

/* Bilinear sample of a w x h image at (u, v) (pixel centres at integers), clamped to the image. */
VD_INLINE float vd_bilinear(VD_GLOBAL const float* img, int w, int h, float u, float v) {
  u = fmin(fmax(u, 0.0f), (float)(w - 1));
  v = fmin(fmax(v, 0.0f), (float)(h - 1));
  int x0 = vd_min_i((int)u, w - 2), y0 = vd_min_i((int)v, h - 2);
  float a = u - (float)x0, b = v - (float)y0;
  VD_GLOBAL const float* r0 = img + y0 * w + x0;
  VD_GLOBAL const float* r1 = r0 + w;
  return (1.0f - b) * ((1.0f - a) * r0[0] + a * r0[1]) + b * ((1.0f - a) * r1[0] + a * r1[1]);
}

/* The half-resolution intensity (w x h) at full-resolution pixel (x, y), whose centre lies at
 * (x / 2 - 1/4, y / 2 - 1/4) there. */
VD_INLINE float vd_intensity_at(VD_GLOBAL const float* img, int w, int h, float x, float y) {
  return vd_bilinear(img, w, h, 0.5f * x - 0.25f, 0.5f * y - 0.25f);
}

/* The binomial (1 4 6 4 1) / 16 of five taps, centre c, its neighbours m1 / p1 and m2 / p2. */
VD_INLINE float vd_binomial5(float m2, float m1, float c, float p1, float p2) {
  return (6.0f * c + 4.0f * (m1 + p1) + (m2 + p2)) * (1.0f / 16.0f);
}

/* The intensity image's smoothing passes along a row and along a column, taps clamped at the edge. */
VD_INLINE float vd_hblur_pixel(VD_GLOBAL const float* in, int width, int x, int y) {
  VD_GLOBAL const float* row = in + y * width;
  return vd_binomial5(row[vd_max_i(x - 2, 0)], row[vd_max_i(x - 1, 0)], row[x], row[vd_min_i(x + 1, width - 1)],
                      row[vd_min_i(x + 2, width - 1)]);
}

VD_INLINE float vd_vblur_pixel(VD_GLOBAL const float* in, int width, int height, int x, int y) {
  return vd_binomial5(in[vd_max_i(y - 2, 0) * width + x], in[vd_max_i(y - 1, 0) * width + x], in[y * width + x],
                      in[vd_min_i(y + 1, height - 1) * width + x], in[vd_min_i(y + 2, height - 1) * width + x]);
}

#endif /* VD_PREPROCESS_H */
