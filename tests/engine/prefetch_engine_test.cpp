// The pipelined frame loop (Engine::Prefetch with --prefetch-preprocess on): the next frame is
// preprocessed on a second device queue while the current one is solved. Whatever is prefetched,
// skipped or dropped, every frame gives what it gives without prefetching.
#include <gtest/gtest.h>

#include <algorithm>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "core/engine.h"
#include "ocl/ocl.h"
#include "vd/capture/synthetic.h"

namespace vd {
namespace {

bool HaveDevice() {
  auto d = ocl::ListDevices();
  return d.ok() && !d->empty();
}

EngineParams Params(const std::string& prefetch) {
  EngineParams p;
  p.voxel_size = 0.008f;
  // Without features the engine is deterministic, so the two runs can be compared exactly.
  p.features.enabled = false;
  p.prefetch_preprocess = prefetch;
  return p;
}

struct Results {
  std::vector<Eigen::Matrix4d> poses;
  std::vector<TriangleMesh> meshes;
};

// Processes `order` (frame indices of the scene); before each, prefetches the frames `ahead`
// says (indices, -1 for none), as the server's receive thread or reader does.
Results Drive(const SyntheticScene& scene, const std::string& prefetch, const std::vector<int>& order,
              const std::vector<std::vector<int>>& ahead) {
  auto engine = Engine::Create(Params(prefetch), "");
  EXPECT_TRUE(engine.ok()) << engine.status().ToString();
  Results out;
  if (!engine.ok()) return out;
  for (size_t i = 0; i < order.size(); ++i) {
    for (int k : ahead[i]) (*engine)->Prefetch(scene.Render(k));
    auto r = (*engine)->Process(scene.Render(order[i]));
    EXPECT_TRUE(r.ok()) << r.status().ToString();
    if (!r.ok()) return out;
    EXPECT_TRUE(r->tracking_ok) << "frame " << order[i];
    out.poses.push_back(r->pose);
    out.meshes.push_back(r->live_mesh);
  }
  return out;
}

Eigen::Vector3d Centroid(const TriangleMesh& m) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < m.num_vertices(); ++i)
    c += Eigen::Vector3d(m.positions[3 * i], m.positions[3 * i + 1], m.positions[3 * i + 2]);
  return c / double(std::max<size_t>(1, m.num_vertices()));
}

// Two runs of the same frames agree to the engine's run-to-run noise (its device reductions are not
// bit-reproducible: up to 2e-5 in the pose and 0.03 mm in the centroid on a quiet machine, 0.14 mm
// beside another test), below what a frame's maps taken for another frame's would move: the tube's
// live surface moves 0.9-2 mm a frame (ConsecutiveFramesMoveFarMoreThanTheTolerance), and a mutant
// that took another waiting frame's maps was off by 0.8-1.4 mm.
void ExpectSame(const Results& a, const Results& b) {
  ASSERT_EQ(a.poses.size(), b.poses.size());
  for (size_t i = 0; i < a.poses.size(); ++i) {
    EXPECT_LT((a.poses[i] - b.poses[i]).cwiseAbs().maxCoeff(), 3e-4) << "frame " << i;
    const double na = double(a.meshes[i].num_vertices()), nb = double(b.meshes[i].num_vertices());
    EXPECT_NEAR(na, nb, 0.002 * na) << "frame " << i;
    EXPECT_LT((Centroid(a.meshes[i]) - Centroid(b.meshes[i])).norm(), 3e-4) << "frame " << i;
  }
}

// What the test's tolerance is set against: consecutive frames' centroids.
TEST(PrefetchEngineTest, ConsecutiveFramesMoveFarMoreThanTheTolerance) {
  if (!HaveDevice()) GTEST_SKIP() << "no OpenCL device";
  SyntheticOptions so;
  so.noise = true;
  so.num_frames = 60;
  auto scene = MakeSyntheticScene("tube", so);
  ASSERT_TRUE(scene.ok());
  const std::vector<int> order = {0, 1, 2, 3, 4, 5, 6, 7, 8};
  const Results r = Drive(**scene, "off", order, std::vector<std::vector<int>>(order.size()));
  ASSERT_EQ(r.meshes.size(), order.size());
  for (size_t i = 5; i + 1 < r.meshes.size(); ++i)
    EXPECT_GT((Centroid(r.meshes[i + 1]) - Centroid(r.meshes[i])).norm(), 6e-4) << "frames " << i << ", " << i + 1;
}

