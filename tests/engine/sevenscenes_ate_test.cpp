// Rigid tracking on the real 7-Scenes "redkitchen" sequence against its ground-truth poses.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <vector>

#include <Eigen/Geometry>

#include "core/engine.h"
#include "ocl/ocl.h"
#include "vd/capture/source.h"

namespace vd {
namespace {

const std::string kDir = std::string(VD_SHARED_DATA_DIR) + "/7scenes_redkitchen";

Eigen::Matrix4d ReadPose(const std::string& path) {
  std::ifstream in(path);
  Eigen::Matrix4d T;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) in >> T(r, c);
  return T;
}

// Absolute trajectory error (RMSE of camera positions, metres), two ways: anchored (world = first
// frame's camera, which both trajectories share by construction, no further alignment) and the
// standard ATE of Sturm et al. (TUM RGB-D benchmark): after the rigid alignment (Horn / Umeyama,
// no scale) of the estimated positions onto the ground truth.
TEST(SevenScenesTest, RigidTrackingAteOnRedKitchen) {
  if (!std::filesystem::exists(kDir + "/frame-000000.depth.png"))
    GTEST_SKIP() << kDir << " is absent (real data lives in ../shared/data; see its README)";
  auto devices = ocl::ListDevices();
  if (!devices.ok() || devices->empty()) GTEST_SKIP() << "no OpenCL device";
  auto source = OpenSource("folder:" + kDir, SourceOptions());
  ASSERT_TRUE(source.ok()) << source.status().ToString();
  EngineParams p;
  // 2 cm voxels keep this 300-frame test within a minute or two on 2 cores; the benchmark runs
  // the same sequence at finer voxels.
  p.voxel_size = 0.02f;
  p.max_depth = 3.5f;
  p.rigid_only = true;
  auto engine = Engine::Create(p, "");
  ASSERT_TRUE(engine.ok()) << engine.status().ToString();
  const Eigen::Matrix4d gt0_inv = ReadPose(kDir + "/frame-000000.pose.txt").inverse();
  double sum_sq = 0, worst = 0;
  int n = 0, lost = 0;
  std::vector<Eigen::Vector3d> est, gt;
  char name[64];
  while (true) {
    auto next = (*source)->Next();
    ASSERT_TRUE(next.ok()) << next.status().ToString();
    if (!next->has_value()) break;
    auto r = (*engine)->Process(**next);
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    lost += !r->tracking_ok;
    std::snprintf(name, sizeof(name), "/frame-%06d.pose.txt", n);
    const Eigen::Matrix4d truth = gt0_inv * ReadPose(kDir + name);
    est.push_back(r->pose.topRightCorner<3, 1>());
    gt.push_back(truth.topRightCorner<3, 1>());
    const double e = (truth.topRightCorner<3, 1>() - r->pose.topRightCorner<3, 1>()).norm();
    sum_sq += e * e;
    worst = std::max(worst, e);
    ++n;
  }
  const double ate = std::sqrt(sum_sq / n);
  Eigen::Matrix3Xd a(3, n), b(3, n);
  for (int k = 0; k < n; ++k) {
    a.col(k) = est[k];
    b.col(k) = gt[k];
  }
  const Eigen::Matrix4d align = Eigen::umeyama(a, b, false);
  const Eigen::Matrix3Xd aligned = (align.topLeftCorner<3, 3>() * a).colwise() + align.topRightCorner<3, 1>();
  const double ate_aligned = std::sqrt((aligned - b).colwise().squaredNorm().mean());
  std::printf("7-Scenes redkitchen: %d frames, ATE RMSE %.1f mm aligned (standard), %.1f mm anchored at frame 0 "
              "(worst %.1f mm), tracking lost on %d\n",
              n, ate_aligned * 1000, ate * 1000, worst * 1000, lost);
  EXPECT_EQ(n, 300);
  EXPECT_EQ(lost, 0);
  // KinectFusion-class systems reach a few centimetres on 7-Scenes. Bounds: 40 mm for the
  // standard (aligned) ATE, 60 mm anchored. Measured 2026-11-22 at 2 cm voxels: 29.2 mm aligned,
  // 52.6 mm anchored (1 cm voxels: 28.8 / 53.8 mm); the anchored error grows mostly between frames
  // 75 and 125 where the camera turns to parts of the kitchen the first view did not see.
  EXPECT_LT(ate_aligned, 0.04);
  EXPECT_LT(ate, 0.06);
}

}  // namespace
}  // namespace vd
