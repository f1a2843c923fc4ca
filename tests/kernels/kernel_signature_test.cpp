// Typed kernel handles (ocl/kernel.h): a launch that does not match the declared signature does
// not compile, and a handle that disagrees with its .cl fails at its first launch.
#include <cstdlib>

#include <gtest/gtest.h>

#include <type_traits>

#include "ocl/preprocess_ocl.h"
#include "ocl/procrustes_ocl.h"
#include "ocl/scan_ocl.h"
#include "test_scenes.h"

namespace vd {
namespace {

using ocl::Buffer;
using ocl::Context;

template <class Handle, class... Args>
constexpr bool kLaunches = std::is_invocable_v<const Handle&, Context&, size_t, Args...>;

using DepthConvert = decltype(ocl::kDepthConvert);
using Procrustes = decltype(ocl::kProcrustesRefine);
using ScanSums = decltype(ocl::kScanSums);

// The launches the code makes compile: read buffers const or not, values of the exact type.
static_assert(kLaunches<DepthConvert, const Buffer<uint16_t>&, Buffer<float>&, float, float, float>);
static_assert(kLaunches<DepthConvert, Buffer<uint16_t>&, Buffer<float>&, const float&, float, float>);
static_assert(kLaunches<Procrustes, const Buffer<int32_t>&, const Buffer<float>&, const Buffer<vd_float4>&,
                        Buffer<vd_float4>&, Buffer<vd_float4>&, int32_t>);
static_assert(kLaunches<ScanSums, const Buffer<uint32_t>&, uint32_t, uint32_t, Buffer<uint32_t>&>);
// Swapped buffers of different element types.
static_assert(!kLaunches<DepthConvert, Buffer<float>&, Buffer<uint16_t>&, float, float, float>);
// A buffer the kernel writes passed const, or as a temporary.
static_assert(!kLaunches<DepthConvert, const Buffer<uint16_t>&, const Buffer<float>&, float, float, float>);
static_assert(!kLaunches<DepthConvert, const Buffer<uint16_t>&, Buffer<float>&&, float, float, float>);
static_assert(!kLaunches<Procrustes, const Buffer<int32_t>&, const Buffer<float>&, const Buffer<vd_float4>&,
                         Buffer<vd_float4>&, const Buffer<vd_float4>&, int32_t>);
// A written buffer swapped with a read one of the same type.
static_assert(!kLaunches<Procrustes, const Buffer<int32_t>&, const Buffer<float>&, Buffer<vd_float4>&,
                         const Buffer<vd_float4>&, const Buffer<vd_float4>&, int32_t>);
// Too few and too many arguments.
static_assert(!kLaunches<DepthConvert, const Buffer<uint16_t>&, Buffer<float>&, float, float>);
static_assert(!kLaunches<DepthConvert, const Buffer<uint16_t>&, Buffer<float>&, float, float, float, float>);
// Scalars that would convert: int or double for float, int for uint32_t, a buffer for a value.
static_assert(!kLaunches<DepthConvert, const Buffer<uint16_t>&, Buffer<float>&, int, float, float>);
static_assert(!kLaunches<DepthConvert, const Buffer<uint16_t>&, Buffer<float>&, float, double, float>);
static_assert(!kLaunches<ScanSums, const Buffer<uint32_t>&, int, uint32_t, Buffer<uint32_t>&>);
static_assert(!kLaunches<ScanSums, const Buffer<uint32_t>&, uint32_t, Buffer<uint32_t>&, Buffer<uint32_t>&>);
// A buffer of another element type where a value of that type is due.
static_assert(!kLaunches<ScanSums, const Buffer<int32_t>&, uint32_t, uint32_t, Buffer<uint32_t>&>);

TEST(KernelSignatureTest, AHandleThatDisagreesWithItsKernelFailsAtLaunch) {
  VD_REQUIRE_OCL(ctx);
  auto neighbours = test::ToDevice(ctx, std::vector<int32_t>(6, -1));
  auto t = test::ToDevice(ctx, std::vector<vd_float4>(1));
  auto rot = test::ToDevice(ctx, std::vector<vd_float4>(1));
  auto w = test::ToDevice(ctx, std::vector<float>(6, 1.f));
  ASSERT_TRUE(ocl::kProcrustesRefine(*ctx, 1, neighbours, w, t, t, rot, 0).ok());

  // vd_procrustes_refine_kernel has six arguments before vd_items; this handle declares three.
  constexpr ocl::Kernel<void(const Buffer<int32_t>& neighbours, const Buffer<vd_float4>& t, Buffer<vd_float4>& rot)>
      kShort{"vd_procrustes_refine_kernel"};
  const Status count = kShort(*ctx, 1, neighbours, t, rot);
  ASSERT_FALSE(count.ok());
  EXPECT_NE(count.message().find("vd_procrustes"), std::string::npos) << count.ToString();
  EXPECT_NE(count.message().find("in the program but its handle"), std::string::npos) << count.ToString();
  if (count.message().find("'rrrrwss'") == std::string::npos) {
    GTEST_SKIP() << "the device reports no argument kinds, so only counts are compared: " << count.ToString();
  }
  // Right count, but it claims to only read the rotations the kernel writes.
  constexpr ocl::Kernel<void(const Buffer<int32_t>& neighbours, const Buffer<float>& edge_w, const Buffer<vd_float4>& t,
                             const Buffer<vd_float4>& t_hat, const Buffer<vd_float4>& rot, int32_t iterations)>
      kReadOnly{"vd_procrustes_refine_kernel", ocl::kLaned};
  const Status kind = kReadOnly(*ctx, 1, neighbours, w, t, t, rot, 0);
  ASSERT_FALSE(kind.ok());
  EXPECT_NE(kind.message().find("'rrrrrss'"), std::string::npos) << kind.ToString();
}

// $VD_LANES picks the lane width of the laned kernels; anything but 1, 4, 8 or 16 is refused with
// a message naming it, before a program is built.
TEST(KernelSignatureTest, LaneWidthFromTheEnvironmentIsCheckedAndUsed) {
  VD_REQUIRE_OCL(ctx);
  EXPECT_TRUE(ctx->lanes() == 1 || ctx->lanes() == 4 || ctx->lanes() == 8 || ctx->lanes() == 16) << ctx->lanes();
  if (ctx->device().is_cpu) EXPECT_GT(ctx->lanes(), 1) << "a CPU device runs the laned kernels as SIMD";
  auto bad = test::ContextWithLanes(*ctx, "3");
  auto eight = test::ContextWithLanes(*ctx, "8");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("VD_LANES='3': expected 1, 4, 8 or 16"), std::string::npos)
      << bad.status().ToString();
  ASSERT_TRUE(eight.ok()) << eight.status().ToString();
  EXPECT_EQ((*eight)->lanes(), 8);
}

}  // namespace
}  // namespace vd
