// The rigid tracker's failure check: a frame of another scene is detected, reported, not fused,
// and the last good pose is kept; tracking then continues on the original scene.
#include <gtest/gtest.h>

#include "core/engine.h"
#include "ocl/ocl.h"
#include "vd/capture/synthetic.h"

namespace vd {
namespace {

TEST(TrackingFailureTest, ForeignFrameIsRejectedAndTheModelKept) {
  auto devices = ocl::ListDevices();
  if (!devices.ok() || devices->empty()) GTEST_SKIP() << "no OpenCL device";
  SyntheticOptions so;
  so.noise = false;
  auto rigid = MakeSyntheticScene("rigid", so);
  auto cloth = MakeSyntheticScene("cloth", so);
  ASSERT_TRUE(rigid.ok() && cloth.ok());
  EngineParams p;
  p.voxel_size = 0.008f;
  p.rigid_only = true;
  auto engine = Engine::Create(p, "");
  ASSERT_TRUE(engine.ok()) << engine.status().ToString();
  for (int k = 0; k < 3; ++k) {
    auto r = (*engine)->Process((*rigid)->Render(k));
    ASSERT_TRUE(r.ok() && r->tracking_ok);
  }
  std::vector<float> tsdf0, w0, tsdf1, w1;
  std::vector<uint32_t> c0, c1;
  auto good = (*engine)->Process((*rigid)->Render(3));
  ASSERT_TRUE(good.ok() && good->tracking_ok);
  ASSERT_TRUE((*engine)->DownloadVolume(&tsdf0, &w0, &c0).ok());

  RgbdFrame foreign = (*cloth)->Render(30);
  auto bad = (*engine)->Process(foreign);
  ASSERT_TRUE(bad.ok()) << bad.status().ToString();
  EXPECT_FALSE(bad->tracking_ok);
  EXPECT_NE(bad->tracking_message.find("kept the last good pose"), std::string::npos) << bad->tracking_message;
  EXPECT_TRUE(bad->pose.isApprox(good->pose, 1e-12));
  ASSERT_TRUE((*engine)->DownloadVolume(&tsdf1, &w1, &c1).ok());
  EXPECT_EQ(tsdf1, tsdf0) << "a frame that failed tracking must not be fused";
  EXPECT_EQ(w1, w0);

  // Back on the original scene, tracking recovers from the kept pose.
  auto again = (*engine)->Process((*rigid)->Render(4));
  ASSERT_TRUE(again.ok());
  EXPECT_TRUE(again->tracking_ok) << again->tracking_message;
}

}  // namespace
}  // namespace vd
