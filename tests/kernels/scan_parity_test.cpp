#include <gtest/gtest.h>

#include <numeric>
#include <random>

#include "ocl/device_ops.h"
#include "test_scenes.h"

namespace vd {
namespace {

TEST(ScanParityTest, MatchesStdExclusiveScanAtChunkBoundaries) {
  VD_REQUIRE_OCL(ctx);
  DeviceOps ops(ctx);
  ASSERT_TRUE(ops.Init().ok());
  std::mt19937 rng(7);
  for (size_t n : {size_t(0), size_t(1), size_t(255), size_t(256), size_t(257), size_t(65536), size_t(65537),
                   size_t(1000003)}) {
    std::vector<uint32_t> in(n);
    for (auto& v : in) v = rng() % 6;
    std::vector<uint32_t> expect(n + 1, 0);
    std::exclusive_scan(in.begin(), in.end(), expect.begin(), 0u);
    if (n) expect[n] = expect[n - 1] + in[n - 1];
    auto din = ctx->Alloc<uint32_t>(std::max<size_t>(n, 1));
    auto dout = ctx->Alloc<uint32_t>(n + 1);
    ASSERT_TRUE(din.ok() && dout.ok());
    ASSERT_TRUE(ctx->Upload(*din, in.data(), n).ok());
    uint32_t total = 12345;
    Status s = ops.ScanExclusive(*din, n, *dout, &total);
    ASSERT_TRUE(s.ok()) << s.ToString();
    EXPECT_EQ(total, expect[n]) << "n = " << n;
    EXPECT_EQ(test::FromDevice(ctx, *dout, n + 1), expect) << "n = " << n;
  }
}

}  // namespace
}  // namespace vd
