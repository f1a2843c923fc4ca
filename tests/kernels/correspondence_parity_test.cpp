#include <gtest/gtest.h>

#include <cmath>

#include "cpu_ref/cpu_ref.h"
#include "ocl/device_ops.h"
#include "sphere_volume.h"
#include "test_scenes.h"

namespace vd {
namespace {

VdCorrParams Params() {
  VdCorrParams p{};
  p.eps_d = 0.02f;
  p.eps_n = 0.5f;
  p.eps_v = 0.8f;
  p.cam_to_world = test::IdentityPose();
  return p;
}

TEST(CorrespondenceTest, WeightFollowsThePapersKernels) {
  const VdCorrParams p = Params();
  // Perfect agreement facing the camera: every Phi = 1, w = 1.
  EXPECT_FLOAT_EQ(vd_corr_weight(0.f, 1.f, 1.f, p), 1.f);
  // Half the distance threshold: Phi_d = 0.5, w = ((0.5 + 1 + 1) / 3)^2.
  EXPECT_NEAR(vd_corr_weight(0.01f, 1.f, 1.f, p), std::pow(2.5f / 3.f, 2.f), 1e-6f);
  // Any kernel below zero prunes: too far, normals too different, silhouette.
  EXPECT_EQ(vd_corr_weight(0.021f, 1.f, 1.f, p), 0.f);
  EXPECT_EQ(vd_corr_weight(0.f, 0.4f, 1.f, p), 0.f);
  EXPECT_EQ(vd_corr_weight(0.f, 1.f, 0.15f, p), 0.f);
  EXPECT_GT(vd_corr_weight(0.f, 1.f, 0.25f, p), 0.f);
}

TEST(CorrespondenceParityTest, SphereAgainstAShiftedObservationMatchesCpu) {
  VD_REQUIRE_OCL(ctx);
  DeviceOps ops(ctx);
  ASSERT_TRUE(ops.Init().ok());
  const VdCamera cam = test::TestCamera(160, 120);
  const int n = cam.width * cam.height;
  // Model: marching cubes of an analytic sphere, as canonical grid positions and world positions.
  const test::AnalyticVolume sphere = test::MakeSphereVolume(
      test::TestVolume(48, 48, 48, 0.01f, VD_F4(-0.24f, -0.24f, 0.76f, 1.f)), 0.f, 0.f, 1.f, 0.2f);
  const VdVolume& vol = sphere.vol;
  cpu::McMesh mc = cpu::MarchingCubes(sphere.tsdf.data(), sphere.weight.data(), sphere.color.data(), vol);
  std::vector<vd_float4> world(mc.positions_grid.size());
  for (size_t i = 0; i < world.size(); ++i)
    world[i] = VD_F4(vol.origin.x + 0.01f * mc.positions_grid[i].x, vol.origin.y + 0.01f * mc.positions_grid[i].y,
                     vol.origin.z + 0.01f * mc.positions_grid[i].z, 1.f);
  cpu::RasterMaps model;
  cpu::Rasterize(world.data(), mc.normals.data(), mc.triangles.data(), int(mc.triangles.size() / 3),
                 test::IdentityPose(), cam, &model);
  // Observation: the same sphere 5 mm closer.
  const auto depth = test::SphereDepth(cam, 0.995f, 0.2f, 100.f);
  std::vector<float> d2(depth);
  for (float& d : d2)
    if (d > 50.f) d = 0.f;
  std::vector<vd_float4> ov(n), on(n);
  cpu::VertexMap(d2.data(), ov.data(), cam);
  cpu::NormalMap(ov.data(), on.data(), cam.width, cam.height, 0.05f);
  const VdCorrParams prm = Params();
  std::vector<VdCorrespondence> ref(n);
  cpu::Correspondences(model, ov.data(), on.data(), mc.positions_grid.data(), mc.triangles.data(), prm, n, ref.data());

  int valid = 0;
  double mean_w = 0;
  for (const auto& c : ref) {
    if (c.canonical.w <= 0.f) continue;
    ++valid;
    mean_w += c.canonical.w;
    // The canonical point lies on the model sphere (grid units -> metres).
    const float x = vol.origin.x + 0.01f * c.canonical.x, y = vol.origin.y + 0.01f * c.canonical.y,
                z = vol.origin.z + 0.01f * c.canonical.z;
    ASSERT_NEAR(std::sqrt(x * x + y * y + (z - 1.f) * (z - 1.f)), 0.2f, 0.002f);
    ASSERT_LE(c.canonical.w, 1.f);
  }
  // The sphere covers ~2060 pixels (radius ~25.6 px); silhouette pixels are pruned by the view term.
  EXPECT_GT(valid, 1600);
  // 5 mm apart with eps_d = 2 cm: Phi_d ~ 0.75 in the centre, so w ~ 0.84 at best.
  EXPECT_LT(mean_w / valid, 0.9);
  EXPECT_GT(mean_w / valid, 0.4);

  DeviceMesh dm;
  dm.positions_grid = test::ToDevice(ctx, mc.positions_grid);
  dm.triangles = test::ToDevice(ctx, mc.triangles);
  dm.num_vertices = mc.positions_grid.size();
  dm.num_triangles = mc.triangles.size() / 3;
  DeviceRaster dr;
  dr.cam = cam;
  dr.vertex = test::ToDevice(ctx, model.vertex);
  dr.normal = test::ToDevice(ctx, model.normal);
  dr.ids = test::ToDevice(ctx, model.ids);
  dr.bary = test::ToDevice(ctx, model.bary);
  auto dov = test::ToDevice(ctx, ov), don = test::ToDevice(ctx, on);
  auto out = ctx->Alloc<VdCorrespondence>(n);
  ASSERT_TRUE(out.ok());
  ASSERT_TRUE(ops.Correspondences(dr, dov, don, dm, prm, *out).ok());
  const auto dev = test::FromDevice(ctx, *out, n);
  auto flatten = [](const std::vector<VdCorrespondence>& v) {
    std::vector<float> f;
    for (const auto& c : v)
      f.insert(f.end(), {c.canonical.x, c.canonical.y, c.canonical.z, c.canonical.w, c.target.x, c.target.y, c.target.z,
                         c.normal.x, c.normal.y, c.normal.z});
    return f;
  };
  EXPECT_TRUE(test::AllClose(flatten(dev), flatten(ref), 1e-5f, 1e-5f));
}

}  // namespace
}  // namespace vd
