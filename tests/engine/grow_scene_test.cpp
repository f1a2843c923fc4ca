// Issue 17's scenes that grow beyond their first view, on the bricks (--sparse-volume):
// - "enter", a textured strip of which the first frame sees only one part, sliding 45 cm along
//   itself so that its other end enters the view. The mesh at the end must cover all of the strip
//   the camera sees. The depth the live model does not explain grows bricks (core/growth.h) and is
//   fused through the field there. A volume fixed at the first frame (the dense grid, kept as the
//   tests' reference) cannot hold the end that entered: it covers 65 % of the strip and none of that
//   end (docs/BENCHMARKS.md "Sparse volume").
// - "pass", a strip longer than the view sliding 60 cm through it, with a pool too small for all of
//   it: the bricks seen longest ago (the part that left the view) must be dropped with their field
//   (Engine::EvictUnseenBricks) and the part in view, including the end that entered, stay covered.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>

#include "scene_eval.h"

namespace vd {
namespace {

struct Coverage {
  // Of the strip's points the last frame sees, and of those that entered the view: within 5 mm of
  // the last live mesh.
  double in_view = 0.0, entered = 0.0;
  // Bricks: the most in use in any frame, the pool, and the bricks dropped over the take.
  int64_t most_used = 0, pool = 0, evicted = 0;
};

// Runs `name` (a strip sliding `slide` m to the right) through an engine with `params`.
Coverage RunStrip(const char* name, double slide, const EngineParams& params, const char* what) {
  Coverage c;
  SyntheticOptions so;
  so.noise = true;
  auto scene = MakeSyntheticScene(name, so);
  EXPECT_TRUE(scene.ok()) << scene.status().ToString();
  if (!scene.ok()) return c;
  const int n = (*scene)->num_frames();
  auto engine = Engine::Create(params, "");
  EXPECT_TRUE(engine.ok()) << engine.status().ToString();
  if (!engine.ok()) return c;
  FrameResult last;
  for (int k = 0; k < n; ++k) {
    auto r = (*engine)->Process((*scene)->Render(k));
    EXPECT_TRUE(r.ok()) << r.status().ToString();
    if (!r.ok()) return c;
    last = std::move(r).value();
    c.most_used = std::max(c.most_used, last.bricks_used);
  }
  c.pool = last.bricks_pool;
  c.evicted = last.bricks_evicted_total;
  EXPECT_GT(last.live_mesh.num_triangles(), 0u);
  const MeshDistance live(last.live_mesh);
  // The strip's points the last frame sees (inside the image, 20 pixels in from its borders); the
  // "entered" ones lie, in the first frame's space (x - slide now), past the part the first frame
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
    if (p.x() - float(slide) < -0.71f) {
      ++entered;
      entered_covered += near;
    }
  }
  EXPECT_GT(entered, 1000u);
  c.in_view = double(covered) / double(std::max<size_t>(seen, 1));
  c.entered = double(entered_covered) / double(std::max<size_t>(entered, 1));
  std::printf(
      "%s, %s, %d frames: %.1f %% of the strip in view within 5 mm of the last live mesh; of the part "
      "that entered %.1f %%; bricks: at most %lld of %lld in use, %lld dropped\n",
      name, what, n, 100.0 * c.in_view, 100.0 * c.entered, (long long)c.most_used, (long long)c.pool,
      (long long)c.evicted);
  return c;
}

TEST(GrowSceneTest, OnTheBricksTheMeshCoversASurfaceThatEntersFromOutsideTheFirstView) {
  if (!test::HaveDevice()) GTEST_SKIP() << "no OpenCL device";
  EngineParams p;
  p.sparse_volume = true;
  const Coverage c = RunStrip("enter", 0.45, p, "bricks");
  EXPECT_GE(c.in_view, 0.95);
  EXPECT_GE(c.entered, 0.95);
}

TEST(GrowSceneTest, AFullPoolDropsTheSurfaceThatLeftTheViewAndKeepsTheViewCovered) {
  if (!test::HaveDevice()) GTEST_SKIP() << "no OpenCL device";
  EngineParams p;
  p.sparse_volume = true;
  // The reference: a pool that holds all of the strip (some 1830 bricks over the take).
  const Coverage all = RunStrip("pass", 0.60, p, "bricks, 600 MB pool");
  EXPECT_EQ(all.evicted, 0);
  // 1410 bricks: the part in view and the bricks beside it need some 1300.
  p.max_grid_mb = 32;
  const Coverage c = RunStrip("pass", 0.60, p, "bricks, 32 MB pool");
  EXPECT_LT(c.pool, all.most_used);
  // What left the view is dropped (about a third of the strip, some 600 bricks), and what is dropped
  // is not needed again at once: bricks dropped and allocated again frame after frame would add up
  // to more than half the strip over the take.
  EXPECT_GE(c.evicted, 300);
  EXPECT_LT(c.evicted, all.most_used / 2);
  // Dropping what left the view costs the view (nearly) nothing. The slide, seen only by the
  // features, leaves the reference at 97.1 % of the strip in view and 92.8 % of the end that
  // entered (the 32 MB pool: 98.4 % and 96.0-96.2 %, 598 dropped; runs repeat but for the full
  // pool's race for its last slots, docs/ARCHITECTURE.md). Other builds and devices round
  // differently, and the take is chaotic enough to turn that into 2-3 points (before runs
  // repeated: 96.5-98.0 % and 91.4-95.1 %); losing part of the view would cost far more.
  EXPECT_GE(c.in_view, all.in_view - 0.03);
  EXPECT_GE(c.entered, all.entered - 0.05);
  EXPECT_GE(c.in_view, 0.94);
  EXPECT_GE(c.entered, 0.88);
}

}  // namespace
}  // namespace vd
