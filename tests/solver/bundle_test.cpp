// The keyframe bundle adjustment (core/bundle.h) on small exact problems: material points seen by a
// fixed first frame and by later frames whose lifts slid by a known amount; the adjustment must
// bring every later frame's points back onto the material points, through chains of matches and to
// points no match names, while wrong matches and frames without evidence leave things alone.
#include "core/bundle.h"

#include <gtest/gtest.h>

#include <cmath>

namespace vd {
namespace {

// Material points on a 12 x 6 patch of a cylinder of radius 20 voxels, 5 voxels apart (grid units).
std::vector<vd_float4> MaterialPoints() {
  std::vector<vd_float4> out;
  for (int i = 0; i < 12; ++i)
    for (int j = 0; j < 6; ++j) {
      const float a = 0.15f * float(j);
      out.push_back(VD_F4(40.f + 5.f * float(i), 60.f + 20.f * std::sin(a), 80.f - 20.f * std::cos(a), 1.f));
    }
  return out;
}

// Frame f sees material points `ids`, lifted with the slide s(p) (its field's error).
template <typename Slide>
std::vector<vd_float4> Lifted(const std::vector<vd_float4>& truth, const std::vector<int>& ids, Slide slide) {
  std::vector<vd_float4> out;
  for (int id : ids) {
    const vd_float4 s = slide(truth[id]);
    out.push_back(VD_F4(truth[id].x + s.x, truth[id].y + s.y, truth[id].z + s.z, 1.f));
  }
  return out;
}

// Links between the features of frames a and b that are the same material point.
void LinkCommon(int a, const std::vector<int>& ids_a, int b, const std::vector<int>& ids_b,
                std::vector<BundleLink>* out) {
  for (size_t i = 0; i < ids_a.size(); ++i)
    for (size_t j = 0; j < ids_b.size(); ++j)
      if (ids_a[i] == ids_b[j]) out->push_back({a, int(i), b, int(j)});
}

double MaxError(const std::vector<vd_float4>& truth, const std::vector<int>& ids, const std::vector<vd_float4>& pts) {
  double worst = 0.0;
  for (size_t i = 0; i < ids.size(); ++i) {
    const vd_float4& t = truth[ids[i]];
    worst = std::max(worst, double(std::hypot(pts[i].x - t.x, pts[i].y - t.y, pts[i].z - t.z)));
  }
  return worst;
}

std::vector<int> Range(int begin, int end) {
  std::vector<int> out;
  for (int i = begin; i < end; ++i) out.push_back(i);
  return out;
}

// Frame 0 (fixed, exact) sees the first half of the patch; frame 1 slid by (3, -2, 1) voxels sees
// the middle; frame 2 slid by (-2, 1, 2) sees the second half and shares points with frame 1 only.
struct Chain {
  std::vector<vd_float4> truth = MaterialPoints();
  std::vector<std::vector<int>> ids = {Range(0, 36), Range(18, 54), Range(36, 72)};
  std::vector<std::vector<vd_float4>> points;
  std::vector<BundleLink> links;
  std::vector<char> free = {0, 1, 1};
  Chain() {
    points.push_back(Lifted(truth, ids[0], [](const vd_float4&) { return VD_F4(0.f, 0.f, 0.f, 0.f); }));
    points.push_back(Lifted(truth, ids[1], [](const vd_float4&) { return VD_F4(3.f, -2.f, 1.f, 0.f); }));
    points.push_back(Lifted(truth, ids[2], [](const vd_float4&) { return VD_F4(-2.f, 1.f, 2.f, 0.f); }));
    // Only every third common point matched: the others must follow their neighbours.
    std::vector<BundleLink> all;
    LinkCommon(1, ids[1], 0, ids[0], &all);
    LinkCommon(2, ids[2], 1, ids[1], &all);
    for (size_t k = 0; k < all.size(); k += 3) links.push_back(all[k]);
  }
};

// An exact problem: the prior is what keeps the system definite, so it is tiny here.
BundleParams Exact() {
  BundleParams p;
  p.prior = 1e-7f;
  p.iterations = 2;
  return p;
}

TEST(BundleTest, ConstantSlidesComeBackThroughAChainOfMatches) {
  Chain c;
  ASSERT_GT(MaxError(c.truth, c.ids[1], c.points[1]), 3.7);
  ASSERT_GT(MaxError(c.truth, c.ids[2], c.points[2]), 2.9);
  BundleStats stats;
  ASSERT_TRUE(SolveBundle(Exact(), c.free, c.links, &c.points, &stats).ok());
  EXPECT_EQ(stats.free_frames, 2);
  EXPECT_EQ(stats.links, int(c.links.size()));
  EXPECT_EQ(stats.outliers, 0);
  EXPECT_GT(stats.rms_before, 3.0);
  EXPECT_LT(stats.rms_after, 1e-3);
  // Every point of the slid frames, matched or not, and frame 2 only through frame 1.
  EXPECT_LT(MaxError(c.truth, c.ids[1], c.points[1]), 1e-3);
  EXPECT_LT(MaxError(c.truth, c.ids[2], c.points[2]), 1e-3);
  // The fixed frame is untouched.
  EXPECT_EQ(MaxError(c.truth, c.ids[0], c.points[0]), 0.0);
}

TEST(BundleTest, ASmoothlyVaryingSlideIsFollowed) {
  // Frame 0 sees the whole patch, frame 1 too, with a slide growing along it from 0 to 4 voxels:
  // a correction that bends, found from every third point.
  const std::vector<vd_float4> truth = MaterialPoints();
  const std::vector<int> ids = Range(0, 72);
  std::vector<std::vector<vd_float4>> points = {
      Lifted(truth, ids, [](const vd_float4&) { return VD_F4(0.f, 0.f, 0.f, 0.f); }),
      Lifted(truth, ids, [](const vd_float4& p) {
        const float s = 4.f * (p.x - 40.f) / 55.f;
        return VD_F4(0.5f * s, -s, 0.f, 0.f);
      })};
  std::vector<BundleLink> links;
  for (int i = 0; i < 72; i += 3) links.push_back({1, i, 0, i});
  const double before = MaxError(truth, ids, points[1]);
  ASSERT_GT(before, 4.4);
  BundleParams p = Exact();
  p.smoothness = 0.05f;
  BundleStats stats;
  ASSERT_TRUE(SolveBundle(p, {0, 1}, links, &points, &stats).ok());
  EXPECT_LT(MaxError(truth, ids, points[1]), 0.1 * before);
}

TEST(BundleTest, AWrongMatchDoesNotDragTheFrame) {
  // Frame 1's point 0 (material 18) matched to frame 0's point 5 (material 5, 15 voxels away).
  auto solve = [](float huber_voxels, BundleStats* stats) {
    Chain c;
    c.links.push_back({1, 0, 0, 5});
    BundleParams p = Exact();
    p.huber_voxels = huber_voxels;
    p.iterations = 5;
    EXPECT_TRUE(SolveBundle(p, c.free, c.links, &c.points, stats).ok());
    return std::max(MaxError(c.truth, c.ids[1], c.points[1]), MaxError(c.truth, c.ids[2], c.points[2]));
  };
  BundleStats stats;
  const double robust = solve(BundleParams().huber_voxels, &stats);
  EXPECT_EQ(stats.outliers, 1);
  EXPECT_LT(robust, 0.6);
  // Counted quadratically, the same match drags the frames several times as far.
  const double plain = solve(1e4f, &stats);
  EXPECT_GT(plain, 3 * robust);
}

TEST(BundleTest, FramesWithoutEvidenceStayWhereTheyAre) {
  Chain c;
  // A fourth free frame no match names, slid by 5 voxels: nothing says where it should be.
  c.ids.push_back(Range(0, 72));
  c.points.push_back(Lifted(c.truth, c.ids[3], [](const vd_float4&) { return VD_F4(5.f, 0.f, 0.f, 0.f); }));
  c.free.push_back(1);
  const std::vector<vd_float4> before = c.points[3];
  BundleStats stats;
  ASSERT_TRUE(SolveBundle(Exact(), c.free, c.links, &c.points, &stats).ok());
  for (size_t i = 0; i < before.size(); ++i) EXPECT_EQ(c.points[3][i].x, before[i].x);
  // With every frame fixed, nothing moves.
  Chain fixed;
  fixed.free = {0, 0, 0};
  const auto frozen = fixed.points;
  ASSERT_TRUE(SolveBundle(Exact(), fixed.free, fixed.links, &fixed.points, &stats).ok());
  EXPECT_EQ(stats.links, 0);
  for (size_t f = 0; f < frozen.size(); ++f)
    for (size_t i = 0; i < frozen[f].size(); ++i) EXPECT_EQ(fixed.points[f][i].y, frozen[f][i].y);
}

TEST(BundleTest, MalformedProblemsAreRejected) {
  Chain c;
  BundleStats stats;
  auto bad = c.links;
  bad.push_back({1, 999, 0, 0});
  EXPECT_EQ(SolveBundle(Exact(), c.free, bad, &c.points, &stats).code(), StatusCode::kInvalidArgument);
  bad = c.links;
  bad.push_back({7, 0, 0, 0});
  EXPECT_EQ(SolveBundle(Exact(), c.free, bad, &c.points, &stats).code(), StatusCode::kInvalidArgument);
  c.points[1][0].w = 0.f;
  bad = c.links;
  bad.push_back({1, 0, 0, 0});
  EXPECT_EQ(SolveBundle(Exact(), c.free, bad, &c.points, &stats).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(SolveBundle(Exact(), {0, 1}, c.links, &c.points, &stats).code(), StatusCode::kInvalidArgument);
  BundleParams p;
  p.prior = 0.f;
  EXPECT_FALSE(p.Validate().ok());
  EXPECT_TRUE(BundleParams().Validate().ok());
}

}  // namespace
}  // namespace vd
