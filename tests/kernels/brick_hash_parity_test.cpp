// The brick table of the sparse volume (kernels/brick_hash.cl) against its CPU reference: insert
// and lookup under collisions, pool exhaustion, allocation from depth, compaction. The device hands
// out pool slots in whatever order its work items win them, so insert tests compare the key sets
// and check the slots are a permutation; lookup and compaction are compared exactly.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <set>

#include "cpu_ref/brick_hash_ref.h"
#include "ocl/brick_hash_ocl.h"
#include "ocl/device_ops.h"
#include "test_scenes.h"

namespace vd {
namespace {

// The table's (key -> slot) pairs.
std::map<uint32_t, int32_t> Contents(const std::vector<uint32_t>& keys, const std::vector<int32_t>& slots) {
  std::map<uint32_t, int32_t> out;
  for (size_t e = 0; e < keys.size(); ++e)
    if (keys[e] != VD_BRICK_EMPTY) out[keys[e]] = slots[e];
  return out;
}

std::map<uint32_t, int32_t> Contents(ocl::Context* ctx, const ocl::BrickTable& t) {
  return Contents(test::FromDevice(ctx, t.keys(), t.capacity()), test::FromDevice(ctx, t.slots(), t.capacity()));
}

std::set<uint32_t> KeySet(const std::map<uint32_t, int32_t>& m) {
  std::set<uint32_t> out;
  for (const auto& [k, s] : m) out.insert(k);
  return out;
}

// n distinct keys of bricks in a 12^3 block around the origin, inserted twice each in shuffled order.
std::vector<uint32_t> Keys(int n, uint32_t seed, std::vector<uint32_t>* distinct) {
  std::mt19937 rng(seed);
  std::set<uint32_t> seen;
  while (int(seen.size()) < n) {
    std::uniform_int_distribution<int> c(-6, 5);
    seen.insert(vd_brick_pack(c(rng), c(rng), c(rng)));
  }
  distinct->assign(seen.begin(), seen.end());
  std::vector<uint32_t> out = *distinct;
  out.insert(out.end(), distinct->begin(), distinct->end());
  std::shuffle(out.begin(), out.end(), rng);
  return out;
}

TEST(BrickHashTest, KeysPackAndUnpackOverTheWholeRange) {
  for (int b : {VD_BRICK_COORD_MIN, -1, 0, 1, VD_BRICK_COORD_MAX}) {
    const uint32_t k = vd_brick_pack(b, -b - 1, b / 2);
    EXPECT_NE(k, VD_BRICK_EMPTY);
    int x, y, z;
    vd_brick_unpack(k, &x, &y, &z);
    EXPECT_EQ(x, b);
    EXPECT_EQ(y, -b - 1);
    EXPECT_EQ(z, b / 2);
  }
  EXPECT_FALSE(vd_brick_coords_valid(VD_BRICK_COORD_MAX + 1, 0, 0));
  EXPECT_FALSE(vd_brick_coords_valid(0, VD_BRICK_COORD_MIN - 1, 0));
}

TEST(BrickHashParityTest, InsertAndLookupMatchTheCpuUnderCollisions) {
  VD_REQUIRE_OCL(ctx);
  // 400 keys into a 1024-entry table (pool 512): runs of several probes happen.
  std::vector<uint32_t> distinct;
  const std::vector<uint32_t> in = Keys(400, 1, &distinct);
  auto table = ocl::BrickTable::Create(*ctx, 512);
  ASSERT_TRUE(table.ok()) << table.status().ToString();
  ASSERT_EQ(table->capacity(), 1024u);
  ocl::Buffer<uint32_t> din = test::ToDevice(ctx, in);
  ASSERT_TRUE(table->Insert(*ctx, din, in.size()).ok());
  cpu::BrickTable ref(1024, 512);
  cpu::BrickInsertKeys(in.data(), in.size(), &ref);

  const std::map<uint32_t, int32_t> dev = Contents(ctx, *table);
  EXPECT_EQ(KeySet(dev), KeySet(Contents(ref.keys, ref.slots)));
  EXPECT_EQ(KeySet(dev), std::set<uint32_t>(distinct.begin(), distinct.end()));
  std::set<int32_t> slots;
  for (const auto& [k, s] : dev) slots.insert(s);
  ASSERT_EQ(slots.size(), distinct.size()) << "each brick has its own slot";
  EXPECT_EQ(*slots.begin(), 0);
  EXPECT_EQ(*slots.rbegin(), int32_t(distinct.size()) - 1);
  auto counts = table->Counts(*ctx);
  ASSERT_TRUE(counts.ok());
  EXPECT_EQ(counts->used, 400u);
  EXPECT_EQ(counts->failed, 0u);
  EXPECT_EQ(ref.counters[VD_BRICK_COUNT_TAKEN], 400u);
  // Some keys sit away from their home entry (the probing is exercised).
  const std::vector<uint32_t> keys = test::FromDevice(ctx, table->keys(), table->capacity());
  int displaced = 0;
  for (uint32_t e = 0; e < keys.size(); ++e)
    if (keys[e] != VD_BRICK_EMPTY && vd_brick_home(keys[e], 1024) != e) ++displaced;
  EXPECT_GT(displaced, 20);

  // Lookups of every key and of 50 that are not there: device == CPU on the device's table.
  std::vector<uint32_t> query = distinct;
  for (int i = 0; i < 50; ++i) query.push_back(vd_brick_pack(100 + i, -200, 7));
  ocl::Buffer<uint32_t> dq = test::ToDevice(ctx, query);
  auto out = ctx->Alloc<int32_t>(query.size());
  ASSERT_TRUE(out.ok());
  ASSERT_TRUE(table->Lookup(*ctx, dq, query.size(), *out).ok());
  const std::vector<int32_t> got = test::FromDevice(ctx, *out, query.size());
  cpu::BrickTable copy(1024, 512);
  copy.keys = keys;
  copy.slots = test::FromDevice(ctx, table->slots(), table->capacity());
  std::vector<int32_t> want(query.size());
  cpu::BrickLookup(query.data(), query.size(), copy, want.data());
  EXPECT_EQ(got, want);
  for (size_t i = 0; i < query.size(); ++i) EXPECT_EQ(got[i], i < distinct.size() ? dev.at(query[i]) : -1) << i;
}

TEST(BrickHashParityTest, APoolUsedUpCountsTheBricksLeftOut) {
  VD_REQUIRE_OCL(ctx);
  std::vector<uint32_t> distinct;
  const std::vector<uint32_t> in = Keys(300, 2, &distinct);
  auto table = ocl::BrickTable::Create(*ctx, 200);
  ASSERT_TRUE(table.ok());
  ocl::Buffer<uint32_t> din = test::ToDevice(ctx, in);
  ASSERT_TRUE(table->Insert(*ctx, din, in.size()).ok());
  auto counts = table->Counts(*ctx);
  ASSERT_TRUE(counts.ok());
  EXPECT_EQ(counts->used, 200u);
  EXPECT_EQ(counts->failed, 100u);
  cpu::BrickTable ref(table->capacity(), 200);
  cpu::BrickInsertKeys(in.data(), in.size(), &ref);
  EXPECT_EQ(ref.counters[VD_BRICK_COUNT_FAILED], 100u);
  // 300 keys in the table, 200 with the slots 0..199, 100 without one.
  const std::map<uint32_t, int32_t> dev = Contents(ctx, *table);
  EXPECT_EQ(dev.size(), 300u);
  std::set<int32_t> slots;
  int none = 0;
  for (const auto& [k, s] : dev) (s < 0 ? ++none : (slots.insert(s), 0));
  EXPECT_EQ(none, 100);
  EXPECT_EQ(slots.size(), 200u);
  EXPECT_EQ(*slots.rbegin(), 199);
}

TEST(BrickHashParityTest, AllocationFromDepthCoversTheTruncationBand) {
  VD_REQUIRE_OCL(ctx);
  const VdCamera cam = test::TestCamera(160, 120);
  const std::vector<float> depth = test::SphereDepth(cam, 0.8f, 0.2f, 1.2f);
  // A camera turned and moved, so bricks are not aligned with the image.
  const float c = std::cos(0.3f), s = std::sin(0.3f);
  VdPose pose{};
  pose.r0 = VD_F4(c, 0.f, s, 0.05f);
  pose.r1 = VD_F4(0.f, 1.f, 0.f, -0.1f);
  pose.r2 = VD_F4(-s, 0.f, c, 0.2f);
  const float trunc = 0.016f, brick = 0.032f;
  auto table = ocl::BrickTable::Create(*ctx, 1 << 14);
  ASSERT_TRUE(table.ok());
  ocl::Buffer<float> dd = test::ToDevice(ctx, depth);
  ASSERT_TRUE(table->AllocateFromDepth(*ctx, dd, cam, pose, trunc, brick).ok());
  cpu::BrickTable ref(table->capacity(), table->pool());
  cpu::BrickAllocDepth(depth.data(), cam, pose, trunc, brick, &ref);
  const std::map<uint32_t, int32_t> dev = Contents(ctx, *table);
  const std::set<uint32_t> keys = KeySet(dev);
  EXPECT_EQ(keys, KeySet(Contents(ref.keys, ref.slots)));
  EXPECT_GT(keys.size(), 100u);
  auto counts = table->Counts(*ctx);
  ASSERT_TRUE(counts.ok());
  EXPECT_EQ(counts->used, keys.size());
  EXPECT_EQ(counts->failed, 0u);
  // Every point of every seventh pixel's band (sampled at a sixteenth of a brick) is in an
  // allocated brick.
  for (int i = 0; i < cam.width * cam.height; i += 7) {
    if (!(depth[i] > 0.f)) continue;
    const float rx = (float(i % cam.width) - cam.cx) / cam.fx, ry = (float(i / cam.width) - cam.cy) / cam.fy;
    for (float z = depth[i] - trunc; z <= depth[i] + trunc; z += brick / 16) {
      const vd_float4 p = vd_pose_apply(pose, VD_F4(rx * z, ry * z, z, 1.f));
      // Points within rounding of a brick face may fall either side.
      const float f[3] = {p.x / brick, p.y / brick, p.z / brick};
      if (std::any_of(f, f + 3, [](float v) { return std::fabs(v - std::round(v)) < 1e-4f; })) continue;
      int bx, by, bz;
      vd_brick_of(p, brick, &bx, &by, &bz);
      ASSERT_TRUE(keys.count(vd_brick_pack(bx, by, bz))) << "pixel " << i << " depth " << z;
    }
  }
}

TEST(BrickHashParityTest, CompactionKeepsTheChosenBricksInSlotOrder) {
  VD_REQUIRE_OCL(ctx);
  DeviceOps ops(ctx);
  ASSERT_TRUE(ops.Init().ok());
  std::vector<uint32_t> distinct;
  const std::vector<uint32_t> in = Keys(300, 3, &distinct);
  auto table = ocl::BrickTable::Create(*ctx, 400);
  ASSERT_TRUE(table.ok());
  ocl::Buffer<uint32_t> din = test::ToDevice(ctx, in);
  ASSERT_TRUE(table->Insert(*ctx, din, in.size()).ok());
  const std::map<uint32_t, int32_t> before = Contents(ctx, *table);
  cpu::BrickTable old(table->capacity(), table->pool());
  old.keys = test::FromDevice(ctx, table->keys(), table->capacity());
  old.slots = test::FromDevice(ctx, table->slots(), table->capacity());
  auto used = table->Counts(*ctx);
  ASSERT_TRUE(used.ok());
  ASSERT_EQ(used->used, 300u);
  old.counters[VD_BRICK_COUNT_TAKEN] = used->used;
  // Keep every third slot (flags past the 300 slots in use mean nothing).
  std::vector<uint32_t> keep(400, 0u);
  for (int sl = 0; sl < 400; sl += 3) keep[sl] = 1u;
  ocl::Buffer<uint32_t> dkeep = test::ToDevice(ctx, keep);
  ASSERT_TRUE(table->Compact(ops, dkeep).ok());
  const cpu::BrickTable ref = cpu::BrickCompact(old, keep.data());
  const std::map<uint32_t, int32_t> after = Contents(ctx, *table);
  EXPECT_EQ(after, Contents(ref.keys, ref.slots));
  // The kept bricks are those of the kept slots, renumbered in slot order; the others are gone.
  ASSERT_EQ(after.size(), 100u);
  for (const auto& [k, s] : before) {
    if (s % 3 == 0) {
      ASSERT_TRUE(after.count(k));
      EXPECT_EQ(after.at(k), s / 3);
    } else {
      EXPECT_FALSE(after.count(k));
    }
  }
  // Inserting after compaction continues behind the kept bricks.
  auto counts = table->Counts(*ctx);
  ASSERT_TRUE(counts.ok());
  EXPECT_EQ(counts->used, 100u);
  const std::vector<uint32_t> more = {vd_brick_pack(300, 300, 300)};
  ocl::Buffer<uint32_t> dmore = test::ToDevice(ctx, more);
  ASSERT_TRUE(table->Insert(*ctx, dmore, 1).ok());
  EXPECT_EQ(Contents(ctx, *table).at(more[0]), 100);
}

TEST(BrickHashParityTest, BadArgumentsAreRefused) {
  VD_REQUIRE_OCL(ctx);
  EXPECT_FALSE(ocl::BrickTable::Create(*ctx, 0).ok());
  auto table = ocl::BrickTable::Create(*ctx, 16);
  ASSERT_TRUE(table.ok());
  const VdCamera cam = test::TestCamera(160, 120);
  auto small = ctx->Alloc<float>(100);
  ASSERT_TRUE(small.ok());
  EXPECT_FALSE(table->AllocateFromDepth(*ctx, *small, cam, test::IdentityPose(), 0.01f, 0.032f).ok());
  std::vector<float> far(size_t(cam.width) * cam.height, 100.f);
  ocl::Buffer<float> dfar = test::ToDevice(ctx, far);
  // 100 m away: outside the +-16 m the keys can name; counted, never wrapped into another brick.
  ASSERT_TRUE(table->AllocateFromDepth(*ctx, dfar, cam, test::IdentityPose(), 0.01f, 0.032f).ok());
  auto counts = table->Counts(*ctx);
  ASSERT_TRUE(counts.ok());
  EXPECT_EQ(counts->used, 0u);
  EXPECT_GT(counts->failed, 0u);
}

}  // namespace
}  // namespace vd
