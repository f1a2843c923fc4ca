/* Triangle coverage for every rasteriser in vdeform: the server's model rasteriser (raster.h, on
 * the device and in the CPU reference), the capture client's synthetic renderer and the viewer.
 * Each caller projects its corners in its own precision and snaps them to 1/256 px; from there on
 * the edge functions are exact 64-bit integers and a top-left rule gives a pixel centre lying on
 * an edge shared by two triangles to exactly one of them: no holes, no double hits. Pixel centres
 * sit at integer coordinates. */
#ifndef VD_RASTER_MATH_H
#define VD_RASTER_MATH_H

#include "vd_compat.h"

/* 8 bits of sub-pixel precision: 1/256 px is ~0.006 mm at 1 m and 525 px focal length. */
#define VD_RASTER_SUB_BITS 8
#define VD_RASTER_SUB_SCALE 256.0f
/* Corners projecting farther out (px) are dropped: below 2^8 * 4e6 per coordinate, an edge
 * function (a difference of two products of coordinate differences) stays under 8.4e18 < 2^63.
 * The viewer's widest default view (640 px, zoom 1000) reaches 2.9e5 px. */
#define VD_RASTER_MAX_PX 4e6f

/* A projected corner: position in 1/256 px, camera depth z > 0 in metres. */
typedef struct {
  vd_long x, y;
  float z;
} VdRasterCorner;

/* Pixels x0..x1, y0..y1 inclusive. */
typedef struct {
  int x0, y0, x1, y1;
} VdRasterBox;

typedef struct {
  /* The caller's corners, 1 and 2 swapped where needed so that the area is positive. */
  VdRasterCorner a, b, c;
  /* Twice the area in (1/256 px)^2: the three edge functions sum to it everywhere. */
  vd_long area;
  /* -1 on an edge that does not own the centres lying on it (top-left rule), else 0. */
  vd_long bias_a, bias_b, bias_c;
  /* 1 / z of the caller's corners 0, 1, 2: affine in screen space over a planar triangle. */
  float iz0, iz1, iz2;
  /* In float for the per-pixel interpolation. */
  float inv_area;
  /* 1 when a, b, c are the caller's corners 0, 2, 1. */
  int swapped;
  /* The pixels whose centres can be covered, clipped to the caller's window; empty (x1 < x0) for
   * a degenerate triangle or one outside the window, so loops over it need no other test. */
  VdRasterBox box;
} VdRasterTri;

VD_INLINE vd_long vd_min_l(vd_long a, vd_long b) { return a < b ? a : b; }
VD_INLINE vd_long vd_max_l(vd_long a, vd_long b) { return a > b ? a : b; }

/* Twice the signed area of (a, b, p): positive when p lies left of a->b in a y-down image. */
VD_INLINE vd_long vd_raster_edge(vd_long ax, vd_long ay, vd_long bx, vd_long by, vd_long px, vd_long py) {
  return (bx - ax) * (py - ay) - (by - ay) * (px - ax);
}

/* Top-left rule: of the two directions of an edge exactly one owns the centres lying on it. */
VD_INLINE vd_long vd_raster_edge_bias(vd_long ax, vd_long ay, vd_long bx, vd_long by) {
  const vd_long dy = by - ay, dx = bx - ax;
  return (dy < 0 || (dy == 0 && dx > 0)) ? 0 : -1;
}

/* A triangle that covers nothing. */
VD_INLINE VdRasterTri vd_raster_tri_empty(void) {
  VdRasterTri r;
  r.a.x = r.a.y = 0;
  r.a.z = 0.0f;
  r.b = r.c = r.a;
  r.area = 0;
  r.bias_a = r.bias_b = r.bias_c = 0;
  r.iz0 = r.iz1 = r.iz2 = 0.0f;
  r.inv_area = 0.0f;
  r.swapped = 0;
  r.box.x0 = r.box.y0 = 0;
  r.box.x1 = r.box.y1 = -1;
  return r;
}

