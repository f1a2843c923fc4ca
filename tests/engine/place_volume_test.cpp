// Where the dense grid goes at the first frame (Engine::PlaceVolume): when the memory budget cannot
// hold the requested room around the first view, the room gives way before the view does, so the
// surface the first frame saw is always in the grid (with --volume-margin 1.5 the old centre crop
// kept only the empty space in front of the tube, which was then lost in 59 of 60 frames).
#include <gtest/gtest.h>

#include "core/engine.h"

namespace vd {
namespace {

// A 640x480 view of a flat patch at 0.8 m covering columns 100..539 and rows 140..339 (about
// 0.67 x 0.30 m), with a step to 0.9 m on its right third.
RgbdFrame Patch() {
  RgbdFrame f;
  f.intrinsics = {525.f, 525.f, 319.5f, 239.5f, 640, 480};
  f.depth = cv::Mat(480, 640, CV_16UC1, cv::Scalar(0));
  f.depth(cv::Rect(100, 140, 300, 200)).setTo(800);
  f.depth(cv::Rect(400, 140, 140, 200)).setTo(900);
  return f;
}

struct Box {
  double lo[3], hi[3];
};

Box Extent(const VdVolume& v) {
  const double o[3] = {v.origin.x, v.origin.y, v.origin.z};
  const int d[3] = {v.dim_x, v.dim_y, v.dim_z};
  Box b;
  for (int a = 0; a < 3; ++a) {
    b.lo[a] = o[a];
    b.hi[a] = o[a] + (d[a] - 1) * double(v.voxel_size);
  }
  return b;
}

// The patch's points (metres, camera frame): x in [-0.33, 0.38], y in [-0.17, 0.17], z 0.8 / 0.9.
constexpr double kLo[3] = {(100 - 319.5) * 0.8 / 525, (140 - 239.5) * 0.9 / 525, 0.8};
constexpr double kHi[3] = {(539 - 319.5) * 0.9 / 525, (339 - 239.5) * 0.9 / 525, 0.9};

double Points(const VdVolume& v) { return double(v.dim_x) * v.dim_y * v.dim_z; }

TEST(PlaceVolumeTest, TheMarginGivesWayBeforeTheFirstView) {
  EngineParams p;
  const double budget = p.max_grid_mb * 1e6 / 44.0;
  // The default margin fits: the patch plus 0.1 m (and the truncation band) on every side.
  auto def = Engine::PlaceVolume(Patch(), p);
  ASSERT_TRUE(def.ok()) << def.status().ToString();
  const Box d = Extent(*def);
  for (int a = 0; a < 3; ++a) {
    EXPECT_LT(d.lo[a], kLo[a] - 0.1) << a;
    EXPECT_GT(d.hi[a], kHi[a] + 0.1) << a;
  }
  // 1.5 m does not fit 600 MB of 4 mm points: the grid keeps the whole patch and as much room
  // around it as the budget holds (more than the default's, the budget nearly used).
  p.volume_margin = 1.5f;
  auto wide = Engine::PlaceVolume(Patch(), p);
  ASSERT_TRUE(wide.ok()) << wide.status().ToString();
  EXPECT_LE(Points(*wide), budget);
  EXPECT_GT(Points(*wide), 0.9 * budget);
  const Box w = Extent(*wide);
  for (int a = 0; a < 3; ++a) {
    EXPECT_LT(w.lo[a], d.lo[a]) << a;
    EXPECT_GT(w.hi[a], d.hi[a]) << a;
  }
}

TEST(PlaceVolumeTest, AViewLargerThanTheBudgetKeepsItsNearPartAndCentre) {
  EngineParams p;
  p.max_grid_mb = 4.0;  // 90909 points: less than the patch alone needs at 4 mm
  p.volume_margin = 1.5f;
  auto v = Engine::PlaceVolume(Patch(), p);
  ASSERT_TRUE(v.ok()) << v.status().ToString();
  EXPECT_LE(Points(*v), p.max_grid_mb * 1e6 / 44.0);
  const Box b = Extent(*v);
  // The nearest surface is inside in depth, and the centre of the view in x and y.
  EXPECT_LT(b.lo[2], kLo[2]);
  EXPECT_GT(b.hi[2], kLo[2]);
  for (int a = 0; a < 2; ++a) {
    const double centre = 0.5 * (kLo[a] + kHi[a]);
    EXPECT_LT(b.lo[a], centre) << a;
    EXPECT_GT(b.hi[a], centre) << a;
  }
}

}  // namespace
}  // namespace vd
