/* Rasterisation of an indexed triangle mesh into triangle-id, vertex and normal buffers.
 * One pass per triangle keeps, per pixel, the minimum of (depth bits << 32 | triangle id) with a
 * 64-bit atomic: the nearest depth (positive floats order like their bit patterns) and, among the
 * triangles that produced exactly that depth, the smallest id; deterministic whatever the order.
 * A per-pixel pass then interpolates position and normal with perspective-correct barycentrics.
 * Coverage, depth and barycentrics come from raster_math.h: pixel centres at integer
 * coordinates, top-left rule. */
#ifndef VD_RASTER_H
#define VD_RASTER_H

#include "raster_math.h"
#include "vd_types.h"

#define VD_RASTER_EMPTY 0xFFFFFFFFu
/* An empty pixel of the packed depth-and-id buffer. */
#define VD_RASTER_EMPTY64 0xFFFFFFFFFFFFFFFFul
/* Triangles nearer than this are skipped (they would project to huge, meaningless areas). */
#define VD_RASTER_NEAR 0.05f
/* A triangle covering more pixels than this bounding-box area is skipped as degenerate. */
#define VD_RASTER_MAX_BOX 65536

/* Camera point p as a snapped corner; 0 when it is nearer than VD_RASTER_NEAR or projects too far out. */
VD_INLINE int vd_raster_corner(VdCamera cam, vd_float4 p, VdRasterCorner* c) {
  if (p.z < VD_RASTER_NEAR) return 0;
  const float u = vd_project_u(cam, p), v = vd_project_v(cam, p);
  if (!(fabs(u) < VD_RASTER_MAX_PX && fabs(v) < VD_RASTER_MAX_PX)) return 0;
  c->x = (vd_long)round(u * VD_RASTER_SUB_SCALE);
  c->y = (vd_long)round(v * VD_RASTER_SUB_SCALE);
  c->z = p.z;
  return 1;
}

VD_INLINE VdRasterTri vd_raster_setup(VD_GLOBAL const vd_float4* pos, VD_GLOBAL const int* tris, int t, VdPose T,
                                      VdCamera cam) {
  VdRasterCorner c0, c1, c2;
  if (!vd_raster_corner(cam, vd_pose_apply(T, pos[tris[3 * t + 0]]), &c0) ||
      !vd_raster_corner(cam, vd_pose_apply(T, pos[tris[3 * t + 1]]), &c1) ||
      !vd_raster_corner(cam, vd_pose_apply(T, pos[tris[3 * t + 2]]), &c2))
    return vd_raster_tri_empty();
  VdRasterBox window;
  window.x0 = 0;
  window.y0 = 0;
  window.x1 = cam.width - 1;
  window.y1 = cam.height - 1;
  VdRasterTri r = vd_raster_tri(c0, c1, c2, window);
  if (r.box.x1 >= r.box.x0 && (r.box.x1 - r.box.x0 + 1) * (r.box.y1 - r.box.y0 + 1) > VD_RASTER_MAX_BOX)
    return vd_raster_tri_empty();
  return r;
}

/* Depth of triangle r at pixel (x, y); 0 when r does not cover it. */
VD_INLINE float vd_raster_pixel_depth(VdRasterTri r, int x, int y) {
  vd_long w0, w1, w2;
  if (!vd_raster_cover(r, x, y, &w0, &w1, &w2)) return 0.0f;
  return 1.0f / vd_raster_inv_depth(r, w0, w1, w2);
}

/* What the per-pixel pass needs of a triangle's set-up, kept by the triangle pass so that it is not
 * built again at every pixel the triangle won: the oriented corners in 1/256 px (under 2^31 by
 * VD_RASTER_MAX_PX), 1 / z of the caller's corners and whether b and c were swapped. */
typedef struct {
  int ax, ay, bx, by, cx, cy;
  float iz0, iz1, iz2;
  int swapped;
} VdRasterSetup;

/* The one pass over triangles: per covered pixel, min(depth bits << 32 | t); triangle t's set-up
 * into setups[t]. */
VD_INLINE void vd_raster_triangle(VD_GLOBAL const vd_float4* pos, VD_GLOBAL const int* tris, int t, VdPose T,
                                  VdCamera cam, VD_GLOBAL vd_ulong* depth_id, VD_GLOBAL VdRasterSetup* setups) {
  VdRasterTri r = vd_raster_setup(pos, tris, t, T, cam);
  VdRasterSetup s;
  s.ax = (int)r.a.x;
  s.ay = (int)r.a.y;
  s.bx = (int)r.b.x;
  s.by = (int)r.b.y;
  s.cx = (int)r.c.x;
  s.cy = (int)r.c.y;
  s.iz0 = r.iz0;
  s.iz1 = r.iz1;
  s.iz2 = r.iz2;
  s.swapped = r.swapped;
  setups[t] = s;
  for (int y = r.box.y0; y <= r.box.y1; ++y) {
    for (int x = r.box.x0; x <= r.box.x1; ++x) {
      const float z = vd_raster_pixel_depth(r, x, y);
      if (z > 0.0f)
        VD_ATOMIC_MIN_U64(&depth_id[y * cam.width + x], ((vd_ulong)VD_FLOAT_AS_UINT(z) << 32) | (vd_ulong)(vd_uint)t);
    }
  }
}

/* The id part of a packed pixel: VD_RASTER_EMPTY where nothing covered it. */
VD_INLINE vd_uint vd_raster_id(vd_ulong depth_id) {
  return depth_id == VD_RASTER_EMPTY64 ? VD_RASTER_EMPTY : (vd_uint)(depth_id & 0xFFFFFFFFul);
}

/* Per pixel, after the triangle pass: camera-space position and normal (w = 1 valid, 0 empty) and
 * the perspective-correct barycentrics (w = 1 valid; the triangle is t, VD_RASTER_EMPTY for none),
 * used to pair and to lift points. */
VD_INLINE void vd_raster_resolve_pixel(VD_GLOBAL const vd_float4* pos, VD_GLOBAL const vd_float4* nrm,
                                       VD_GLOBAL const int* tris, VD_GLOBAL const VdRasterSetup* setups, VdPose T,
                                       VdCamera cam, int pix, vd_uint t, vd_float4* vertex, vd_float4* normal,
                                       vd_float4* bary) {
  *vertex = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  *normal = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  *bary = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  if (t == VD_RASTER_EMPTY) return;
  const VdRasterSetup s = setups[t];
  vd_long ea, eb, ec, e0, e1, e2;
  vd_raster_edges(s.ax, s.ay, s.bx, s.by, s.cx, s.cy, s.swapped, pix % cam.width, pix / cam.width, &ea, &eb, &ec, &e0,
                  &e1, &e2);
  const vd_float4 b = vd_raster_bary_iz(s.iz0, s.iz1, s.iz2, e0, e1, e2);
  const float w0 = b.x, w1 = b.y, w2 = b.z;
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
