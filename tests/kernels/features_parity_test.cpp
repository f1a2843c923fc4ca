// Feature kernels (kernels/features.cl) against their CPU references, and the pruning rules on
// constructed cases.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "cpu_ref/cpu_ref.h"
#include "cpu_ref/features_ref.h"
#include "ocl/features_ocl.h"
#include "shared/features.h"
#include "test_scenes.h"
#include "sphere_volume.h"

namespace vd {
namespace {

std::vector<uint8_t> RandomDescriptors(int n, std::mt19937* rng) {
  std::uniform_int_distribution<int> byte(0, 80);
  std::vector<uint8_t> d(size_t(n) * VD_DESC_BYTES);
  for (auto& b : d) b = uint8_t(byte(*rng));
  return d;
}

TEST(FeatureMatchParityTest, DistancesRowsAndColumnsMatchCpuAndFindPlantedMatches) {
  VD_REQUIRE_OCL(ctx);
  std::mt19937 rng(11);
  // Five earlier frames of 40..90 features; 120 current features, of which every third is a
  // noisy copy of a feature of frame 2 and every fifth of one of frame 4.
  const std::vector<int> sizes = {40, 90, 64, 57, 71};
  std::vector<int32_t> frames;
  std::vector<uint8_t> cand;
  for (int s : sizes) {
    frames.push_back(int32_t(cand.size() / VD_DESC_BYTES));
    auto d = RandomDescriptors(s, &rng);
    cand.insert(cand.end(), d.begin(), d.end());
    frames.push_back(int32_t(cand.size() / VD_DESC_BYTES));
  }
  const int n_cand = int(cand.size() / VD_DESC_BYTES), n_cur = 120;
  std::vector<uint8_t> cur = RandomDescriptors(n_cur, &rng);
  std::vector<int> planted(n_cur, -1);
  std::uniform_int_distribution<int> noise(-3, 3);
  for (int a = 0; a < n_cur; ++a) {
    int b = -1;
    if (a % 3 == 0) b = frames[4] + (a / 3) % sizes[2];
    else if (a % 5 == 0) b = frames[8] + (a / 5) % sizes[4];
    if (b < 0) continue;
    planted[a] = b;
    for (int j = 0; j < VD_DESC_BYTES; ++j)
      cur[size_t(a) * VD_DESC_BYTES + j] = uint8_t(std::clamp(int(cand[size_t(b) * VD_DESC_BYTES + j]) + noise(rng), 0, 255));
  }
  // CPU reference (candidates transposed as the kernels take them).
  std::vector<uint8_t> cand_t(cand.size());
  vd_desc_transpose(cand.data(), n_cand, cand_t.data());
  EXPECT_EQ(cand_t[size_t(5) * n_cand + 17], cand[size_t(17) * VD_DESC_BYTES + 5]);
  std::vector<float> dist(size_t(n_cur) * n_cand);
  cpu::MatchDistances(cur.data(), n_cur, cand_t.data(), n_cand, dist.data());
  const int nf = int(sizes.size());
  std::vector<VdMatchBest> rows(size_t(n_cur) * nf), cols(n_cand);
  cpu::MatchRows(dist.data(), n_cur, n_cand, frames.data(), nf, rows.data());
  cpu::MatchColumns(dist.data(), n_cur, n_cand, cols.data());
  // Device.
  auto d_cur = test::ToDevice(ctx, cur);
  auto d_cand = test::ToDevice(ctx, cand_t);
  auto d_frames = test::ToDevice(ctx, frames);
  auto d_dist = test::ToDevice(ctx, std::vector<float>(dist.size(), -1.f));
  auto d_rows = test::ToDevice(ctx, std::vector<VdMatchBest>(rows.size()));
  auto d_cols = test::ToDevice(ctx, std::vector<VdMatchBest>(cols.size()));
  ASSERT_TRUE(ocl::kMatchDistances(*ctx, size_t(n_cand), d_cur, n_cur, d_cand, n_cand, d_dist).ok());
  ASSERT_TRUE(ocl::kMatchRows(*ctx, rows.size(), d_dist, n_cur, n_cand, d_frames, d_rows).ok());
  ASSERT_TRUE(ocl::kMatchColumns(*ctx, cols.size(), d_dist, n_cur, n_cand, d_cols).ok());
  const auto g_dist = test::FromDevice(ctx, d_dist, dist.size());
  const auto g_rows = test::FromDevice(ctx, d_rows, rows.size());
  const auto g_cols = test::FromDevice(ctx, d_cols, cols.size());
  // Sums of integer squares below 2^24: exact on both sides.
  EXPECT_EQ(g_dist, dist);
  for (size_t i = 0; i < rows.size(); ++i) {
    ASSERT_EQ(g_rows[i].best, rows[i].best) << i;
    ASSERT_EQ(g_rows[i].best_d2, rows[i].best_d2) << i;
    ASSERT_EQ(g_rows[i].second_d2, rows[i].second_d2) << i;
  }
  for (size_t b = 0; b < cols.size(); ++b) {
    ASSERT_EQ(g_cols[b].best, cols[b].best) << b;
    ASSERT_EQ(g_cols[b].best_d2, cols[b].best_d2) << b;
  }
  // Spot check of one distance by hand.
  float d = 0;
  for (int j = 0; j < VD_DESC_BYTES; ++j) {
    const float e = float(cur[7 * VD_DESC_BYTES + j]) - float(cand[size_t(33) * VD_DESC_BYTES + j]);
    d += e * e;
  }
  EXPECT_EQ(dist[size_t(7) * n_cand + 33], d);
  // Every planted pair is the mutual best in its frame; unplanted features have no mutual match
  // that passes a ratio of 0.8 (random descriptors are all about equally far).
  int mutual_planted = 0;
  for (int a = 0; a < n_cur; ++a) {
    if (planted[a] < 0) continue;
    const int f = planted[a] < frames[5] ? 2 : 4;
    const VdMatchBest& r = rows[size_t(f) * n_cur + a];
    EXPECT_EQ(r.best, planted[a]) << a;
    EXPECT_LT(std::sqrt(r.best_d2), 0.3f * std::sqrt(r.second_d2)) << a;
    mutual_planted += cols[r.best].best == a;
  }
  EXPECT_EQ(mutual_planted, 40 + 16);
}

TEST(FeaturePruneTest, EachRuleOnConstructedCases) {
  const VdMatchPrune p = {250.f, 0.8f, 60.f, 0.08f};
  VdMatchBest m{};
  m.best = 3;
  m.best_d2 = 100.f * 100.f;
  m.second_d2 = 200.f * 200.f;
  const vd_float4 obs = VD_F4(0.f, 0.f, 1.f, 1.f);
  const vd_float4 near = VD_F4(0.01f, 0.f, 1.f, 1.f);
  EXPECT_EQ(vd_match_prune(m, near, obs, 5.f, 0.f, p), VD_PRUNE_KEPT);
  // Feature space: too far in absolute terms ...
  VdMatchBest far = m;
  far.best_d2 = 260.f * 260.f;
  far.second_d2 = 400.f * 400.f;
  EXPECT_EQ(vd_match_prune(far, near, obs, 5.f, 0.f, p), VD_PRUNE_DESCRIPTOR);
  // ... or not distinctive (ratio 0.9 > 0.8); a frame with a single candidate has no second.
  VdMatchBest amb = m;
  amb.second_d2 = (100.f / 0.9f) * (100.f / 0.9f);
  EXPECT_EQ(vd_match_prune(amb, near, obs, 5.f, 0.f, p), VD_PRUNE_RATIO);
  VdMatchBest single = m;
  single.second_d2 = 3.4e38f;
  EXPECT_EQ(vd_match_prune(single, near, obs, 5.f, 0.f, p), VD_PRUNE_KEPT);
  // Screen space: 61 px off, and exactly on the bound.
  EXPECT_EQ(vd_match_prune(m, near, obs, 61.f, 0.f, p), VD_PRUNE_SCREEN);
  EXPECT_EQ(vd_match_prune(m, near, obs, 36.f, 48.f, p), VD_PRUNE_KEPT);
  // 3D: 9 cm apart.
  EXPECT_EQ(vd_match_prune(m, VD_F4(0.f, 0.09f, 1.f, 1.f), obs, 5.f, 0.f, p), VD_PRUNE_WORLD);
  // No prediction (the earlier feature left the grid).
  EXPECT_EQ(vd_match_prune(m, VD_F4(0.f, 0.f, 0.f, 0.f), obs, 5.f, 0.f, p), VD_PRUNE_NO_POSITION);
  // NaN distances never pass.
  VdMatchBest nan = m;
  nan.best_d2 = std::nanf("");
  EXPECT_EQ(vd_match_prune(nan, near, obs, 5.f, 0.f, p), VD_PRUNE_DESCRIPTOR);
}

VdVolume LiftVolume() { return test::TestVolume(24, 20, 16, 0.01f, VD_F4(-0.12f, -0.1f, 0.4f, 1.f)); }

// A smooth non-affine field: a bend about the y axis growing with x, plus a shift.
std::vector<vd_float4> BentField(const VdVolume& vol) {
  std::vector<vd_float4> pos(size_t(vol.dim_x) * vol.dim_y * vol.dim_z), rot(pos.size());
  cpu::DeformationReset(pos.data(), rot.data(), vol);
  for (auto& p : pos) {
    const float a = 0.8f * (p.x + 0.12f);
    const float cz = 0.5f;
    const float x = p.x, z = p.z - cz;
    p = VD_F4(std::cos(a) * x + std::sin(a) * z + 0.01f, p.y + 0.005f, cz - std::sin(a) * x + std::cos(a) * z, 1.f);
  }
  return pos;
}

TEST(FeatureLiftParityTest, NewtonInvertsTheFieldAndMatchesCpu) {
  VD_REQUIRE_OCL(ctx);
  const VdVolume vol = LiftVolume();
  const std::vector<vd_float4> field = BentField(vol);
  const VdCamera cam = test::TestCamera(64, 48);
  const int pixels = cam.width * cam.height;
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> gx(3.f, float(vol.dim_x) - 4.f), gy(3.f, float(vol.dim_y) - 4.f),
      gz(3.f, float(vol.dim_z) - 4.f), off(-0.8f, 0.8f);
  // Each feature: a true canonical point g, its observation f = S(g), and a one-triangle raster
  // hit at its own pixel whose barycentric start is up to ~1.4 voxels off g.
  const int n = 40;
  std::vector<vd_float4> truth(n), points(n), canon;
  std::vector<int32_t> pixel(n), tris;
  std::vector<uint32_t> ids(pixels, VD_RASTER_EMPTY);
  std::vector<vd_float4> bary(pixels, VD_F4(0.f, 0.f, 0.f, 0.f)), raster_v(pixels, VD_F4(0.f, 0.f, 0.f, 0.f));
  const VdPose identity = test::IdentityPose();
  for (int i = 0; i < n; ++i) {
    truth[i] = VD_F4(gx(rng), gy(rng), gz(rng), 0.f);
    points[i] = vd_deform_point(truth[i], field.data(), vol);
    pixel[i] = 3 * i + 1;
    const vd_float4 start = VD_F4(truth[i].x + off(rng), truth[i].y + off(rng), truth[i].z + off(rng), 0.f);
    for (int c = 0; c < 3; ++c) {
      canon.push_back(start);
      tris.push_back(int32_t(canon.size() - 1));
    }
    ids[pixel[i]] = uint32_t(i);
    bary[pixel[i]] = VD_F4(0.2f, 0.3f, 0.5f, 1.f);
    raster_v[pixel[i]] = VD_F4(points[i].x, points[i].y, points[i].z + 0.004f, 1.f);
  }
  // Failure cases: an empty pixel, a raster 5 cm behind the observation, a point beyond the grid.
  points[1].w = 1.f;
  pixel[1] = 0;
  raster_v[pixel[2]].z += 0.05f;
  points[3] = VD_F4(5.f, 5.f, 5.f, 1.f);
  VdLiftParams lp{};
  lp.world_to_cam = identity;
  lp.max_depth_gap = 0.03f;
  lp.tolerance = 1e-4f;
  lp.iterations = 8;
  lp.no_model = 0;
  std::vector<vd_float4> ref(n);
  cpu::FeatureLift(points.data(), pixel.data(), n, ids.data(), bary.data(), raster_v.data(), canon.data(), tris.data(),
                   field.data(), vol, lp, ref.data());
  auto d_points = test::ToDevice(ctx, points);
  auto d_pixel = test::ToDevice(ctx, pixel);
  auto d_ids = test::ToDevice(ctx, ids);
  auto d_bary = test::ToDevice(ctx, bary);
  auto d_rv = test::ToDevice(ctx, raster_v);
  auto d_canon = test::ToDevice(ctx, canon);
  auto d_tris = test::ToDevice(ctx, tris);
  auto d_field = test::ToDevice(ctx, field);
  auto d_out = test::ToDevice(ctx, std::vector<vd_float4>(n));
  ASSERT_TRUE(ocl::kFeatureLift(*ctx, size_t(n), d_points, d_pixel, d_ids, d_bary, d_rv, d_canon, d_tris, d_field, vol,
                                ocl::Buffer<uint32_t>(), ocl::Buffer<int32_t>(), 0u, ocl::Buffer<int32_t>(), lp, d_out)
                  .ok());
  const auto got = test::FromDevice(ctx, d_out, n);
  int lifted = 0;
  for (int i = 0; i < n; ++i) {
    ASSERT_EQ(got[i].w, ref[i].w) << i;
    EXPECT_NEAR(got[i].x, ref[i].x, 1e-4f) << i;
    EXPECT_NEAR(got[i].y, ref[i].y, 1e-4f) << i;
    EXPECT_NEAR(got[i].z, ref[i].z, 1e-4f) << i;
    if (i >= 1 && i <= 3) {
      EXPECT_EQ(ref[i].w, 0.f) << "failure case " << i << " was lifted";
      continue;
    }
    ASSERT_EQ(ref[i].w, 1.f) << i;
    ++lifted;
    // Deformed back onto the observation (0.1 mm), and the true canonical point found (the field
    // is one-to-one here): within 0.02 voxels.
    const vd_float4 back = vd_deform_point(ref[i], field.data(), vol);
    EXPECT_LT(std::sqrt((back.x - points[i].x) * (back.x - points[i].x) + (back.y - points[i].y) * (back.y - points[i].y) +
                        (back.z - points[i].z) * (back.z - points[i].z)),
              1e-4f)
        << i;
    EXPECT_NEAR(ref[i].x, truth[i].x, 0.02f) << i;
    EXPECT_NEAR(ref[i].y, truth[i].y, 0.02f) << i;
    EXPECT_NEAR(ref[i].z, truth[i].z, 0.02f) << i;
  }
  EXPECT_EQ(lifted, n - 3);
  // The first frame (no model yet): the undeformed grid position of the world point.
  std::vector<vd_float4> rest(size_t(vol.dim_x) * vol.dim_y * vol.dim_z), rot(rest.size());
  cpu::DeformationReset(rest.data(), rot.data(), vol);
  lp.no_model = 1;
  const vd_float4 f = VD_F4(0.013f, -0.021f, 0.47f, 1.f);
  const vd_float4 g = vd_feature_lift(f, -1, ids.data(), bary.data(), raster_v.data(), canon.data(), tris.data(),
                                      rest.data(), vol, nullptr, nullptr, 0u, nullptr, lp);
  EXPECT_EQ(g.w, 1.f);
  EXPECT_NEAR(g.x, (0.013f + 0.12f) / 0.01f, 1e-3f);
  EXPECT_NEAR(g.y, (-0.021f + 0.1f) / 0.01f, 1e-3f);
  EXPECT_NEAR(g.z, (0.47f - 0.4f) / 0.01f, 1e-3f);
}

TEST(FeaturePredictParityTest, MatchesCpuAndSkipsInvalid) {
  VD_REQUIRE_OCL(ctx);
  const VdVolume vol = LiftVolume();
  const std::vector<vd_float4> field = BentField(vol);
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> u(0.f, 15.f);
  std::vector<vd_float4> g(100);
  for (size_t i = 0; i < g.size(); ++i) g[i] = VD_F4(u(rng), u(rng), u(rng), i % 7 == 0 ? 0.f : 1.f);
  std::vector<vd_float4> ref(g.size());
  cpu::FeaturePredict(g.data(), int(g.size()), field.data(), vol, ref.data());
  auto d_g = test::ToDevice(ctx, g);
  auto d_field = test::ToDevice(ctx, field);
  auto d_out = test::ToDevice(ctx, std::vector<vd_float4>(g.size()));
  ASSERT_TRUE(ocl::kFeaturePredict(*ctx, g.size(), d_g, d_field, vol, ocl::Buffer<uint32_t>(), ocl::Buffer<int32_t>(),
                                   0u, ocl::Buffer<int32_t>(), d_out)
                  .ok());
  const auto got = test::FromDevice(ctx, d_out, g.size());
  for (size_t i = 0; i < g.size(); ++i) {
    EXPECT_EQ(got[i].w, ref[i].w) << i;
    EXPECT_EQ(ref[i].w, i % 7 == 0 ? 0.f : 1.f);
    EXPECT_NEAR(got[i].x, ref[i].x, 1e-6f);
    EXPECT_NEAR(got[i].y, ref[i].y, 1e-6f);
    EXPECT_NEAR(got[i].z, ref[i].z, 1e-6f);
  }
}

}  // namespace
}  // namespace vd
