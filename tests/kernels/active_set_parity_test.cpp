#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "cpu_ref/cpu_ref.h"
#include "ocl/device_ops.h"
#include "ocl/mc_table.h"
#include "sphere_volume.h"
#include "test_scenes.h"

namespace vd {
namespace {

TEST(ActiveSetParityTest, SurfaceCellsPlusOneRingMatchCpu) {
  VD_REQUIRE_OCL(ctx);
  DeviceOps ops(ctx);
  ASSERT_TRUE(ops.Init().ok());
  // A sphere of 9.3 voxels around grid point (20, 18, 16).
  test::AnalyticVolume sphere =
      test::MakeSphereVolume(test::TestVolume(40, 36, 32, 0.01f, VD_F4(0, 0, 0, 1)), 0.2f, 0.18f, 0.16f, 0.093f);
  const VdVolume& vol = sphere.vol;
  const size_t n = sphere.tsdf.size();
  const std::vector<float>& tsdf = sphere.tsdf;
  std::vector<float>& weight = sphere.weight;
  const std::vector<uint32_t>& color = sphere.color;
  // An unobserved slab: no surface there, so no active points either.
  for (size_t i = size_t(vol.dim_x) * vol.dim_y * 23; i < n; ++i) weight[i] = 0.f;
  const cpu::McMesh mesh = cpu::MarchingCubes(tsdf.data(), weight.data(), color.data(), vol);
  cpu::ActiveSet ref_solved;
  const cpu::ActiveSet ref = cpu::BuildActiveSet(mesh.codes.data(), vol, &ref_solved);
  ASSERT_GT(ref.list.size(), 1000u);

  DeviceVolume dv;
  ASSERT_TRUE(ops.AllocVolume(vol, false, &dv).ok());
  ASSERT_TRUE(ctx->Upload(dv.tsdf, tsdf.data(), n).ok());
  ASSERT_TRUE(ctx->Upload(dv.weight, weight.data(), n).ok());
  ASSERT_TRUE(ops.MarkTouched(dv).ok());
  DeviceMesh dm;
  ASSERT_TRUE(ops.MarchingCubes(dv, &dm).ok());
  DeviceActiveSet das, solved;
  Status s = ops.BuildActiveSet(dv, &das, &solved);
  ASSERT_TRUE(s.ok()) << s.ToString();
  ASSERT_EQ(das.count, ref.list.size());
  EXPECT_EQ(test::FromDevice(ctx, das.list, das.count), ref.list);
  EXPECT_EQ(test::FromDevice(ctx, das.compact, n), ref.compact);
  EXPECT_EQ(test::FromDevice(ctx, das.neighbours, 6 * das.count), ref.neighbours);
  // The solver's set, the surface points alone: device against CPU, and exactly the corners of the
  // cells with triangles (checked below); on this sphere the ring is a third of M or more.
  ASSERT_EQ(solved.count, ref_solved.list.size());
  EXPECT_EQ(test::FromDevice(ctx, solved.list, solved.count), ref_solved.list);
  EXPECT_EQ(test::FromDevice(ctx, solved.compact, n), ref_solved.compact);
  EXPECT_EQ(test::FromDevice(ctx, solved.neighbours, 6 * solved.count), ref_solved.neighbours);
  std::printf("M %zu points, of them %zu surface points (the solver's)\n", ref.list.size(), ref_solved.list.size());
  EXPECT_LT(double(ref_solved.list.size()), 0.67 * double(ref.list.size()));

  // A second build into the same set on the same dims (the engine's every frame) writes only the old
  // and the new members of the map: a smaller sphere elsewhere gives the CPU's set and a map that
  // is -1 everywhere else, also where the first sphere's members were.
  const test::AnalyticVolume other =
      test::MakeSphereVolume(test::TestVolume(40, 36, 32, 0.01f, VD_F4(0, 0, 0, 1)), 0.16f, 0.2f, 0.14f, 0.071f);
  const cpu::McMesh other_mesh = cpu::MarchingCubes(other.tsdf.data(), other.weight.data(), other.color.data(), vol);
  const cpu::ActiveSet other_ref = cpu::BuildActiveSet(other_mesh.codes.data(), vol);
  ASSERT_GT(other_ref.list.size(), 500u);
  ASSERT_TRUE(ctx->Upload(dv.tsdf, other.tsdf.data(), n).ok());
  ASSERT_TRUE(ctx->Upload(dv.weight, other.weight.data(), n).ok());
  ASSERT_TRUE(ops.MarkTouched(dv).ok());
  ASSERT_TRUE(ops.MarchingCubes(dv, &dm).ok());
  ASSERT_TRUE(ops.BuildActiveSet(dv, &das).ok());
  EXPECT_EQ(das.kept.dim_x, vol.dim_x);
  ASSERT_EQ(das.count, other_ref.list.size());
  EXPECT_EQ(test::FromDevice(ctx, das.list, das.count), other_ref.list);
  EXPECT_EQ(test::FromDevice(ctx, das.compact, n), other_ref.compact);
  EXPECT_EQ(test::FromDevice(ctx, das.neighbours, 6 * das.count), other_ref.neighbours);

  // Every corner of every triangle-emitting cell is a member, and a surface point; the surface
  // points are those corners and nothing else.
  const McTable& table = GetMcTable();
  std::vector<uint8_t> corner(n, 0);
  for (size_t i = 0; i < n; ++i) {
    if (!(mesh.codes[i] & 0x100) || table.counts[mesh.codes[i] & 255] == 0) continue;
    const int x = int(i % vol.dim_x), y = int(i / vol.dim_x % vol.dim_y), z = int(i / vol.dim_x / vol.dim_y);
    for (int k = 0; k < 8; ++k) {
      const size_t c = (x + (k & 1)) + size_t(vol.dim_x) * ((y + ((k >> 1) & 1)) + size_t(vol.dim_y) * (z + ((k >> 2) & 1)));
      ASSERT_GE(ref.compact[c], 0);
      corner[c] = 1;
    }
  }
  for (size_t i = 0; i < n; ++i) ASSERT_EQ(ref_solved.compact[i] >= 0, corner[i] == 1) << "grid point " << i;
  // Neighbourhoods are symmetric, and nothing lies in the unobserved slab.
  for (size_t k = 0; k < ref.list.size(); ++k) {
    EXPECT_LE(ref.list[k] / (vol.dim_x * vol.dim_y), 23);
    for (int d = 0; d < 6; ++d) {
      const int j = ref.neighbours[6 * k + d];
      if (j < 0) continue;
      EXPECT_EQ(ref.neighbours[6 * j + (d ^ 1)], int(k));
    }
  }
}

}  // namespace
}  // namespace vd
