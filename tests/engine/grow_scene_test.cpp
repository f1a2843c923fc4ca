// Issue 17's scene that grows beyond its first view: "enter", a textured strip of which the first
// frame sees only one part, sliding 45 cm along itself so that its other end enters the view. The
// mesh at the end must cover all of the strip the camera sees. On the bricks (--sparse-volume) the
// depth the live model does not explain grows bricks (core/growth.h) and is fused through the
// field there. A volume fixed at the first frame (the dense grid, kept as the tests' reference)
// cannot hold the end that entered: it covers 65 % of the strip and none of that end
// (docs/BENCHMARKS.md "Sparse volume").
#include <gtest/gtest.h>

#include <cstdio>

#include "scene_eval.h"

namespace vd {
namespace {

void ExpectCoverage(const EngineParams& params, const char* what) {
  SyntheticOptions so;
  so.noise = true;
  auto scene = MakeSyntheticScene("enter", so);
  ASSERT_TRUE(scene.ok()) << scene.status().ToString();
  const int n = (*scene)->num_frames();
  auto engine = Engine::Create(params, "");
  ASSERT_TRUE(engine.ok()) << engine.status().ToString();
  FrameResult last;
  for (int k = 0; k < n; ++k) {
    auto r = (*engine)->Process((*scene)->Render(k));
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    last = std::move(r).value();
  }
  ASSERT_GT(last.live_mesh.num_triangles(), 0u);
  const MeshDistance live(last.live_mesh);
  // The strip's points the last frame sees (inside the image, 20 pixels in from its borders); the
  // "entered" ones lie, in the first frame's space (x - 0.45 m now), past the part the first frame
  // saw (from x = -0.61 m, the image's left edge) and the volume's 10 cm margin.
  const Intrinsics& in = (*scene)->intrinsics();
  const TriangleMesh gt = (*scene)->GroundTruthMesh(n - 1);
  size_t seen = 0, covered = 0, entered = 0, entered_covered = 0;
  for (size_t i = 0; i < gt.num_vertices(); ++i) {
    const Eigen::Vector3f p = test::V(gt, i);
    const float u = in.fx * p.x() / p.z() + in.cx, v = in.fy * p.y() / p.z() + in.cy;
    if (u < 20.f || v < 20.f || u > in.width - 21.f || v > in.height - 21.f) continue;
    const bool near = live.Closest(p).distance < 0.005f;
    ++seen;
    covered += near;
    if (p.x() - 0.45f < -0.71f) {
      ++entered;
      entered_covered += near;
    }
  }
  ASSERT_GT(entered, 1000u);
  const double coverage = double(covered) / double(seen), entered_coverage = double(entered_covered) / double(entered);
  std::printf(
      "enter, %s, %d frames: %.1f %% of the strip in view within 5 mm of the last live mesh; of the part "
      "that entered %.1f %%\n",
      what, n, 100.0 * coverage, 100.0 * entered_coverage);
  EXPECT_GE(coverage, 0.95);
  EXPECT_GE(entered_coverage, 0.95);
}

TEST(GrowSceneTest, OnTheBricksTheMeshCoversASurfaceThatEntersFromOutsideTheFirstView) {
  if (!test::HaveDevice()) GTEST_SKIP() << "no OpenCL device";
  EngineParams p;
  p.sparse_volume = true;
  ExpectCoverage(p, "bricks");
}

}  // namespace
}  // namespace vd
