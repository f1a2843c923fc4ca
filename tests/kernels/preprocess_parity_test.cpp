#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>

#include "cpu_ref/cpu_ref.h"
#include "ocl/device_ops.h"
#include "test_scenes.h"

namespace vd {
namespace {

TEST(PreprocessParityTest, ConvertBilateralPyramidVertexNormalMatchCpu) {
  VD_REQUIRE_OCL(ctx);
  DeviceOps ops(ctx);
  ASSERT_TRUE(ops.Init().ok());
  const VdCamera cam = test::TestCamera(160, 120);
  const int n = cam.width * cam.height;
  const auto raw = test::SphereDepthRaw(cam, 1.0f, 0.25f, 1.6f);

  std::vector<float> depth_cpu(n);
  cpu::DepthConvert(raw.data(), depth_cpu.data(), n, 0.001f, 0.3f, 1.5f);
  auto draw = test::ToDevice(ctx, raw);
  auto ddepth = ctx->Alloc<float>(n);
  ASSERT_TRUE(ops.DepthConvert(draw, *ddepth, n, 0.001f, 0.3f, 1.5f).ok());
  const auto depth_ocl = test::FromDevice(ctx, *ddepth, n);
  EXPECT_TRUE(test::AllClose(depth_ocl, depth_cpu, 0.f, 0.f));
  // The wall at 1.6 m is clipped away; sphere pixels remain.
  int valid = 0;
  for (float d : depth_cpu) valid += d > 0.f;
  EXPECT_GT(valid, 1000);
  EXPECT_LT(valid, n / 2);

  std::vector<float> bil_cpu(n);
  cpu::Bilateral(depth_cpu.data(), bil_cpu.data(), cam.width, cam.height, 2, 3.f, 0.02f);
  auto dbil = ctx->Alloc<float>(n);
  ASSERT_TRUE(ops.Bilateral(*ddepth, *dbil, cam.width, cam.height, 2, 3.f, 0.02f).ok());
  EXPECT_TRUE(test::AllClose(test::FromDevice(ctx, *dbil, n), bil_cpu, 1e-6f, 1e-5f));

  std::vector<float> half_cpu(n / 4);
  cpu::PyrDown(bil_cpu.data(), half_cpu.data(), cam.width, cam.height, 0.05f);
  auto dhalf = ctx->Alloc<float>(n / 4);
  ASSERT_TRUE(ops.PyrDown(*dbil, *dhalf, cam.width, cam.height, 0.05f).ok());
  EXPECT_TRUE(test::AllClose(test::FromDevice(ctx, *dhalf, n / 4), half_cpu, 1e-6f, 1e-5f));

  std::vector<vd_float4> v_cpu(n), n_cpu(n);
  cpu::VertexMap(bil_cpu.data(), v_cpu.data(), cam);
  cpu::NormalMap(v_cpu.data(), n_cpu.data(), cam.width, cam.height, 0.05f);
  auto dv = ctx->Alloc<vd_float4>(n);
  auto dn = ctx->Alloc<vd_float4>(n);
  ASSERT_TRUE(ops.VertexMap(*dbil, *dv, cam).ok());
  ASSERT_TRUE(ops.NormalMap(*dv, *dn, cam.width, cam.height, 0.05f).ok());
  EXPECT_TRUE(test::AllClose(test::Flatten(test::FromDevice(ctx, *dv, n)), test::Flatten(v_cpu), 1e-6f, 1e-5f));
  // Normals difference nearby points, which amplifies the last-ulp differences of exp() in the
  // bilateral filter; 1e-4 is still far below anything tracking notices.
  EXPECT_TRUE(test::AllClose(test::Flatten(test::FromDevice(ctx, *dn, n)), test::Flatten(n_cpu), 1e-4f, 1e-4f));

  // Normals of the sphere point back to the camera and are unit length.
  int normals = 0;
  for (const auto& nv : n_cpu) {
    if (nv.w == 0.f) continue;
    ++normals;
    EXPECT_NEAR(nv.x * nv.x + nv.y * nv.y + nv.z * nv.z, 1.f, 1e-4f);
    EXPECT_LT(nv.z, 0.f);
  }
  EXPECT_GT(normals, valid / 2);
}

// The laned bilateral filter on an image whose rows are no multiple of any lane width, so lane
// groups straddle rows and the image's edges (the gather path) and the last group is partial:
// against the reference, and the same at lane widths 1, 4 and the device's own up to the last bits
// of exp() (PoCL's vector exp and its scalar one round differently).
// Packs 8-bit R, G, B as the frames are uploaded (R in the low byte, alpha 255).
uint32_t Rgba(int r, int g, int b) { return uint32_t(r) | uint32_t(g) << 8 | uint32_t(b) << 16 | 255u << 24; }

TEST(PreprocessParityTest, IntensityIsSmoothedHalfResolutionLumaAndMatchesCpu) {
  VD_REQUIRE_OCL(ctx);
  DeviceOps ops(ctx);
  ASSERT_TRUE(ops.Init().ok());
  // An odd size, so rows do not line up with any vector width (and the last column has no
  // 2x2 block); random colours.
  const int w = 97, h = 61, n = w * h, hw = w / 2, hh = h / 2, m = hw * hh;
  std::vector<uint32_t> rgba(n);
  std::srand(7);
  for (uint32_t& c : rgba) c = Rgba(std::rand() % 256, std::rand() % 256, std::rand() % 256);
  std::vector<float> ref(m);
  cpu::Intensity(rgba.data(), ref.data(), w, h);
  auto drgba = test::ToDevice(ctx, rgba);
  auto tmp = ctx->Alloc<float>(m), out = ctx->Alloc<float>(m);
  ASSERT_TRUE(tmp.ok() && out.ok());
  ASSERT_TRUE(ops.Intensity(drgba, *tmp, *out, w, h).ok());
  EXPECT_TRUE(test::AllClose(test::FromDevice(ctx, *out, m), ref, 1e-6f, 1e-6f));
  // Smoothing: the noise's spread falls (uniform luma has a standard deviation near 0.2).
  double mean = 0, var = 0;
  for (float v : ref) mean += v / m;
  for (float v : ref) var += (v - mean) * (v - mean) / m;
  EXPECT_NEAR(mean, 0.5, 0.02);
  EXPECT_LT(std::sqrt(var), 0.06);
  // Buffers too small for half resolution are refused.
  auto small = ctx->Alloc<float>(m - 1);
  ASSERT_TRUE(small.ok());
  EXPECT_FALSE(ops.Intensity(drgba, *tmp, *small, w, h).ok());

  // BT.601 luma: pure red, green and blue.
  EXPECT_NEAR(vd_rgba_luma(Rgba(255, 0, 0)), 0.299f, 1e-6f);
  EXPECT_NEAR(vd_rgba_luma(Rgba(0, 255, 0)), 0.587f, 1e-6f);
  EXPECT_NEAR(vd_rgba_luma(Rgba(0, 0, 255)), 0.114f, 1e-6f);
  // A horizontal ramp stays the same ramp away from the edges (the blur is symmetric), and sampled
  // back at full-resolution pixels it is the image's own value: the colour term's central
  // differences see the true gradient.
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) rgba[y * w + x] = Rgba(2 * x, 2 * x, 2 * x);
  cpu::Intensity(rgba.data(), ref.data(), w, h);
  for (int y = 0; y < h - 1; ++y)
    for (int x = 10; x < w - 10; ++x)
      ASSERT_NEAR(vd_intensity_at(ref.data(), hw, hh, float(x), float(y)), 2.f * x / 255.f, 1e-5f) << x << "," << y;
}

TEST(PreprocessParityTest, BilateralIsTheSameAtEveryLaneWidth) {
  VD_REQUIRE_OCL(ctx);
  const VdCamera cam = test::TestCamera(157, 61);
  const int n = cam.width * cam.height;
  const auto raw = test::SphereDepthRaw(cam, 1.0f, 0.25f, 1.4f);
  std::vector<float> depth(n);
  cpu::DepthConvert(raw.data(), depth.data(), n, 0.001f, 0.3f, 1.5f);
  std::vector<float> ref(n);
  cpu::Bilateral(depth.data(), ref.data(), cam.width, cam.height, 3, 3.f, 0.02f);
  auto run = [&](ocl::Context* c) {
    DeviceOps ops(c);
    EXPECT_TRUE(ops.Init().ok());
    auto din = test::ToDevice(c, depth);
    auto dout = c->Alloc<float>(n);
    EXPECT_TRUE(dout.ok());
    EXPECT_TRUE(ops.Bilateral(din, *dout, cam.width, cam.height, 3, 3.f, 0.02f).ok());
    return test::FromDevice(c, *dout, n);
  };
  const std::vector<float> native = run(ctx);
  EXPECT_TRUE(test::AllClose(native, ref, 1e-6f, 1e-5f));
  int smoothed = 0;
  for (int i = 0; i < n; ++i) smoothed += ref[i] > 0.f && ref[i] != depth[i];
  EXPECT_GT(smoothed, n / 10);
  for (const char* lanes : {"1", "4"}) {
    auto other = test::ContextWithLanes(*ctx, lanes);
    ASSERT_TRUE(other.ok()) << other.status().ToString();
    const std::vector<float> out = run(other->get());
    EXPECT_TRUE(test::AllClose(out, native, 1e-6f, 1e-6f)) << "lanes " << lanes;
  }
}

}  // namespace
}  // namespace vd
