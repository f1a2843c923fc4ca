// Issue 14's long-take bounds, on 300-frame takes of the synthetic scenes (the same motion as the
// 60-frame takes, a fifth of it per frame). Reached on tube, cloth and rigid since session 11; not
// yet on bend (its drift and tracked mesh): the "acceptance" label keeps this suite out of
// deploy/test.sh until they are; docs/BENCHMARKS.md ("Long takes") has the numbers. Each scene
// runs for about a minute on 2 cores.
#include <gtest/gtest.h>

#include "scene_eval.h"

namespace vd {
namespace {

test::SceneErrors LongTake(const std::string& scene) {
  test::SceneRun run;
  run.name = scene;
  run.num_frames = 300;
  run.report_every = 30;
  run.track_mesh = true;
  auto e = test::EvaluateScene(run);
  EXPECT_TRUE(e.ok()) << e.status().ToString();
  if (!e.ok()) return test::SceneErrors{};
  test::PrintErrors(scene + ", 300 frames", *e);
  return *e;
}

// The tube bounds: the canonical model stays true, the surface close, the drift bounded,
// and the tracked first-frame mesh near its material points.
void ExpectTubeBounds(const std::string& scene) {
  const test::SceneErrors e = LongTake(scene);
  ASSERT_EQ(e.frames, 300);
  EXPECT_GE(e.canonical_within_5mm, 0.95);
  EXPECT_LE(e.worst_surface_mm, 1.0);
  EXPECT_LE(e.last_drift_mm, 3.0);
  EXPECT_LE(e.tracked_mean_mm, 3.0);
}

TEST(LongTakeTest, TubeCanonicalModelStaysTrueAndDriftStaysBounded) { ExpectTubeBounds("tube"); }

// "bend": the tube closing to 150 degrees and staying there (no return to hide what went wrong),
// like the held-out take the issue measured; the tube's bounds apply.
TEST(LongTakeTest, BendCanonicalModelStaysTrueAndDriftStaysBounded) { ExpectTubeBounds("bend"); }

TEST(LongTakeTest, ClothDriftStaysBoundedWithFeatures) {
  const test::SceneErrors e = LongTake("cloth");
  ASSERT_EQ(e.frames, 300);
  EXPECT_LE(e.last_drift_mm, 3.0);
}

TEST(LongTakeTest, RigidSceneStaysRigid) {
  const test::SceneErrors e = LongTake("rigid");
  ASSERT_EQ(e.frames, 300);
  EXPECT_LE(e.last_nonrigid_mm, 1.0);
}

}  // namespace
}  // namespace vd
