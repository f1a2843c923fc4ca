#pragma once
// CPU z-buffer rasteriser for triangle meshes in camera coordinates: per pixel, the nearest
// triangle, its exact depth along the pixel ray and perspective-correct barycentrics.
#include <cstdint>
#include <vector>

#include "vd/common/camera.h"

namespace vd {

struct RasterImage {
  int width = 0;
  int height = 0;
  // Index of the visible triangle per pixel (row-major), -1 where no surface.
  std::vector<int32_t> triangle;
  // Camera z of the surface point on the pixel ray, metres; 0 where no surface.
  std::vector<float> depth;
  // Barycentrics (b0, b1, b2) of the surface point for the triangle's three vertices.
  std::vector<float> bary;
};

// Nearest triangles closer than this are dropped rather than clipped; the scenes never come
// this close to the camera.
inline constexpr float kRasterMinDepth = 0.01f;

// positions: x, y, z per vertex in camera coordinates (metres, z forward); triangles: three
// vertex indices each. Pixel centres sit at integer coordinates. Coverage uses fixed-point edge
// functions with a top-left rule, so triangles sharing an edge leave no holes and no double hits.
// Both faces are drawn. Triangles with an out-of-range index, a vertex nearer than
// kRasterMinDepth or non-finite coordinates are skipped. Rows are split across OpenMP threads;
// the result does not depend on the thread count.
RasterImage Rasterize(const std::vector<float>& positions, const std::vector<int32_t>& triangles,
                      const Intrinsics& intrinsics);

}  // namespace vd
