#include <gtest/gtest.h>

#include "ocl/kernel.h"
#include "shared/correspondence.h"
#include "shared/features.h"
#include "shared/icp.h"
#include "shared/solver.h"
#include "shared/tsdf.h"
#include "test_scenes.h"

namespace vd {
namespace {

// Test-only kernel of kernels/types.cl: one item writes every size.
constexpr ocl::Kernel<void(ocl::Buffer<int32_t>& out)> kTypeSizes{"vd_type_sizes"};

TEST(TypesParityTest, SharedStructSizesMatchOnHostAndDevice) {
  VD_REQUIRE_OCL(ctx);
  // In the order of kernels/types.cl.
  const std::vector<int> host = {int(sizeof(VdCamera)),     int(sizeof(VdPose)),       int(sizeof(VdVolume)),
                                 int(sizeof(VdIcpParams)),  int(sizeof(vd_float4)),    int(sizeof(VdCorrespondence)),
                                 int(sizeof(VdCorrParams)), int(sizeof(VdLiftParams)), int(sizeof(VdSolverWeights)),
                                 int(sizeof(VdMatchBest)),  int(sizeof(VdMat3)),       int(sizeof(VdFusionParams)),
                                 int(sizeof(VdLattice))};
  auto out = ctx->Alloc<int32_t>(host.size());
  ASSERT_TRUE(out.ok());
  ASSERT_TRUE(kTypeSizes(*ctx, 1, *out).ok());
  const auto device = test::FromDevice(ctx, *out, host.size());
  for (size_t i = 0; i < host.size(); ++i) EXPECT_EQ(device[i], host[i]) << "struct #" << i;
  EXPECT_EQ(sizeof(VdCamera) % 16, 0u);
  EXPECT_EQ(sizeof(VdVolume) % 16, 0u);
  EXPECT_EQ(sizeof(VdLattice) % 16, 0u);
}

TEST(TypesParityTest, UnknownKernelAndBadDeviceGiveClearErrors) {
  VD_REQUIRE_OCL(ctx);
  constexpr ocl::Kernel<void(int n)> kMissing{"vd_no_such_kernel"};
  Status s = kMissing(*ctx, 1, 0);
  EXPECT_FALSE(s.ok());
  EXPECT_NE(s.message().find("CL_INVALID_KERNEL_NAME"), std::string::npos) << s.ToString();
  auto bad = ocl::Context::Create("no-such-device-xyz");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("available"), std::string::npos) << bad.status().ToString();
}

}  // namespace
}  // namespace vd
