// Whole pipeline on the synthetic scenes with sensor noise, 4 mm voxels, 60 frames, default
// parameters, against ground truth (issue: OpenCL core part 2):
//   surface error = mean distance from live-mesh vertices to the true surface of that frame;
//   drift = mean distance between each live vertex and the true position, in that frame, of the
//   material point its canonical vertex lies on.
// Measured 2026-12-01 with the sparse colour term: worst-frame surface error 0.85 mm (bound 2),
// last-frame drift 1.5 mm (bound 5; 6.6 mm depth-only). Numbers: docs/BENCHMARKS.md.
#include <gtest/gtest.h>

#include "scene_eval.h"

namespace vd {
namespace {

using test::HaveDevice;
using test::RunScene;
using test::SceneErrors;

TEST(NonRigidScenesTest, BendingTube) {
  if (!HaveDevice()) GTEST_SKIP() << "no OpenCL device";
  const SceneErrors e = RunScene("tube", false);
  EXPECT_LE(e.worst_surface_mm, 2.0);
  EXPECT_LE(e.last_drift_mm, 5.0);
}

TEST(NonRigidScenesTest, NonRigidBeatsRigidOnTheTube) {
  if (!HaveDevice()) GTEST_SKIP() << "no OpenCL device";
  const SceneErrors nr = RunScene("tube", false);
  const SceneErrors rigid = RunScene("tube", true);
  EXPECT_LT(nr.mean_surface_mm, rigid.mean_surface_mm);
  EXPECT_LT(nr.last_drift_mm, rigid.last_drift_mm);
}

}  // namespace
}  // namespace vd
