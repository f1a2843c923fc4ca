#include <gtest/gtest.h>

#include <cmath>

#include "core/device_ops.h"
#include "cpu_ref/cpu_ref.h"
#include "test_scenes.h"

namespace vd {
namespace {

VdVolume SphereVolume() {
  VdVolume vol{};
  vol.dim_x = vol.dim_y = vol.dim_z = 64;
  vol.voxel_size = 0.01f;
  vol.origin = VD_F4(-0.32f, -0.32f, 0.68f, 1.f);
  vol.truncation = 0.04f;
  vol.max_weight = 64.f;
  return vol;
}

TEST(TsdfParityTest, IntegrationMatchesCpuAndFindsTheSphere) {
  VD_REQUIRE_OCL(ctx);
  DeviceOps ops(ctx);
  ASSERT_TRUE(ops.Init().ok());
  const VdCamera cam = test::TestCamera(160, 120);
  const auto depth = test::SphereDepth(cam, 1.0f, 0.2f, 1.6f);
  const auto colors = test::TestColors(cam);
  const VdVolume vol = SphereVolume();
  const size_t n = size_t(vol.dim_x) * vol.dim_y * vol.dim_z;
  std::vector<float> tsdf(n, 1.f), weight(n, 0.f);
  std::vector<uint32_t> color(n, 0u);
  VdPose T = test::IdentityPose();
  for (int k = 0; k < 2; ++k) cpu::IntegrateTsdf(tsdf.data(), weight.data(), color.data(), vol, cam, T, depth.data(), colors.data());

  DeviceVolume dv;
  ASSERT_TRUE(ops.AllocVolume(vol, false, &dv).ok());
  auto ddepth = test::ToDevice(ctx, depth);
  auto dcol = test::ToDevice(ctx, colors);
  for (int k = 0; k < 2; ++k) ASSERT_TRUE(ops.IntegrateTsdf(dv, cam, T, ddepth, dcol).ok());
  EXPECT_TRUE(test::AllClose(test::FromDevice(ctx, dv.tsdf, n), tsdf, 1e-6f, 1e-5f));
  EXPECT_TRUE(test::AllClose(test::FromDevice(ctx, dv.weight, n), weight, 0.f, 0.f));
  EXPECT_EQ(test::FromDevice(ctx, dv.color, n), color);

  // The voxel nearest the sphere's front pole (0, 0, 0.8) has a distance near zero; one voxel
  // in front of it is positive, one behind negative.
  auto at = [&](float x, float y, float z) {
    int ix = int(std::lround((x - vol.origin.x) / vol.voxel_size));
    int iy = int(std::lround((y - vol.origin.y) / vol.voxel_size));
    int iz = int(std::lround((z - vol.origin.z) / vol.voxel_size));
    return size_t(ix + vol.dim_x * (iy + vol.dim_y * iz));
  };
  EXPECT_NEAR(tsdf[at(0.f, 0.f, 0.8f)] * vol.truncation, 0.f, 0.006f);
  EXPECT_GT(tsdf[at(0.f, 0.f, 0.78f)], 0.f);
  EXPECT_LT(tsdf[at(0.f, 0.f, 0.82f)], 0.f);
  EXPECT_EQ(weight[at(0.f, 0.f, 0.8f)], 2.f);
  // Far behind the surface nothing is observed.
  EXPECT_EQ(weight[at(0.f, 0.f, 0.95f)], 0.f);
}

}  // namespace
}  // namespace vd