/* Set-up of a triangle whose corners lie within VD_RASTER_MAX_PX, clipped to `window`. */
VD_INLINE VdRasterTri vd_raster_tri(VdRasterCorner c0, VdRasterCorner c1, VdRasterCorner c2, VdRasterBox window) {
  VdRasterTri r = vd_raster_tri_empty();
  vd_long area = vd_raster_edge(c0.x, c0.y, c1.x, c1.y, c2.x, c2.y);
  if (area == 0) return r;
  r.swapped = area < 0;
  if (r.swapped) {
    VdRasterCorner t = c1;
    c1 = c2;
    c2 = t;
    area = -area;
  }
  r.a = c0;
  r.b = c1;
  r.c = c2;
  r.area = area;
  const vd_long min_x = vd_min_l(c0.x, vd_min_l(c1.x, c2.x)), max_x = vd_max_l(c0.x, vd_max_l(c1.x, c2.x));
  const vd_long min_y = vd_min_l(c0.y, vd_min_l(c1.y, c2.y)), max_y = vd_max_l(c0.y, vd_max_l(c1.y, c2.y));
  /* The first centre at or after the minimum, the last at or before the maximum. */
  const vd_long round_up = (1 << VD_RASTER_SUB_BITS) - 1;
  r.box.x0 = vd_max_i((int)((min_x + round_up) >> VD_RASTER_SUB_BITS), window.x0);
  r.box.x1 = vd_min_i((int)(max_x >> VD_RASTER_SUB_BITS), window.x1);
  r.box.y0 = vd_max_i((int)((min_y + round_up) >> VD_RASTER_SUB_BITS), window.y0);
  r.box.y1 = vd_min_i((int)(max_y >> VD_RASTER_SUB_BITS), window.y1);
  r.bias_a = vd_raster_edge_bias(c1.x, c1.y, c2.x, c2.y);
  r.bias_b = vd_raster_edge_bias(c2.x, c2.y, c0.x, c0.y);
  r.bias_c = vd_raster_edge_bias(c0.x, c0.y, c1.x, c1.y);
  /* Back in the caller's order: the swap only orients the edges. */
  r.iz0 = 1.0f / c0.z;
  r.iz1 = 1.0f / (r.swapped ? c2.z : c1.z);
  r.iz2 = 1.0f / (r.swapped ? c1.z : c2.z);
  r.inv_area = 1.0f / (float)area;
  return r;
}

/* The edge functions at the centre of pixel (x, y) of the oriented corners a, b, c (opposite a, b,
 * c: ea, eb, ec) and, in *w0..*w2, the same for the caller's corners 0, 1, 2 (each that corner's
 * screen-space barycentric times the area). */
VD_INLINE void vd_raster_edges(vd_long ax, vd_long ay, vd_long bx, vd_long by, vd_long cx, vd_long cy, int swapped,
                               int x, int y, vd_long* ea, vd_long* eb, vd_long* ec, vd_long* w0, vd_long* w1,
                               vd_long* w2) {
  const vd_long sx = (vd_long)x << VD_RASTER_SUB_BITS, sy = (vd_long)y << VD_RASTER_SUB_BITS;
  *ea = vd_raster_edge(bx, by, cx, cy, sx, sy);
  *eb = vd_raster_edge(cx, cy, ax, ay, sx, sy);
  *ec = vd_raster_edge(ax, ay, bx, by, sx, sy);
  *w0 = *ea;
  *w1 = swapped ? *ec : *eb;
  *w2 = swapped ? *eb : *ec;
}

/* Edge functions at the centre of pixel (x, y) for the caller's corners 0, 1, 2 (vd_raster_edges);
 * returns 1 when the triangle covers it. */
VD_INLINE int vd_raster_cover(VdRasterTri r, int x, int y, vd_long* w0, vd_long* w1, vd_long* w2) {
  vd_long ea, eb, ec;
  vd_raster_edges(r.a.x, r.a.y, r.b.x, r.b.y, r.c.x, r.c.y, r.swapped, x, y, &ea, &eb, &ec, w0, w1, w2);
  return ea + r.bias_a >= 0 && eb + r.bias_b >= 0 && ec + r.bias_c >= 0;
}

/* 1 / z at the point with edge functions (w0, w1, w2). */
VD_INLINE float vd_raster_inv_depth(VdRasterTri r, vd_long w0, vd_long w1, vd_long w2) {
  return ((float)w0 * r.iz0 + (float)w1 * r.iz1 + (float)w2 * r.iz2) * r.inv_area;
}

/* Perspective-correct barycentrics (x, y, z for corners 0, 1, 2; w = 0) at edge functions
 * (w0, w1, w2) of a covered centre, from 1 / z of the three corners: the weights for
 * interpolating vertex attributes. */
VD_INLINE vd_float4 vd_raster_bary_iz(float iz0, float iz1, float iz2, vd_long w0, vd_long w1, vd_long w2) {
  const float b0 = (float)w0 * iz0, b1 = (float)w1 * iz1, b2 = (float)w2 * iz2;
  const float inv = 1.0f / (b0 + b1 + b2);
  return VD_F4(b0 * inv, b1 * inv, b2 * inv, 0.0f);
}

VD_INLINE vd_float4 vd_raster_bary(VdRasterTri r, vd_long w0, vd_long w1, vd_long w2) {
  return vd_raster_bary_iz(r.iz0, r.iz1, r.iz2, w0, w1, w2);
}

#endif /* VD_RASTER_MATH_H */
