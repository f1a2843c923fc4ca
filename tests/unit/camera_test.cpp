#include "vd/common/camera.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>

namespace vd {
namespace {

TEST(IntrinsicsTest, ParsesFlagAndValidates) {
  auto k = ParseIntrinsicsFlag("570.342,570.342,320,240", 640, 480);
  ASSERT_TRUE(k.ok()) << k.status().ToString();
  EXPECT_FLOAT_EQ(k->fx, 570.342f);
  EXPECT_TRUE(k->Validate().ok());
  EXPECT_FALSE(ParseIntrinsicsFlag("1,2,3", 640, 480).ok());
  EXPECT_FALSE(ParseIntrinsicsFlag("1,2,x,4", 640, 480).ok());
  Intrinsics bad = *k;
  bad.fx = NAN;
  EXPECT_NE(bad.Validate().message().find("fx"), std::string::npos);
  bad = *k;
  bad.cx = 1e6f;
  EXPECT_FALSE(bad.Validate().ok());
}

TEST(IntrinsicsTest, ScaledKeepsPixelCentres) {
  Intrinsics k{500.f, 500.f, 319.5f, 239.5f, 640, 480};
  Intrinsics h = k.Scaled(1);
  EXPECT_FLOAT_EQ(h.fx, 250.f);
  EXPECT_FLOAT_EQ(h.cx, 159.5f);
  EXPECT_EQ(h.width, 320);
}

TEST(IntrinsicsTest, LoadsMatrixFiles) {
  const std::string path = testing::TempDir() + "/k33.txt";
  {
    std::ofstream f(path);
    f << "585 0 320\n0 586 240\n0 0 1\n";
  }
  auto k = LoadIntrinsicsFile(path);
  ASSERT_TRUE(k.ok()) << k.status().ToString();
  EXPECT_FLOAT_EQ(k->fx, 585.f);
  EXPECT_FLOAT_EQ(k->fy, 586.f);
  EXPECT_FLOAT_EQ(k->cy, 240.f);
  {
    std::ofstream f(path);
    f << "517 0 320 0\n0 518 241 0\n0 0 1 0\n0 0 0 1\n";
  }
  k = LoadIntrinsicsFile(path);
  ASSERT_TRUE(k.ok());
  EXPECT_FLOAT_EQ(k->fy, 518.f);
  EXPECT_FLOAT_EQ(k->cy, 241.f);
  EXPECT_EQ(LoadIntrinsicsFile("/nonexistent/k.txt").status().code(), StatusCode::kNotFound);
  {
    std::ofstream f(path);
    f << "1 2 3 4 5\n";
  }
  EXPECT_EQ(LoadIntrinsicsFile(path).status().code(), StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace vd
