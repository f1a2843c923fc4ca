// Rigid tracking on the real 7-Scenes "redkitchen" sequence against its ground-truth poses.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <vector>

#include "core/engine.h"
#include "ocl/ocl.h"
#include "trajectory_error.h"
#include "vd/capture/source.h"

namespace vd {
namespace {

const std::string kDir = std::string(VD_SHARED_DATA_DIR) + "/7scenes_redkitchen";

Eigen::Matrix4d ReadPose(const std::string& path) {
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  test::ReadPoseFile(path, &T);
  return T;
}

struct AteResult {
  int frames = 0, lost = 0;
  double ate_aligned = 0, ate_anchored = 0, worst = 0, ms_per_frame = 0;
  // The volume (dense: its box) and the last frame's canonical mesh (world metres).
  VdVolume volume{};
  TriangleMesh canonical;
};

bool HaveData() { return std::filesystem::exists(kDir + "/frame-000000.depth.png"); }
bool HaveDevice() {
  auto devices = ocl::ListDevices();
  return devices.ok() && !devices->empty();
}

// Absolute trajectory error: test::ComputeTrajectoryError (anchored and aligned).
StatusOr<AteResult> RunRedKitchen(bool rigid_only, bool sparse_volume = false) {
  VD_ASSIGN_OR_RETURN(auto source, OpenSource("folder:" + kDir, SourceOptions()));
  EngineParams p;
  // 2 cm voxels keep this 300-frame test within minutes on 2 cores; the benchmark runs the same
  // sequence at finer voxels.
  p.voxel_size = 0.02f;
  p.max_depth = 3.5f;
  p.rigid_only = rigid_only;
  p.sparse_volume = sparse_volume;
  VD_ASSIGN_OR_RETURN(auto engine, Engine::Create(p, ""));
  const Eigen::Matrix4d gt0_inv = ReadPose(kDir + "/frame-000000.pose.txt").inverse();
  AteResult out;
  double ms = 0;
  std::vector<Eigen::Vector3d> est, gt;
  char name[64];
  while (true) {
    VD_ASSIGN_OR_RETURN(auto next, source->Next());
    if (!next.has_value()) break;
    VD_ASSIGN_OR_RETURN(FrameResult r, engine->Process(*next));
    ms += r.times.Total();
    out.lost += !r.tracking_ok;
    std::snprintf(name, sizeof(name), "/frame-%06d.pose.txt", out.frames);
    const Eigen::Matrix4d truth = gt0_inv * ReadPose(kDir + name);
    est.push_back(r.pose.topRightCorner<3, 1>());
    gt.push_back(truth.topRightCorner<3, 1>());
    ++out.frames;
    out.canonical = std::move(r.canonical_mesh);
  }
  out.volume = engine->volume();
  const int n = out.frames;
  if (n == 0) return FailedPrecondition("no frames");
  const test::TrajectoryError ate = test::ComputeTrajectoryError(est, gt);
  out.ate_anchored = ate.anchored;
  out.ate_aligned = ate.aligned;
  out.worst = ate.worst;
  out.ms_per_frame = ms / n;
  std::printf(
      "7-Scenes redkitchen, %s: %d frames, ATE RMSE %.1f mm aligned (standard), %.1f mm anchored at frame 0 "
      "(worst %.1f mm), tracking lost on %d, %.0f ms per frame\n",
      sparse_volume ? "rigid-only, sparse volume" : (rigid_only ? "rigid-only" : "non-rigid"), n,
      out.ate_aligned * 1000, out.ate_anchored * 1000, out.worst * 1000, out.lost, out.ms_per_frame);
  return out;
}

// One test case for both modes: ctest runs every case in its own process, so two cases would
// repeat the rigid pass (about two minutes on 2 cores).
TEST(SevenScenesTest, RigidAteAndNonRigidModeKeepsIt) {
  if (!HaveData()) GTEST_SKIP() << kDir << " is absent (real data lives in ../shared/data; see its README)";
  if (!HaveDevice()) GTEST_SKIP() << "no OpenCL device";
  const auto rigid = RunRedKitchen(true);
  ASSERT_TRUE(rigid.ok()) << rigid.status().ToString();
  EXPECT_EQ(rigid->frames, 300);
  EXPECT_EQ(rigid->lost, 0);
  // KinectFusion-class systems reach a few centimetres on 7-Scenes. Bounds: 40 mm for the
  // standard (aligned) ATE, 60 mm anchored. Measured 2026-11-22 at 2 cm voxels: 29.2 mm aligned,
  // 52.6 mm anchored (1 cm voxels: 28.8 / 53.8 mm); the anchored error grows mostly between frames
  // 75 and 125 where the camera turns to parts of the kitchen the first view did not see.
  EXPECT_LT(rigid->ate_aligned, 0.04);
  EXPECT_LT(rigid->ate_anchored, 0.06);

  // A static scene in non-rigid mode (issue: OpenCL core part 2): the deformation field must not
  // cost tracking accuracy; bound: the non-rigid ATE within 10 % of the rigid one (both measures).
  // Measured 2026-11-22: 24.6 mm aligned, 45.3 mm anchored; 2026-12-03 with carving (--carve-rate
  // 0.5): 24.5 / 36.4 mm (26.3 / 45.1 without it, same build).
  const auto nonrigid = RunRedKitchen(false);
  ASSERT_TRUE(nonrigid.ok()) << nonrigid.status().ToString();
  EXPECT_EQ(nonrigid->frames, 300);
  EXPECT_EQ(nonrigid->lost, 0);
  EXPECT_LE(nonrigid->ate_aligned, 1.10 * rigid->ate_aligned);
  EXPECT_LE(nonrigid->ate_anchored, 1.10 * rigid->ate_anchored);

  // The sparse volume (issue 17): no box fixed at the first frame, so the camera moving through
  // the kitchen keeps fusing what the first view's box (the dense grid's) leaves out, and tracking
  // holds. Measured 2026-12-03 at 2 cm: 29.8 mm aligned, 53.9 mm anchored (dense 29.2 / 52.6).
  const auto sparse = RunRedKitchen(true, true);
  ASSERT_TRUE(sparse.ok()) << sparse.status().ToString();
  EXPECT_EQ(sparse->frames, 300);
  EXPECT_EQ(sparse->lost, 0);
  EXPECT_LT(sparse->ate_aligned, 0.04);
  EXPECT_LT(sparse->ate_anchored, 0.06);
  EXPECT_LE(sparse->ate_aligned, 1.05 * rigid->ate_aligned);
  const VdVolume& box = rigid->volume;
  size_t outside = 0;
  const size_t nv = sparse->canonical.num_vertices();
  for (size_t i = 0; i < nv; ++i) {
    const float p[3] = {sparse->canonical.positions[3 * i], sparse->canonical.positions[3 * i + 1],
                        sparse->canonical.positions[3 * i + 2]};
    const float o[3] = {box.origin.x, box.origin.y, box.origin.z};
    const int d[3] = {box.dim_x, box.dim_y, box.dim_z};
    for (int a = 0; a < 3; ++a)
      if (p[a] < o[a] || p[a] > o[a] + box.voxel_size * float(d[a] - 1)) {
        ++outside;
        break;
      }
  }
  std::printf("sparse volume: %zu of %zu canonical vertices lie outside the dense grid's box\n", outside, nv);
  EXPECT_GT(outside, nv / 10);
}

}  // namespace
}  // namespace vd
