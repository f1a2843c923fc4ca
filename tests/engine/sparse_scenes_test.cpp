// The sparse colour term on the synthetic scenes (sensor noise, 4 mm voxels, 60 frames, defaults;
// issue: SIFT matches as global anchors):
//   - ablation on the waving cloth, whose slide and turn depth cannot see: last-frame drift <= 5 mm
//     with features and at most a third of the depth-only drift (both without the dense colour
//     term), and the colour term on top (--w-photo 0.03) takes at least a fifth off;
//   - fast motion: the bending tube fed every 2nd and every 3rd frame, last-frame drift <= 8 mm.
// Drift as in scene_eval.h. Measured numbers: docs/BENCHMARKS.md.
#include <gtest/gtest.h>

#include "scene_eval.h"

namespace vd {
namespace {

using test::EvaluateScene;
using test::HaveDevice;
using test::PrintErrors;
using test::SceneErrors;
using test::SceneRun;

// sift: E_sparse on; colour: the dense colour term on (--w-photo 0.03; off by default).
SceneErrors RunSparse(const std::string& name, bool sift, int stride, bool colour = false) {
  SceneRun run;
  run.name = name;
  run.params.features.enabled = sift;
  run.params.solver.w_photo = colour ? 0.06f : 0.f;
  run.stride = stride;
  auto e = EvaluateScene(run);
  EXPECT_TRUE(e.ok()) << e.status().ToString();
  if (!e.ok()) {
    SceneErrors failed;
    failed.last_drift_mm = failed.worst_surface_mm = 1e9;
    return failed;
  }
  PrintErrors(name + (sift ? " with features" : " without features") + (colour ? ", colour" : ", no colour") +
                  ", stride " + std::to_string(stride),
              *e);
  std::printf("  %.0f keypoints, %.0f lifted, %.0f matches per frame\n", e->mean_features, e->mean_lifted,
              e->mean_matches);
  return *e;
}

TEST(SparseScenesTest, ClothAblation) {
  if (!HaveDevice()) GTEST_SKIP() << "no OpenCL device";
  const SceneErrors with = RunSparse("cloth", true, 1, false);
  const SceneErrors without = RunSparse("cloth", false, 1, false);
  EXPECT_LE(with.last_drift_mm, 5.0);
  EXPECT_LE(with.last_drift_mm, without.last_drift_mm / 3.0);
  // The surface follows as well (depth-only loses the sheet).
  EXPECT_LE(with.worst_surface_mm, 2.0);
  EXPECT_GT(with.mean_matches, 100.0);
  // The dense colour term on top (--w-photo 0.06, on the coarse levels) pins the slide where no
  // feature matched: measured 2.24 -> 1.35 mm (docs/BENCHMARKS.md "Session 35").
  const SceneErrors colour = RunSparse("cloth", true, 1, true);
  EXPECT_TRUE(colour.colour_term_active);
  EXPECT_FALSE(with.colour_term_active);
  EXPECT_LE(colour.last_drift_mm, 0.7 * with.last_drift_mm);
  EXPECT_LE(colour.worst_surface_mm, with.worst_surface_mm + 0.05);
}

// On the rigid scene the colour term leaves the field still: its rows on the fine level too (session
// 28) gave a non-rigid displacement of 0.78 mm over these 60 frames; on the coarse levels alone
// 0.58 (0.49 without the term).
TEST(SparseScenesTest, ColourLeavesTheRigidSceneStill) {
  if (!HaveDevice()) GTEST_SKIP() << "no OpenCL device";
  const SceneErrors colour = RunSparse("rigid", true, 1, true);
  EXPECT_TRUE(colour.colour_term_active);
  EXPECT_LE(colour.last_nonrigid_mm, 0.7);
  EXPECT_LE(colour.worst_surface_mm, 1.0);
}

TEST(SparseScenesTest, TubeEverySecondFrame) {
  if (!HaveDevice()) GTEST_SKIP() << "no OpenCL device";
  const SceneErrors e = RunSparse("tube", true, 2);
  EXPECT_LE(e.last_drift_mm, 8.0);
  EXPECT_LE(e.worst_surface_mm, 2.0);
}

TEST(SparseScenesTest, TubeEveryThirdFrame) {
  if (!HaveDevice()) GTEST_SKIP() << "no OpenCL device";
  const SceneErrors e = RunSparse("tube", true, 3);
  EXPECT_LE(e.last_drift_mm, 8.0);
  EXPECT_LE(e.worst_surface_mm, 2.0);
}

}  // namespace
}  // namespace vd
