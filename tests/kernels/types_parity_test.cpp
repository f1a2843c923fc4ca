#include <gtest/gtest.h>

#include "shared/correspondence.h"
#include "shared/icp.h"
#include "test_scenes.h"

namespace vd {
namespace {

TEST(TypesParityTest, SharedStructSizesMatchOnHostAndDevice) {
  VD_REQUIRE_OCL(ctx);
  auto out = ctx->Alloc<int>(7);
  ASSERT_TRUE(out.ok());
  ASSERT_TRUE(ctx->Run("vd_type_sizes", 1, *out).ok());
  auto sizes = test::FromDevice(ctx, *out, 7);
  EXPECT_EQ(sizes[0], int(sizeof(VdCamera)));
  EXPECT_EQ(sizes[1], int(sizeof(VdPose)));
  EXPECT_EQ(sizes[2], int(sizeof(VdVolume)));
  EXPECT_EQ(sizes[3], int(sizeof(VdIcpParams)));
  EXPECT_EQ(sizes[4], int(sizeof(vd_float4)));
  EXPECT_EQ(sizes[5], int(sizeof(VdCorrespondence)));
  EXPECT_EQ(sizes[6], int(sizeof(VdCorrParams)));
  EXPECT_EQ(sizeof(VdCamera) % 16, 0u);
  EXPECT_EQ(sizeof(VdVolume) % 16, 0u);
}

TEST(TypesParityTest, UnknownKernelAndBadDeviceGiveClearErrors) {
  VD_REQUIRE_OCL(ctx);
  Status s = ctx->Run("vd_no_such_kernel", 1, 0);
  EXPECT_FALSE(s.ok());
  EXPECT_NE(s.message().find("CL_INVALID_KERNEL_NAME"), std::string::npos) << s.ToString();
  auto bad = ocl::Context::Create("no-such-device-xyz");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("available"), std::string::npos) << bad.status().ToString();
}

}  // namespace
}  // namespace vd
