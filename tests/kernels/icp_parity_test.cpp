#include <gtest/gtest.h>

#include "cpu_ref/cpu_ref.h"
#include "ocl/device_ops.h"
#include "test_scenes.h"

namespace vd {
namespace {

TEST(IcpParityTest, NormalEquationsMatchCpu) {
  VD_REQUIRE_OCL(ctx);
  DeviceOps ops(ctx);
  ASSERT_TRUE(ops.Init().ok());
  const VdCamera cam = test::TestCamera(160, 120);
  const int n = cam.width * cam.height;
  // Model: the sphere scene; frame: the same scene seen 1 cm closer.
  const auto model_d = test::SphereDepth(cam, 1.0f, 0.25f, 1.5f);
  const auto frame_d = test::SphereDepth(cam, 0.99f, 0.25f, 1.49f);
  std::vector<vd_float4> mv(n), mn(n), fv(n), fn(n);
  cpu::VertexMap(model_d.data(), mv.data(), cam);
  cpu::NormalMap(mv.data(), mn.data(), cam.width, cam.height, 0.05f);
  cpu::VertexMap(frame_d.data(), fv.data(), cam);
  cpu::NormalMap(fv.data(), fn.data(), cam.width, cam.height, 0.05f);
  VdIcpParams prm{};
  prm.cam_to_world = test::IdentityPose();
  prm.world_to_model = test::IdentityPose();
  prm.model_to_world = test::IdentityPose();
  prm.model_cam = cam;
  prm.max_distance = 0.1f;
  prm.min_normal_dot = 0.8f;
  double ref[VD_ICP_ACC];
  cpu::IcpReduce(fv.data(), fn.data(), mv.data(), mn.data(), n, prm, ref);
  double dev[VD_ICP_ACC];
  auto dfv = test::ToDevice(ctx, fv), dfn = test::ToDevice(ctx, fn), dmv = test::ToDevice(ctx, mv), dmn = test::ToDevice(ctx, mn);
  ASSERT_TRUE(ops.IcpReduce(dfv, dfn, dmv, dmn, n, prm, dev).ok());
  for (int k = 0; k < VD_ICP_ACC; ++k) EXPECT_NEAR(dev[k], ref[k], 1e-4 * (1 + std::fabs(ref[k]))) << "entry " << k;
  EXPECT_GT(ref[28], 0.8 * n);
  // Mean residual: the frame is 1 cm closer everywhere; point-to-plane residual ~ -1 cm * n_z.
  EXPECT_NEAR(std::sqrt(ref[27] / ref[28]), 0.01, 0.004);
}

}  // namespace
}  // namespace vd
