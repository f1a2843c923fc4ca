#pragma once
// Small analytic inputs shared by the kernel tests: a sphere in front of a wall seen by a camera,
// and the OpenCL context the tests share.
#include <cstdint>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "ocl/ocl.h"
#include "shared/vd_types.h"

namespace vd::test {

// The process-wide test context. nullptr with an empty *error when no OpenCL device exists (the
// caller skips); nullptr with the reason in *error when a device exists but setup failed (for
// example a kernel build error: the caller fails).
ocl::Context* SharedContext(std::string* error);
// A new context on the same device as `like`, its laned kernels built with `lanes` ($VD_LANES
// for the call only).
StatusOr<std::unique_ptr<ocl::Context>> ContextWithLanes(const ocl::Context& like, const char* lanes);

#define VD_REQUIRE_OCL(ctx)                                                                     \
  std::string ctx##_error;                                                                      \
  ocl::Context* ctx = ::vd::test::SharedContext(&ctx##_error);                                  \
  if (!ctx && !ctx##_error.empty()) FAIL() << ctx##_error;                                      \
  if (!ctx) GTEST_SKIP() << "no OpenCL device (install pocl-opencl-icd; set POCL_CACHE_DIR)"

VdCamera TestCamera(int width = 160, int height = 120);
VdPose IdentityPose();
// Depth (metres, 0 invalid) of a sphere (centre cz metres ahead, radius r) in front of a wall at
// wall_z, with a few holes; deterministic.
std::vector<float> SphereDepth(const VdCamera& cam, float cz, float r, float wall_z);
// Raw uint16 millimetre depth of the same scene.
std::vector<uint16_t> SphereDepthRaw(const VdCamera& cam, float cz, float r, float wall_z);
// RGBA colour pattern.
std::vector<uint32_t> TestColors(const VdCamera& cam);

template <typename T>
ocl::Buffer<T> ToDevice(ocl::Context* ctx, const std::vector<T>& v) {
  auto b = ctx->Alloc<T>(v.size());
  EXPECT_TRUE(b.ok()) << b.status().ToString();
  ocl::Buffer<T> buf = std::move(b).value();
  EXPECT_TRUE(ctx->Upload(buf, v.data(), v.size()).ok());
  return buf;
}
template <typename T>
std::vector<T> FromDevice(ocl::Context* ctx, const ocl::Buffer<T>& b, size_t n) {
  std::vector<T> v(n);
  Status s = ctx->Download(b, v.data(), n);
  EXPECT_TRUE(s.ok()) << s.ToString();
  return v;
}
// Flattens float4 arrays into floats for AllClose.
std::vector<float> Flatten(const std::vector<vd_float4>& v);

// Relative/absolute closeness of two float arrays; reports the worst index.
::testing::AssertionResult AllClose(const std::vector<float>& a, const std::vector<float>& b, float atol, float rtol);

}  // namespace vd::test
