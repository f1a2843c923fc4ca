#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>

#include "cpu_ref/cpu_ref.h"
#include "ocl/device_ops.h"
#include "test_scenes.h"
#include "sphere_volume.h"

namespace vd {
namespace {

VdVolume SphereVolume() { return test::TestVolume(64, 64, 64, 0.01f, VD_F4(-0.32f, -0.32f, 0.68f, 1.f)); }

// A sphere of radius 0.2 m centred 1 m in front of a 160x120 camera, and the grid around it.
struct SphereView {
  VdCamera cam = test::TestCamera(160, 120);
  std::vector<float> depth = test::SphereDepth(cam, 1.0f, 0.2f, 1.6f);
  std::vector<uint32_t> colors = test::TestColors(cam);
  VdVolume vol = SphereVolume();
  size_t n = size_t(vol.dim_x) * vol.dim_y * vol.dim_z;
};

TEST(TsdfParityTest, IntegrationMatchesCpuAndFindsTheSphere) {
  VD_REQUIRE_OCL(ctx);
  DeviceOps ops(ctx);
  ASSERT_TRUE(ops.Init().ok());
  const SphereView view;
  const auto& [cam, depth, colors, vol, n] = view;
  std::vector<float> tsdf(n, 1.f), weight(n, 0.f);
  std::vector<uint32_t> color(n, 0u);
  VdPose T = test::IdentityPose();
  for (int k = 0; k < 2; ++k) cpu::IntegrateTsdf(tsdf.data(), weight.data(), color.data(), vol, cam, T, depth.data(), colors.data());

  DeviceVolume dv;
  ASSERT_TRUE(ops.AllocVolume(vol, false, &dv).ok());
  auto ddepth = test::ToDevice(ctx, depth);
  auto dcol = test::ToDevice(ctx, colors);
  for (int k = 0; k < 2; ++k) ASSERT_TRUE(ops.IntegrateTsdfDense(dv, cam, T, ddepth, dcol).ok());
  EXPECT_TRUE(test::AllClose(test::FromDevice(ctx, dv.tsdf, n), tsdf, 1e-6f, 1e-5f));
  EXPECT_TRUE(test::AllClose(test::FromDevice(ctx, dv.weight, n), weight, 0.f, 0.f));
  EXPECT_EQ(test::FromDevice(ctx, dv.color, n), color);

  // The voxel nearest the sphere's front pole (0, 0, 0.8) has a distance near zero; one voxel
  // in front of it is positive, one behind negative.
  auto at = [&](float x, float y, float z) {
    int ix = int(std::lround((x - vol.origin.x) / vol.voxel_size));
    int iy = int(std::lround((y - vol.origin.y) / vol.voxel_size));
    int iz = int(std::lround((z - vol.origin.z) / vol.voxel_size));
    return size_t(ix + vol.dim_x * (iy + vol.dim_y * iz));
  };
  EXPECT_NEAR(tsdf[at(0.f, 0.f, 0.8f)] * vol.truncation, 0.f, 0.006f);
  EXPECT_GT(tsdf[at(0.f, 0.f, 0.78f)], 0.f);
  EXPECT_LT(tsdf[at(0.f, 0.f, 0.82f)], 0.f);
  EXPECT_EQ(weight[at(0.f, 0.f, 0.8f)], 2.f);
  // Far behind the surface nothing is observed.
  EXPECT_EQ(weight[at(0.f, 0.f, 0.95f)], 0.f);
}

// Touched bricks (shared/tsdf.h): brick fusion flags exactly the bricks it marks, every brick with
// a weighted point is among them, MarkTouched rebuilds the CPU's flags, and marching cubes, which
// skips the untouched bricks, gives the CPU's mesh of the whole grid; with no brick touched it
// finds nothing, so the skip is real.
TEST(TsdfParityTest, TouchedBricksCoverEveryFusedPointAndMarchingCubesSkipsTheRest) {
  VD_REQUIRE_OCL(ctx);
  DeviceOps ops(ctx);
  ASSERT_TRUE(ops.Init().ok());
  const SphereView view;
  const auto& [cam, depth, colors, vol, n] = view;
  VdPose T = test::IdentityPose();
  T.r0.w = 0.01f;
  DeviceVolume dv;
  ASSERT_TRUE(ops.AllocVolume(vol, false, &dv).ok());
  ASSERT_EQ(dv.num_bricks(), 512u);
  EXPECT_EQ(test::FromDevice(ctx, dv.touched, dv.num_bricks()), std::vector<uint8_t>(512, 0));
  auto ddepth = test::ToDevice(ctx, depth);
  auto dcol = test::ToDevice(ctx, colors);
  for (int k = 0; k < 2; ++k) ASSERT_TRUE(ops.IntegrateTsdf(dv, cam, T, ddepth, dcol).ok());
  const std::vector<uint8_t> fused = test::FromDevice(ctx, dv.touched, 512);
  const std::vector<uint32_t> flags = test::FromDevice(ctx, ops.brick_flags(), 512);
  const std::vector<float> tsdf = test::FromDevice(ctx, dv.tsdf, n), weight = test::FromDevice(ctx, dv.weight, n);
  const std::vector<uint32_t> color = test::FromDevice(ctx, dv.color, n);
  const std::vector<uint8_t> exact = cpu::VolumeTouched(weight.data(), vol);
  size_t touched = 0, weighted = 0;
  for (size_t b = 0; b < 512; ++b) {
    EXPECT_EQ(fused[b], flags[b] ? 1 : 0) << b;
    if (exact[b]) EXPECT_EQ(fused[b], 1) << "brick " << b << " holds weight but is not touched";
    touched += fused[b];
    weighted += exact[b];
  }
  EXPECT_GT(weighted, 20u);
  EXPECT_LT(touched, 256u);
  ASSERT_TRUE(ops.MarkTouched(dv).ok());
  EXPECT_EQ(test::FromDevice(ctx, dv.touched, 512), exact);

  const cpu::McMesh ref = cpu::MarchingCubes(tsdf.data(), weight.data(), color.data(), vol);
  ASSERT_GT(ref.triangles.size(), 300u);
  DeviceMesh mesh;
  ASSERT_TRUE(ops.MarchingCubes(dv, &mesh).ok());
  ASSERT_EQ(mesh.num_triangles * 3, ref.triangles.size());
  EXPECT_EQ(test::FromDevice(ctx, mesh.triangles, ref.triangles.size()), ref.triangles);
  EXPECT_TRUE(test::AllClose(test::Flatten(test::FromDevice(ctx, mesh.positions_grid, mesh.num_vertices)),
                             test::Flatten(ref.positions_grid), 1e-6f, 1e-6f));
  ASSERT_TRUE(ctx->Fill(dv.touched, uint8_t{0}, 512).ok());
  ASSERT_TRUE(ops.MarchingCubes(dv, &mesh).ok());
  EXPECT_EQ(mesh.num_triangles, 0u);
}

// One vd_tsdf_integrate_active on the device from the given grid state; the state after it.
struct FusedState {
  std::vector<float> tsdf, weight;
  std::vector<uint32_t> color;
};
FusedState FuseActiveOnDevice(ocl::Context* ctx, DeviceOps& ops, const SphereView& view, const FusedState& before,
                              const std::vector<vd_float4>& pos, const std::vector<int>& list, const VdFusionParams& fp,
                              const VdPose& T) {
  const size_t n = view.n;
  DeviceVolume dv;
  EXPECT_TRUE(ops.AllocVolume(view.vol, true, &dv).ok());
  EXPECT_TRUE(ctx->Upload(dv.tsdf, before.tsdf.data(), n).ok());
  EXPECT_TRUE(ctx->Upload(dv.weight, before.weight.data(), n).ok());
  EXPECT_TRUE(ops.MarkTouched(dv).ok());
  EXPECT_TRUE(ctx->Upload(dv.color, before.color.data(), n).ok());
  EXPECT_TRUE(ctx->Upload(dv.def_pos, pos.data(), n).ok());
  DeviceActiveSet active;
  active.list = test::ToDevice(ctx, list);
  active.count = list.size();
  EXPECT_TRUE(ops.IntegrateActive(dv, active, fp, view.cam, T, test::ToDevice(ctx, view.depth),
                                  test::ToDevice(ctx, view.colors))
                  .ok());
  // Every brick holding weight after the fusion is touched (new points fused included).
  const std::vector<uint8_t> touched = test::FromDevice(ctx, dv.touched, dv.num_bricks());
  const std::vector<float> weight = test::FromDevice(ctx, dv.weight, n);
  const std::vector<uint8_t> exact = cpu::VolumeTouched(weight.data(), view.vol);
  for (size_t b = 0; b < exact.size(); ++b)
    if (exact[b]) EXPECT_EQ(touched[b], 1) << "brick " << b << " holds weight but is not touched";
  return {test::FromDevice(ctx, dv.tsdf, n), test::FromDevice(ctx, dv.weight, n), test::FromDevice(ctx, dv.color, n)};
}

// Non-rigid fusion of the active points at their deformed positions, on the device and the CPU:
// a point optimised fewer than k_min times is not fused; one never fused before (weight 0) waits
// for k_min_new; the deformation moves where a point samples the depth.
TEST(TsdfParityTest, ActiveIntegrationMatchesCpuAndGatesNewSpaceLonger) {
  VD_REQUIRE_OCL(ctx);
  DeviceOps ops(ctx);
  ASSERT_TRUE(ops.Init().ok());
  const SphereView view;
  const auto& [cam, depth, colors, vol, n] = view;
  std::vector<float> tsdf(n, 1.f), weight(n, 0.f);
  std::vector<uint32_t> color(n, 0u);
  std::vector<vd_float4> pos(n), rot(n);
  cpu::DeformationReset(pos.data(), rot.data(), vol);
  // Points along the line through the sphere's front pole (x = y = 0), z = 0.70 .. 0.82 m: all in
  // front of the surface (0.8 m) or inside the truncation band behind it.
  auto at = [&](int iz) { return int(32 + vol.dim_x * (32 + vol.dim_y * iz)); };
  std::vector<int> list;
  for (int iz = 2; iz <= 14; ++iz) list.push_back(at(iz));
  ASSERT_GT(vol.truncation, 0.021f);
  // Counts: below k_min (3) at iz 2, 3; between k_min and k_min_new (12) at 4..8; 12 at 9..14. Old
  // space (weight 1 already) at odd iz, new space (weight 0) at even iz. The field moves the points
  // at iz 12..14 3 cm towards the camera.
  for (int iz = 2; iz <= 14; ++iz) {
    const int i = at(iz);
    pos[i].w = iz <= 3 ? 2.f : (iz <= 8 ? 5.f : 12.f);
    if (iz % 2) weight[i] = 1.f;
    if (iz >= 12) pos[i].z -= 0.03f;
  }
  // New space in a brick nothing else has weight in (x 40..47, y 32..39, z 8..15), 3.7 cm in front
  // of the sphere: fusing it must flag its brick touched (FuseActiveOnDevice checks).
  const int fresh = 40 + vol.dim_x * (32 + vol.dim_y * 10);
  list.push_back(fresh);
  pos[fresh].w = 12.f;
  VdFusionParams fp{};
  fp.k_min = 3.f;
  fp.k_min_new = 12.f;  // no carving: the points in front of the surface are fused as free space
  const VdPose T = test::IdentityPose();
  std::vector<float> tsdf_ref = tsdf, weight_ref = weight;
  std::vector<uint32_t> color_ref = color;
  cpu::IntegrateActive(tsdf_ref.data(), weight_ref.data(), color_ref.data(), list.data(), int(list.size()), pos.data(),
                       fp, vol, cam, T, depth.data(), colors.data());
  int fused = 0;
  for (int iz = 2; iz <= 14; ++iz) {
    const int i = at(iz);
    const bool want = iz >= 4 && (iz % 2 == 1 || iz >= 9);
    EXPECT_EQ(weight_ref[i], weight[i] + (want ? 1.f : 0.f)) << "iz " << iz;
    fused += want;
  }
  EXPECT_EQ(fused, 8);  // iz 5, 7 (old, 5 optimisations) and 9..14
  EXPECT_EQ(weight_ref[fresh], 1.f);
  // Where the field moved it, a point samples the depth 3 cm nearer: iz 13 (0.81 m, old) is fused as
  // a point at 0.78 m, the distance iz 10 (0.78 m, new) got, averaged with its weight-1 value 1.
  EXPECT_NEAR(tsdf_ref[at(13)], 0.5f * (1.f + tsdf_ref[at(10)]), 1e-5f);
  EXPECT_GT(tsdf_ref[at(10)], 0.3f);  // 2 cm in front of the surface

  const FusedState dev = FuseActiveOnDevice(ctx, ops, view, {tsdf, weight, color}, pos, list, fp, T);
  EXPECT_TRUE(test::AllClose(dev.tsdf, tsdf_ref, 1e-6f, 1e-5f));
  EXPECT_TRUE(test::AllClose(dev.weight, weight_ref, 0.f, 0.f));
  EXPECT_EQ(dev.color, color_ref);
}

// Carving: a stale surface 8 cm in front of the sphere's pole (fused at full weight with a
// deformation since corrected, or by a part that has moved) is unlearnt in a few frames where the
// depth sees free space, and kept for many more without carving; the true surface is untouched,
// and a point just outside the sphere's rim, whose own pixel sees the wall while its neighbours see
// the sphere, is carved only when the window is a single pixel. Device and CPU agree.
TEST(TsdfParityTest, CarvingUnlearnsStaleSurfaceOnlyWhereTheDepthSeesFreeSpace) {
  VD_REQUIRE_OCL(ctx);
  DeviceOps ops(ctx);
  ASSERT_TRUE(ops.Init().ok());
  const SphereView view;
  const auto& [cam, depth, colors, vol, n] = view;
  ASSERT_FLOAT_EQ(vol.truncation, 0.04f);
  auto at = [&](int ix, int iz) { return int(ix + vol.dim_x * (32 + vol.dim_y * iz)); };
  auto z_of = [&](int iz) { return vol.origin.z + vol.voxel_size * float(iz); };
  std::vector<float> tsdf(n, 1.f), weight(n, 0.f);
  std::vector<uint32_t> color(n, 0u);
  std::vector<vd_float4> pos(n), rot(n);
  cpu::DeformationReset(pos.data(), rot.data(), vol);
  std::vector<int> list;
  // The pole line x = y = 0: a stale surface at 0.72 m up to z = 0.76 m (iz 0..8), the true one
  // (0.80 m) from 0.79 m (iz 11..14); all fused at the weight cap.
  for (int iz = 0; iz <= 14; ++iz) {
    if (iz == 9 || iz == 10) continue;
    const int i = at(32, iz);
    const float surface = iz <= 8 ? 0.72f : 0.80f;
    tsdf[i] = std::clamp((surface - z_of(iz)) / vol.truncation, -1.f, 1.f);
    weight[i] = vol.max_weight;
    list.push_back(i);
  }
  // Just outside the rim: (0.21, 0, 1.0) m, stale surface.
  const int rim = at(53, 32);
  tsdf[rim] = -0.5f;
  weight[rim] = vol.max_weight;
  list.push_back(rim);
  for (int i : list) pos[i].w = 12.f;
  VdFusionParams fp{};
  fp.k_min = 3.f;
  fp.k_min_new = 20.f;
  fp.carve_rate = 0.5f;
  fp.carve_radius = 2;
  const VdPose T = test::IdentityPose();

  auto run = [&](VdFusionParams p, int frames, std::vector<float>* t, std::vector<float>* w) {
    *t = tsdf;
    *w = weight;
    std::vector<uint32_t> c = color;
    for (int k = 0; k < frames; ++k)
      cpu::IntegrateActive(t->data(), w->data(), c.data(), list.data(), int(list.size()), pos.data(), p, vol, cam, T,
                           depth.data(), colors.data());
  };
  std::vector<float> t_carve, w_carve, t_keep, w_keep;
  VdFusionParams off = fp;
  off.carve_rate = 0.f;
  run(fp, 6, &t_carve, &w_carve);
  run(off, 6, &t_keep, &w_keep);
  for (int iz = 0; iz <= 7; ++iz) {  // free space: more than a band (4 cm) in front of 0.80 m
    const int i = at(32, iz);
    EXPECT_GT(t_carve[i], 0.f) << "iz " << iz << ": the stale surface is still there after carving";
    // iz 0 (0.68 m) already says free space (tsdf 1): nothing to unlearn, its weight stays.
    if (iz > 0) EXPECT_LT(w_carve[i], 8.f) << "iz " << iz;
  }
  EXPECT_EQ(w_carve[at(32, 0)], vol.max_weight);
  // Without carving the stale crossing at 0.72 m survives: 0.73 and 0.75 m still inside.
  EXPECT_LT(t_keep[at(32, 5)], -0.1f);
  EXPECT_LT(t_keep[at(32, 7)], -0.55f);
  for (int iz = 11; iz <= 14; ++iz) {  // the true surface's band: never carved
    EXPECT_EQ(t_carve[at(32, iz)], t_keep[at(32, iz)]) << "iz " << iz;
    EXPECT_EQ(w_carve[at(32, iz)], vol.max_weight) << "iz " << iz;
  }
  // The rim point: the 5x5 window reaches the sphere, so it is fused as free space at full weight;
  // a 1-pixel window sees only the wall and carves it.
  std::vector<float> t1, w1;
  run(fp, 1, &t1, &w1);
  EXPECT_EQ(w1[rim], vol.max_weight);
  VdFusionParams single = fp;
  single.carve_radius = 0;
  std::vector<float> t0, w0;
  run(single, 1, &t0, &w0);
  EXPECT_EQ(w0[rim], 0.5f * vol.max_weight + 1.f);
  EXPECT_EQ(w1[at(32, 3)], 0.5f * vol.max_weight + 1.f);

  const FusedState dev = FuseActiveOnDevice(ctx, ops, view, {tsdf, weight, color}, pos, list, fp, T);
  EXPECT_TRUE(test::AllClose(dev.tsdf, t1, 1e-6f, 1e-5f));
  EXPECT_TRUE(test::AllClose(dev.weight, w1, 0.f, 0.f));
}

// Brick integration: the device's marking and integration against the CPU reference, then
// against dense integration: identical inside the truncation band, the same mesh, a fraction
// of the grid visited.
TEST(TsdfParityTest, BrickIntegrationMatchesCpuAndDenseInsideTheBand) {
  VD_REQUIRE_OCL(ctx);
  DeviceOps ops(ctx);
  ASSERT_TRUE(ops.Init().ok());
  const SphereView view;
  const auto& [cam, depth, colors, vol, n] = view;
  // Camera turned 3 degrees about y and moved 1 cm: the marking's ray transform is exercised.
  VdPose T = test::IdentityPose();
  const float a = 3.f * float(M_PI) / 180.f;
  T.r0 = VD_F4(std::cos(a), 0.f, std::sin(a), 0.01f);
  T.r2 = VD_F4(-std::sin(a), 0.f, std::cos(a), 0.f);
  std::vector<float> tsdf(n, 1.f), weight(n, 0.f);
  std::vector<uint32_t> color(n, 0u), flags;
  for (int k = 0; k < 2; ++k)
    cpu::IntegrateTsdfBricks(tsdf.data(), weight.data(), color.data(), vol, cam, T, depth.data(), colors.data(), &flags);

  DeviceVolume dv;
  ASSERT_TRUE(ops.AllocVolume(vol, false, &dv).ok());
  auto ddepth = test::ToDevice(ctx, depth);
  auto dcol = test::ToDevice(ctx, colors);
  for (int k = 0; k < 2; ++k) ASSERT_TRUE(ops.IntegrateTsdf(dv, cam, T, ddepth, dcol).ok());
  EXPECT_EQ(test::FromDevice(ctx, ops.brick_flags(), flags.size()), flags);
  EXPECT_TRUE(test::AllClose(test::FromDevice(ctx, dv.tsdf, n), tsdf, 1e-6f, 1e-5f));
  EXPECT_TRUE(test::AllClose(test::FromDevice(ctx, dv.weight, n), weight, 0.f, 0.f));
  EXPECT_EQ(test::FromDevice(ctx, dv.color, n), color);
  size_t marked = 0;
  for (uint32_t f : flags) marked += f;
  EXPECT_EQ(ops.last_integrated_bricks(), marked);
  // The sphere's band is part of the 512 bricks (the test is conservative at 16-pixel depth tiles
  // of this 160x120 camera: measured 244).
  EXPECT_GT(marked, 10u);
  EXPECT_LT(marked, flags.size() / 2);

  // Dense integration of the same frames.
  std::vector<float> dtsdf(n, 1.f), dweight(n, 0.f);
  std::vector<uint32_t> dcolor(n, 0u);
  for (int k = 0; k < 2; ++k)
    cpu::IntegrateTsdf(dtsdf.data(), dweight.data(), dcolor.data(), vol, cam, T, depth.data(), colors.data());
  size_t band = 0, carved_only = 0;
  for (size_t i = 0; i < n; ++i) {
    if (dweight[i] > 0.f && std::fabs(dtsdf[i]) < 1.f) {
      ++band;
      ASSERT_EQ(weight[i], dweight[i]) << i;
      ASSERT_NEAR(tsdf[i], dtsdf[i], 1e-4f) << i;
    } else if (dweight[i] > 0.f && weight[i] == 0.f) {
      ++carved_only;  // free space beyond the band: dense carves it, bricks leave it
      ASSERT_EQ(dtsdf[i], 1.f);
    }
  }
  EXPECT_GT(band, 1000u);
  EXPECT_GT(carved_only, 0u);
  const cpu::McMesh ma = cpu::MarchingCubes(tsdf.data(), weight.data(), color.data(), vol);
  const cpu::McMesh mb = cpu::MarchingCubes(dtsdf.data(), dweight.data(), dcolor.data(), vol);
  EXPECT_GT(ma.triangles.size(), 300u);
  // The same surface: every vertex of the brick mesh is a vertex of the dense mesh (to 1e-3
  // voxels). Dense integration also carves free space beyond the band, which adds a few cells at
  // depth discontinuities (the sphere's silhouette against the background): at most 1 % more.
  std::vector<std::array<float, 3>> dense_vertices;
  for (const vd_float4& p : mb.positions_grid) dense_vertices.push_back({p.x, p.y, p.z});
  std::sort(dense_vertices.begin(), dense_vertices.end());
  size_t missing = 0;
  for (const vd_float4& p : ma.positions_grid) {
    auto it = std::lower_bound(dense_vertices.begin(), dense_vertices.end(), std::array<float, 3>{p.x - 1e-3f, 0.f, 0.f});
    bool found = false;
    for (; it != dense_vertices.end() && (*it)[0] <= p.x + 1e-3f && !found; ++it)
      found = std::fabs((*it)[1] - p.y) < 1e-3f && std::fabs((*it)[2] - p.z) < 1e-3f;
    missing += !found;
  }
  EXPECT_EQ(missing, 0u) << "brick-mesh vertices not on the dense mesh";
  EXPECT_LE(ma.triangles.size(), mb.triangles.size());
  EXPECT_GE(double(ma.triangles.size()), 0.99 * double(mb.triangles.size()));
  std::printf("brick mesh %zu triangles, dense %zu\n", ma.triangles.size() / 3, mb.triangles.size() / 3);
}

}  // namespace
}  // namespace vd
