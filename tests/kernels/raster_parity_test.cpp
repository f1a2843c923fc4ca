#include <gtest/gtest.h>

#include <cmath>

#include "cpu_ref/cpu_ref.h"
#include "ocl/device_ops.h"
#include "shared/raster.h"
#include "test_scenes.h"

namespace vd {
namespace {

// A UV sphere mesh (world metres) centred at (0, 0, cz).
void SphereMesh(float cz, float r, int rings, int segs, std::vector<vd_float4>* pos, std::vector<vd_float4>* nrm,
                std::vector<int32_t>* tris) {
  for (int i = 0; i <= rings; ++i) {
    const float th = float(M_PI) * i / rings;
    for (int j = 0; j < segs; ++j) {
      const float ph = 2.f * float(M_PI) * j / segs;
      const vd_float4 n = VD_F4(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th), 0.f);
      nrm->push_back(n);
      pos->push_back(VD_F4(r * n.x, r * n.y, cz + r * n.z, 1.f));
    }
  }
  for (int i = 0; i < rings; ++i)
    for (int j = 0; j < segs; ++j) {
      const int a = i * segs + j, b = i * segs + (j + 1) % segs, c = a + segs, d = b + segs;
      tris->insert(tris->end(), {a, c, b, b, c, d});
    }
}

TEST(RasterParityTest, DepthIdsAndMapsMatchCpuAndTheAnalyticSphere) {
  VD_REQUIRE_OCL(ctx);
  DeviceOps ops(ctx);
  ASSERT_TRUE(ops.Init().ok());
  std::vector<vd_float4> pos, nrm;
  std::vector<int32_t> tris;
  SphereMesh(1.0f, 0.25f, 48, 96, &pos, &nrm, &tris);
  const VdCamera cam = test::TestCamera(160, 120);
  const VdPose T = test::IdentityPose();
  cpu::RasterMaps ref;
  cpu::Rasterize(pos.data(), nrm.data(), tris.data(), int(tris.size() / 3), T, cam, &ref);

  DeviceMesh m;
  m.positions = test::ToDevice(ctx, pos);
  m.normals = test::ToDevice(ctx, nrm);
  m.triangles = test::ToDevice(ctx, tris);
  m.num_vertices = pos.size();
  m.num_triangles = tris.size() / 3;
  DeviceRaster out;
  ASSERT_TRUE(ops.Rasterize(m, T, cam, &out).ok());
  const size_t n = size_t(cam.width) * cam.height;
  EXPECT_EQ(test::FromDevice(ctx, out.depth_id, n), ref.depth_id);
  EXPECT_EQ(test::FromDevice(ctx, out.ids, n), ref.ids);
  EXPECT_TRUE(test::AllClose(test::Flatten(test::FromDevice(ctx, out.vertex, n)), test::Flatten(ref.vertex), 1e-6f, 1e-5f));
  EXPECT_TRUE(test::AllClose(test::Flatten(test::FromDevice(ctx, out.normal, n)), test::Flatten(ref.normal), 1e-5f, 1e-5f));
  EXPECT_TRUE(test::AllClose(test::Flatten(test::FromDevice(ctx, out.bary, n)), test::Flatten(ref.bary), 1e-6f, 1e-5f));

  // Against the analytic sphere: every covered pixel's depth is near the ray-sphere hit.
  const auto truth = test::SphereDepth(cam, 1.0f, 0.25f, 100.f);
  int covered = 0, expected = 0;
  double worst = 0;
  for (size_t i = 0; i < n; ++i) {
    const bool hit = truth[i] > 0.f && truth[i] < 50.f;
    expected += hit;
    if (ref.ids[i] == VD_RASTER_EMPTY) continue;
    ++covered;
    if (hit) worst = std::max(worst, std::fabs(double(ref.vertex[i].z) - truth[i]));
  }
  // The tessellation (48 x 96) sits inside the sphere by at most r (1 - cos(pi / 96)) ~ 0.13 mm
  // radially, more near the silhouette; the holes pattern of SphereDepth makes expected smaller.
  EXPECT_LT(worst, 0.004);
  EXPECT_GT(covered, expected * 0.97);
  EXPECT_LT(covered, expected * 1.06);
}

// Four triangles over the same pixels: ids 0 and 3 at 1.2 m, 1 and 2 at 1.0 m (1 and 2 the same
// triangle). The nearest depth wins whatever its id, and among equal depths the smallest id: the
// packed min(depth << 32 | id) is the two-pass rule (depth first, then id) in one atomic.
TEST(RasterParityTest, NearestDepthWinsAndTiesGoToTheSmallestId) {
  VD_REQUIRE_OCL(ctx);
  DeviceOps ops(ctx);
  ASSERT_TRUE(ops.Init().ok());
  std::vector<vd_float4> pos, nrm;
  std::vector<int32_t> tris;
  for (float z : {1.2f, 1.0f, 1.0f, 1.2f}) {
    const int b = int(pos.size());
    for (const auto& xy : {std::pair{-0.3f, -0.3f}, std::pair{0.3f, -0.3f}, std::pair{0.f, 0.3f}}) {
      pos.push_back(VD_F4(xy.first * z, xy.second * z, z, 1.f));
      nrm.push_back(VD_F4(0.f, 0.f, -1.f, 0.f));
    }
    tris.insert(tris.end(), {b, b + 2, b + 1});
  }
  const VdCamera cam = test::TestCamera(64, 48);
  const VdPose T = test::IdentityPose();
  cpu::RasterMaps ref;
  cpu::Rasterize(pos.data(), nrm.data(), tris.data(), 4, T, cam, &ref);
  DeviceMesh m;
  m.positions = test::ToDevice(ctx, pos);
  m.normals = test::ToDevice(ctx, nrm);
  m.triangles = test::ToDevice(ctx, tris);
  m.num_vertices = pos.size();
  m.num_triangles = 4;
  DeviceRaster out;
  ASSERT_TRUE(ops.Rasterize(m, T, cam, &out).ok());
  const size_t n = size_t(cam.width) * cam.height;
  const std::vector<uint32_t> ids = test::FromDevice(ctx, out.ids, n);
  EXPECT_EQ(ids, ref.ids);
  int covered = 0;
  for (size_t i = 0; i < n; ++i) {
    if (ids[i] == VD_RASTER_EMPTY) continue;
    ++covered;
    EXPECT_EQ(ids[i], 1u) << "pixel " << i;
    EXPECT_NEAR(ref.vertex[i].z, 1.0f, 1e-5f);
  }
  EXPECT_GT(covered, 100);
}

}  // namespace
}  // namespace vd
