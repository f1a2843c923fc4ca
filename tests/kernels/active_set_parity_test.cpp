#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "core/device_ops.h"
#include "core/mc_table.h"
#include "cpu_ref/cpu_ref.h"
#include "test_scenes.h"

namespace vd {
namespace {

TEST(ActiveSetParityTest, SurfaceCellsPlusOneRingMatchCpu) {
  VD_REQUIRE_OCL(ctx);
  DeviceOps ops(ctx);
  ASSERT_TRUE(ops.Init().ok());
  VdVolume vol{};
  vol.dim_x = 40;
  vol.dim_y = 36;
  vol.dim_z = 32;
  vol.voxel_size = 0.01f;
  vol.origin = VD_F4(0, 0, 0, 1);
  vol.truncation = 0.04f;
  vol.max_weight = 64;
  const size_t n = size_t(vol.dim_x) * vol.dim_y * vol.dim_z;
  std::vector<float> tsdf(n), weight(n, 1.f);
  std::vector<uint32_t> color(n, 0u);
  for (int z = 0; z < vol.dim_z; ++z)
    for (int y = 0; y < vol.dim_y; ++y)
      for (int x = 0; x < vol.dim_x; ++x) {
        const size_t i = x + size_t(vol.dim_x) * (y + size_t(vol.dim_y) * z);
        const float d = std::sqrt(float((x - 20) * (x - 20) + (y - 18) * (y - 18) + (z - 16) * (z - 16))) - 9.3f;
        tsdf[i] = std::clamp(d / 4.f, -1.f, 1.f);
        // An unobserved slab: no surface there, so no active points either.
        if (z > 22) weight[i] = 0.f;
      }
  const cpu::McMesh mesh = cpu::MarchingCubes(tsdf.data(), weight.data(), color.data(), vol);
  const cpu::ActiveSet ref = cpu::BuildActiveSet(mesh.codes.data(), vol);
  ASSERT_GT(ref.list.size(), 1000u);

  DeviceVolume dv;
  ASSERT_TRUE(ops.AllocVolume(vol, false, &dv).ok());
  ASSERT_TRUE(ctx->Upload(dv.tsdf, tsdf.data(), n).ok());
  ASSERT_TRUE(ctx->Upload(dv.weight, weight.data(), n).ok());
  DeviceMesh dm;
  ASSERT_TRUE(ops.MarchingCubes(dv, &dm).ok());
  DeviceActiveSet das;
  Status s = ops.BuildActiveSet(dv, &das);
  ASSERT_TRUE(s.ok()) << s.ToString();
  ASSERT_EQ(das.count, ref.list.size());
  EXPECT_EQ(test::FromDevice(ctx, das.list, das.count), ref.list);
  EXPECT_EQ(test::FromDevice(ctx, das.compact, n), ref.compact);
  EXPECT_EQ(test::FromDevice(ctx, das.neighbours, 6 * das.count), ref.neighbours);

  // Every corner of every triangle-emitting cell is a member.
  const McTable& table = GetMcTable();
  for (size_t i = 0; i < n; ++i) {
    if (!(mesh.codes[i] & 0x100) || table.counts[mesh.codes[i] & 255] == 0) continue;
    const int x = int(i % vol.dim_x), y = int(i / vol.dim_x % vol.dim_y), z = int(i / vol.dim_x / vol.dim_y);
    for (int k = 0; k < 8; ++k) {
      const size_t c = (x + (k & 1)) + size_t(vol.dim_x) * ((y + ((k >> 1) & 1)) + size_t(vol.dim_y) * (z + ((k >> 2) & 1)));
      ASSERT_GE(ref.compact[c], 0);
    }
  }
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
