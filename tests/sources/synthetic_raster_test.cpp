// The rasteriser behind the synthetic scenes is private to vd::capture; its header sits next to
// its source.
#include "../../capture_client/src/raster.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <Eigen/Core>

namespace vd {
namespace {

const Intrinsics kCamera{525.f, 525.f, 319.5f, 239.5f, 640, 480};

// A grid of nx x ny vertices from `pos(i, j)`, two triangles per cell.
template <typename F>
void Grid(int nx, int ny, F pos, std::vector<float>* positions, std::vector<int32_t>* triangles) {
  const int32_t base = int32_t(positions->size() / 3);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const Eigen::Vector3d p = pos(i, j);
      positions->insert(positions->end(), {float(p.x()), float(p.y()), float(p.z())});
    }
  for (int j = 0; j + 1 < ny; ++j)
    for (int i = 0; i + 1 < nx; ++i) {
      const int32_t a = base + j * nx + i, b = a + 1, c = a + nx + 1, d = a + nx;
      triangles->insert(triangles->end(), {a, b, c, a, c, d});
    }
}

// A tilted plane z = 1 + 0.3 x of jittered tiny triangles (about 1.5 px): every pixel is covered
// once, the depth is the exact plane depth and the barycentrics are perspective-correct.
TEST(RasterTest, JitteredPlaneIsWatertightAndExact) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> jitter(-0.001, 0.001);
  std::vector<float> positions;
  std::vector<int32_t> triangles;
  const int n = 600;
  std::vector<double> jx(n * n), jy(n * n);
  for (auto& v : jx) v = jitter(rng);
  for (auto& v : jy) v = jitter(rng);
  Grid(n, 440, [&](int i, int j) {
    const double x = -0.9 + 0.003 * i + jx[j * n + i], y = -0.66 + 0.003 * j + jy[j * n + i];
    return Eigen::Vector3d(x, y, 1.0 + 0.3 * x);
  }, &positions, &triangles);
  const RasterImage image = Rasterize(positions, triangles, kCamera);
  ASSERT_EQ(image.width, 640);
  int holes = 0;
  double worst_depth = 0.0, worst_point = 0.0, worst_bary = 0.0;
  for (int y = 0; y < 480; ++y)
    for (int x = 0; x < 640; ++x) {
      const size_t idx = size_t(y) * 640 + size_t(x);
      const int32_t t = image.triangle[idx];
      if (t < 0) {
        ++holes;
        continue;
      }
      const double a = (x - 319.5) / 525.0, b = (y - 239.5) / 525.0;
      const double z = 1.0 / (1.0 - 0.3 * a);
      worst_depth = std::max(worst_depth, std::fabs(image.depth[idx] - z));
      Eigen::Vector3d p = Eigen::Vector3d::Zero();
      for (int v = 0; v < 3; ++v) {
        const float* q = &positions[3 * size_t(triangles[3 * size_t(t) + size_t(v)])];
        p += double(image.bary[3 * idx + size_t(v)]) * Eigen::Vector3d(q[0], q[1], q[2]);
        worst_bary = std::max(worst_bary, -double(image.bary[3 * idx + size_t(v)]));
      }
      worst_point = std::max(worst_point, (p - Eigen::Vector3d(a * z, b * z, z)).norm());
    }
  EXPECT_EQ(holes, 0);
  EXPECT_LT(worst_depth, 2e-6);
  // Coverage uses vertices snapped to 1/256 px (~0.01 mm here); barycentrics are clamped onto the triangle.
  EXPECT_LT(worst_point, 2e-5);
  EXPECT_LE(worst_bary, 0.0);
}

// Vertices projecting exactly onto pixel centres exercise the top-left rule on shared edges
// and vertices.
TEST(RasterTest, VerticesOnPixelCentresLeaveNoHoles) {
  std::vector<float> positions;
  std::vector<int32_t> triangles;
  Grid(170, 130, [](int i, int j) {
    return Eigen::Vector3d((4 * i - 20 - 319.5) / 525.0 * 2.0, (4 * j - 20 - 239.5) / 525.0 * 2.0, 2.0);
  }, &positions, &triangles);
  const RasterImage image = Rasterize(positions, triangles, kCamera);
  int holes = 0;
  for (int32_t t : image.triangle) holes += t < 0;
  EXPECT_EQ(holes, 0);
  for (float z : image.depth) ASSERT_NEAR(z, 2.f, 1e-6f);
}

TEST(RasterTest, NearestSurfaceWinsWhateverTheOrder) {
  std::vector<float> positions;
  std::vector<int32_t> triangles;
  auto square = [&](double z) {
    Grid(2, 2, [z](int i, int j) { return Eigen::Vector3d((i - 0.5) * 0.4 * z, (j - 0.5) * 0.4 * z, z); },
         &positions, &triangles);
  };
  square(1.5);
  square(1.0);
  square(2.0);
  const RasterImage image = Rasterize(positions, triangles, kCamera);
  const size_t centre = 240 * 640 + 320;
  EXPECT_FLOAT_EQ(image.depth[centre], 1.0f);
  EXPECT_TRUE(image.triangle[centre] == 2 || image.triangle[centre] == 3);
  EXPECT_EQ(image.triangle[0], -1);
  EXPECT_EQ(image.depth[0], 0.f);
}

TEST(RasterTest, BadTrianglesAreSkipped) {
  const std::vector<float> positions = {-0.1f, -0.1f, 1.f, 0.1f, -0.1f, 1.f, 0.f, 0.1f, 1.f,
                                        -0.1f, -0.1f, -1.f, NAN, 0.f, 1.f};
  const std::vector<int32_t> triangles = {0, 1, 7, -1, 0, 1, 0, 1, 3, 0, 1, 4, 0, 0, 0, 0, 1};
  const RasterImage image = Rasterize(positions, triangles, kCamera);
  int covered = 0;
  for (int32_t t : image.triangle) covered += t >= 0;
  EXPECT_EQ(covered, 0);
  Intrinsics empty = kCamera;
  empty.width = 0;
  EXPECT_TRUE(Rasterize(positions, triangles, empty).triangle.empty());
}

}  // namespace
}  // namespace vd
