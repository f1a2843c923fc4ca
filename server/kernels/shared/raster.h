/* Rasterisation of an indexed triangle mesh into depth, triangle-id, vertex and normal buffers.
 * Two passes per triangle keep it deterministic with 32-bit atomics only: the first keeps the
 * nearest depth per pixel (positive floats order like their bit patterns), the second writes the
 * smallest id among the triangles that produced exactly that depth. A per-pixel pass then
 * interpolates position and normal with perspective-correct barycentrics. Pixel centres sit at
 * integer coordinates; a pixel is covered when its centre is inside or on the triangle's edge. */
#ifndef VD_RASTER_H
#define VD_RASTER_H

#include "vd_types.h"

#define VD_RASTER_EMPTY 0xFFFFFFFFu
/* Triangles nearer than this are skipped (they would project to huge, meaningless areas). */
#define VD_RASTER_NEAR 0.05f
/* A triangle covering more pixels than this bounding-box area is skipped as degenerate. */
#define VD_RASTER_MAX_BOX 65536

typedef struct {
  /* Screen positions and 1 / z of the three corners. */
  float u0, v0, u1, v1, u2, v2;
  float iz0, iz1, iz2;
  float inv_area;
  int x0, y0, x1, y1;
  int valid;
} VdRasterTri;

VD_INLINE VdRasterTri vd_raster_setup(VD_GLOBAL const vd_float4* pos, VD_GLOBAL const int* tris, int t, VdPose T,
                                      VdCamera cam) {
  VdRasterTri r;
  r.valid = 0;
  vd_float4 p0 = vd_pose_apply(T, pos[tris[3 * t + 0]]);
  vd_float4 p1 = vd_pose_apply(T, pos[tris[3 * t + 1]]);
  vd_float4 p2 = vd_pose_apply(T, pos[tris[3 * t + 2]]);
  if (p0.z < VD_RASTER_NEAR || p1.z < VD_RASTER_NEAR || p2.z < VD_RASTER_NEAR) return r;
  r.u0 = vd_project_u(cam, p0);
  r.v0 = vd_project_v(cam, p0);
  r.u1 = vd_project_u(cam, p1);
  r.v1 = vd_project_v(cam, p1);
  r.u2 = vd_project_u(cam, p2);
  r.v2 = vd_project_v(cam, p2);
  r.iz0 = 1.0f / p0.z;
  r.iz1 = 1.0f / p1.z;
  r.iz2 = 1.0f / p2.z;
  float area = (r.u1 - r.u0) * (r.v2 - r.v0) - (r.v1 - r.v0) * (r.u2 - r.u0);
  if (fabs(area) < 1e-12f) return r;
  r.inv_area = 1.0f / area;
  float umin = fmin(r.u0, fmin(r.u1, r.u2)), umax = fmax(r.u0, fmax(r.u1, r.u2));
  float vmin = fmin(r.v0, fmin(r.v1, r.v2)), vmax = fmax(r.v0, fmax(r.v1, r.v2));
  if (umax < 0.0f || vmax < 0.0f || umin > (float)(cam.width - 1) || vmin > (float)(cam.height - 1)) return r;
  r.x0 = vd_max_i((int)ceil(umin), 0);
  r.y0 = vd_max_i((int)ceil(vmin), 0);
  r.x1 = vd_min_i((int)floor(umax), cam.width - 1);
  r.y1 = vd_min_i((int)floor(vmax), cam.height - 1);
  if (r.x1 < r.x0 || r.y1 < r.y0) return r;
  if ((r.x1 - r.x0 + 1) * (r.y1 - r.y0 + 1) > VD_RASTER_MAX_BOX) return r;
  r.valid = 1;
  return r;
}

/* Screen-space barycentrics of pixel (x, y); returns 0 when outside. */
VD_INLINE int vd_raster_bary(VdRasterTri r, int x, int y, float* b0, float* b1, float* b2) {
  float px = (float)x, py = (float)y;
  *b0 = ((r.u1 - px) * (r.v2 - py) - (r.v1 - py) * (r.u2 - px)) * r.inv_area;
  *b1 = ((r.u2 - px) * (r.v0 - py) - (r.v2 - py) * (r.u0 - px)) * r.inv_area;
  *b2 = 1.0f - *b0 - *b1;
  return *b0 >= 0.0f && *b1 >= 0.0f && *b2 >= 0.0f;
}

