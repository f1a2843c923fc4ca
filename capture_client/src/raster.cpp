#include "raster.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <omp.h>

#include "shared/raster_math.h"

namespace vd {
namespace {

struct Projected {
  VdRasterCorner corner{};
  bool ok = false;
};

struct RayHit {
  bool ok = false;
  double t = 0.0;
  double b1 = 0.0;
  double b2 = 0.0;
};

// Ray from the origin along d (d.z = 1, so t is the camera z) against the plane of triangle
// (p0, p1, p2); barycentrics relative to p1 and p2.
inline RayHit IntersectRay(const double d[3], const float* p0, const float* p1, const float* p2) {
  const double e1[3] = {double(p1[0]) - p0[0], double(p1[1]) - p0[1], double(p1[2]) - p0[2]};
  const double e2[3] = {double(p2[0]) - p0[0], double(p2[1]) - p0[1], double(p2[2]) - p0[2]};
  const double q[3] = {d[1] * e2[2] - d[2] * e2[1], d[2] * e2[0] - d[0] * e2[2], d[0] * e2[1] - d[1] * e2[0]};
  const double det = e1[0] * q[0] + e1[1] * q[1] + e1[2] * q[2];
  const double scale = std::sqrt(e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2]) *
                       std::sqrt(e2[0] * e2[0] + e2[1] * e2[1] + e2[2] * e2[2]);
  RayHit hit;
  if (!(std::fabs(det) > 1e-12 * scale)) return hit;
  const double inv = 1.0 / det;
  const double s[3] = {-double(p0[0]), -double(p0[1]), -double(p0[2])};
  const double r[3] = {s[1] * e1[2] - s[2] * e1[1], s[2] * e1[0] - s[0] * e1[2], s[0] * e1[1] - s[1] * e1[0]};
  hit.b1 = (s[0] * q[0] + s[1] * q[1] + s[2] * q[2]) * inv;
  hit.b2 = (d[0] * r[0] + d[1] * r[1] + d[2] * r[2]) * inv;
  hit.t = (e2[0] * r[0] + e2[1] * r[1] + e2[2] * r[2]) * inv;
  hit.ok = std::isfinite(hit.t) && hit.t > 0.0;
  return hit;
}

}  // namespace

RasterImage Rasterize(const std::vector<float>& positions, const std::vector<int32_t>& triangles,
                      const Intrinsics& intrinsics) {
  RasterImage out;
  const int w = std::max(0, intrinsics.width);
  const int h = std::max(0, intrinsics.height);
  out.width = w;
  out.height = h;
  const size_t num_pixels = size_t(w) * size_t(h);
  out.triangle.assign(num_pixels, -1);
  out.depth.assign(num_pixels, 0.f);
  out.bary.assign(3 * num_pixels, 0.f);
  if (num_pixels == 0) return out;

  const int64_t num_vertices = int64_t(positions.size() / 3);
  const int64_t num_triangles = int64_t(triangles.size() / 3);
  const double fx = intrinsics.fx, fy = intrinsics.fy, cx = intrinsics.cx, cy = intrinsics.cy;

  std::vector<Projected> proj(static_cast<size_t>(num_vertices));
#pragma omp parallel for schedule(static)
  for (int64_t i = 0; i < num_vertices; ++i) {
    const float* p = &positions[size_t(3 * i)];
    Projected& q = proj[size_t(i)];
    if (!(std::isfinite(p[0]) && std::isfinite(p[1]) && p[2] >= kRasterMinDepth && std::isfinite(p[2]))) continue;
    const double u = fx * p[0] / p[2] + cx;
    const double v = fy * p[1] / p[2] + cy;
    if (!(std::fabs(u) < VD_RASTER_MAX_PX && std::fabs(v) < VD_RASTER_MAX_PX)) continue;
    q.corner = VdRasterCorner{std::llround(u * VD_RASTER_SUB_SCALE), std::llround(v * VD_RASTER_SUB_SCALE), p[2]};
    q.ok = true;
  }

  // Each thread owns a band of rows and walks every triangle, so z-buffer writes never race and
  // ties resolve in triangle order whatever the thread count.
  std::vector<float> zbuf(num_pixels, std::numeric_limits<float>::infinity());
#pragma omp parallel
  {
    const int nt = omp_get_num_threads();
    const int id = omp_get_thread_num();
    const int row_begin = int(int64_t(h) * id / nt);
    const int row_end = int(int64_t(h) * (id + 1) / nt);
    for (int64_t t = 0; t < num_triangles && row_begin < row_end; ++t) {
      int32_t i0 = triangles[size_t(3 * t)], i1 = triangles[size_t(3 * t + 1)], i2 = triangles[size_t(3 * t + 2)];
      if (i0 < 0 || i1 < 0 || i2 < 0 || i0 >= num_vertices || i1 >= num_vertices || i2 >= num_vertices) continue;
      const Projected* a = &proj[size_t(i0)];
      const Projected* b = &proj[size_t(i1)];
      const Projected* c = &proj[size_t(i2)];
      if (!(a->ok && b->ok && c->ok)) continue;
      const VdRasterBox band{0, row_begin, w - 1, row_end - 1};
      const VdRasterTri r = vd_raster_tri(a->corner, b->corner, c->corner, band);
      for (int py = r.box.y0; py <= r.box.y1; ++py) {
        for (int px = r.box.x0; px <= r.box.x1; ++px) {
          vd_long w0, w1, w2;
          if (!vd_raster_cover(r, px, py, &w0, &w1, &w2)) continue;
          const float z = 1.f / vd_raster_inv_depth(r, w0, w1, w2);
          const size_t idx = size_t(py) * size_t(w) + size_t(px);
          if (z < zbuf[idx]) {
            zbuf[idx] = z;
            out.triangle[idx] = int32_t(t);
          }
        }
      }
    }
  }

  // Deferred pass: the exact ray-plane intersection of each pixel with its visible triangle.
#pragma omp parallel for schedule(static)
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const size_t idx = size_t(y) * size_t(w) + size_t(x);
      const int32_t t = out.triangle[idx];
      if (t < 0) continue;
      const float* p0 = &positions[size_t(3) * size_t(triangles[size_t(3 * t)])];
      const float* p1 = &positions[size_t(3) * size_t(triangles[size_t(3 * t + 1)])];
      const float* p2 = &positions[size_t(3) * size_t(triangles[size_t(3 * t + 2)])];
      const double d[3] = {(x - cx) / fx, (y - cy) / fy, 1.0};
      const RayHit hit = IntersectRay(d, p0, p1, p2);
      float* b = &out.bary[3 * idx];
      if (hit.ok) {
        // Coverage used snapped vertices: a centre within 1/256 px of an edge may fall just
        // outside, so clamp the barycentrics onto the triangle; the depth stays on its plane.
        double b1 = std::clamp(hit.b1, 0.0, 1.0), b2 = std::clamp(hit.b2, 0.0, 1.0);
        if (b1 + b2 > 1.0) {
          const double s = b1 + b2;
          b1 /= s;
          b2 /= s;
        }
        b[0] = float(std::max(0.0, 1.0 - b1 - b2));
        b[1] = float(b1);
        b[2] = float(b2);
        out.depth[idx] = float(hit.t);
      } else {
        // Seen exactly edge-on: keep the rasterised depth and the centroid.
        b[0] = b[1] = b[2] = 1.f / 3.f;
        out.depth[idx] = zbuf[idx];
      }
    }
  }
  return out;
}

}  // namespace vd