TEST(PrefetchEngineTest, PrefetchedSkippedAndDroppedFramesGiveTheSameResults) {
  if (!HaveDevice()) GTEST_SKIP() << "no OpenCL device";
  SyntheticOptions so;
  so.noise = true;
  // The first 12 frames of the 60-frame bend: small steps, so a skipped frame still tracks.
  so.num_frames = 60;
  auto scene = MakeSyntheticScene("tube", so);
  ASSERT_TRUE(scene.ok()) << scene.status().ToString();
  // A prefetch starts once Process opens its window (after tracking). Frames 0..5 each prefetched
  // one ahead (the bench and the offline reader: started beside the previous frame's solve); 7
  // (twice) and 8 offered before 6, so both start beside 6's solve, but 8 processed next (7
  // dropped); 10 never prefetched; 10 and 11 offered before 11 (10 too late, 11 not started).
  const std::vector<int> order = {0, 1, 2, 3, 4, 5, 6, 8, 10, 11};
  const std::vector<std::vector<int>> ahead = {{1}, {2}, {3}, {4}, {5}, {6}, {7, 7, 8}, {}, {}, {10, 11}};
  const std::vector<std::vector<int>> none(order.size());
  const Results plain = Drive(**scene, "off", order, none);
  const Results offered_off = Drive(**scene, "off", order, ahead);
  const Results pipelined = Drive(**scene, "on", order, ahead);
  ASSERT_EQ(plain.poses.size(), order.size());
  EXPECT_GT(plain.meshes.back().num_vertices(), 1000u);
  ExpectSame(plain, offered_off);
  ExpectSame(plain, pipelined);
}

TEST(PrefetchEngineTest, AFrameOfAnotherSizeWithTheSameNumberIsPreprocessedAgain) {
  if (!HaveDevice()) GTEST_SKIP() << "no OpenCL device";
  SyntheticOptions so;
  so.num_frames = 2;
  auto scene = MakeSyntheticScene("tube", so);
  ASSERT_TRUE(scene.ok());
  auto engine = Engine::Create(Params("on"), "");
  ASSERT_TRUE(engine.ok()) << engine.status().ToString();
  RgbdFrame f0 = (*scene)->Render(0);
  // A half-size frame under frame 0's number is prefetched; frame 0 itself must not take its maps.
  RgbdFrame small = f0;
  cv::resize(f0.depth, small.depth, cv::Size(), 0.5, 0.5, cv::INTER_NEAREST);
  cv::resize(f0.color, small.color, cv::Size(), 0.5, 0.5);
  small.intrinsics.width /= 2;
  small.intrinsics.height /= 2;
  small.intrinsics.fx /= 2;
  small.intrinsics.fy /= 2;
  small.intrinsics.cx /= 2;
  small.intrinsics.cy /= 2;
  (*engine)->Prefetch(small);
  auto r = (*engine)->Process(f0);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  auto reference = Engine::Create(Params("off"), "");
  ASSERT_TRUE(reference.ok());
  auto want = (*reference)->Process(f0);
  ASSERT_TRUE(want.ok());
  EXPECT_NEAR(double(r->live_mesh.num_vertices()), double(want->live_mesh.num_vertices()),
              0.002 * double(want->live_mesh.num_vertices()));
  EXPECT_LT((Centroid(r->live_mesh) - Centroid(want->live_mesh)).norm(), 3e-4);
  EXPECT_GT(r->live_mesh.num_vertices(), 1000u);
}

TEST(PrefetchEngineTest, AnUnknownSettingIsRefused) {
  EngineParams p;
  p.prefetch_preprocess = "sometimes";
  const Status s = p.Validate();
  EXPECT_FALSE(s.ok());
  EXPECT_NE(s.ToString().find("--prefetch-preprocess"), std::string::npos) << s.ToString();
}

}  // namespace
}  // namespace vd