VD_INLINE float vd_raster_depth(VdRasterTri r, float b0, float b1, float b2) {
  return 1.0f / (b0 * r.iz0 + b1 * r.iz1 + b2 * r.iz2);
}

/* Pass 1: nearest depth (as uint bits) per pixel. */
VD_INLINE void vd_raster_depth_triangle(VD_GLOBAL const vd_float4* pos, VD_GLOBAL const int* tris, int t, VdPose T,
                                        VdCamera cam, VD_GLOBAL vd_uint* depth_bits) {
  VdRasterTri r = vd_raster_setup(pos, tris, t, T, cam);
  if (!r.valid) return;
  for (int y = r.y0; y <= r.y1; ++y) {
    for (int x = r.x0; x <= r.x1; ++x) {
      float b0, b1, b2;
      if (!vd_raster_bary(r, x, y, &b0, &b1, &b2)) continue;
      VD_ATOMIC_MIN_U32(&depth_bits[y * cam.width + x], VD_FLOAT_AS_UINT(vd_raster_depth(r, b0, b1, b2)));
    }
  }
}

/* Pass 2: smallest triangle id that produced the stored depth. */
VD_INLINE void vd_raster_id_triangle(VD_GLOBAL const vd_float4* pos, VD_GLOBAL const int* tris, int t, VdPose T,
                                     VdCamera cam, VD_GLOBAL const vd_uint* depth_bits, VD_GLOBAL vd_uint* ids) {
  VdRasterTri r = vd_raster_setup(pos, tris, t, T, cam);
  if (!r.valid) return;
  for (int y = r.y0; y <= r.y1; ++y) {
    for (int x = r.x0; x <= r.x1; ++x) {
      float b0, b1, b2;
      if (!vd_raster_bary(r, x, y, &b0, &b1, &b2)) continue;
      int pix = y * cam.width + x;
      if (VD_FLOAT_AS_UINT(vd_raster_depth(r, b0, b1, b2)) == depth_bits[pix]) VD_ATOMIC_MIN_U32(&ids[pix], (vd_uint)t);
    }
  }
}

/* Pass 3 for one pixel: camera-space position and normal (w = 1 valid, 0 empty) and the
 * perspective-correct barycentrics (w = 1 valid; the triangle is ids[pix]), used to lift points. */
VD_INLINE void vd_raster_resolve_pixel(VD_GLOBAL const vd_float4* pos, VD_GLOBAL const vd_float4* nrm,
                                       VD_GLOBAL const int* tris, VdPose T, VdCamera cam, int pix,
                                       VD_GLOBAL const vd_uint* ids, vd_float4* vertex, vd_float4* normal,
                                       vd_float4* bary) {
  vd_uint t = ids[pix];
  *vertex = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  *normal = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  *bary = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  if (t == VD_RASTER_EMPTY) return;
  VdRasterTri r = vd_raster_setup(pos, tris, (int)t, T, cam);
  float b0, b1, b2;
  vd_raster_bary(r, pix % cam.width, pix / cam.width, &b0, &b1, &b2);
  /* Perspective-correct weights. */
  float w0 = b0 * r.iz0, w1 = b1 * r.iz1, w2 = b2 * r.iz2;
  float inv = 1.0f / (w0 + w1 + w2);
  w0 *= inv;
  w1 *= inv;
  w2 *= inv;
  int i0 = tris[3 * t + 0], i1 = tris[3 * t + 1], i2 = tris[3 * t + 2];
  vd_float4 p = pos[i0] * w0 + pos[i1] * w1 + pos[i2] * w2;
  p.w = 1.0f;
  *vertex = vd_pose_apply(T, p);
  vd_float4 n = vd_normalize3(vd_pose_rotate(T, nrm[i0] * w0 + nrm[i1] * w1 + nrm[i2] * w2));
  n.w = 1.0f;
  *normal = n;
  *bary = VD_F4(w0, w1, w2, 1.0f);
}

#endif /* VD_RASTER_H */
