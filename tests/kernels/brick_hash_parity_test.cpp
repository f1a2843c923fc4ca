// The brick table of the sparse volume (kernels/brick_hash.cl) against its CPU reference: insert
// and lookup under collisions, pool exhaustion, allocation from depth, compaction. The device hands
// out pool slots in whatever order its work items win them, so insert tests compare the key sets
// and check the slots are a permutation; lookup and compaction are compared exactly.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <random>
#include <set>

#include "brick_scene.h"
#include "cpu_ref/brick_hash_ref.h"
#include "cpu_ref/cpu_ref.h"
#include "ocl/brick_hash_ocl.h"
#include "ocl/device_ops.h"
#include "shared/deformation.h"
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

// A camera turned and moved, so bricks are not aligned with the image.
VdPose TurnedPose() {
  const float c = std::cos(0.3f), s = std::sin(0.3f);
  VdPose pose{};
  pose.r0 = VD_F4(c, 0.f, s, 0.05f);
  pose.r1 = VD_F4(0.f, 1.f, 0.f, -0.1f);
  pose.r2 = VD_F4(-s, 0.f, c, 0.2f);
  return pose;
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
  // The batch's slots go in key order whatever order the atomics took: the same slots as the CPU's.
  EXPECT_EQ(dev, Contents(ref.keys, ref.slots));
  EXPECT_EQ(KeySet(dev), std::set<uint32_t>(distinct.begin(), distinct.end()));
  std::set<int32_t> slots;
  for (const auto& [k, s] : dev) slots.insert(s);
  ASSERT_EQ(slots.size(), distinct.size()) << "each brick has its own slot";
  EXPECT_EQ(*slots.begin(), 0);
  EXPECT_EQ(*slots.rbegin(), int32_t(distinct.size()) - 1);
  // Each slot records its brick.
  const std::vector<uint32_t> slot_keys = test::FromDevice(ctx, table->slot_keys(), table->pool());
  for (const auto& [k, s] : dev) EXPECT_EQ(slot_keys[s], k);
  EXPECT_TRUE(std::is_sorted(slot_keys.begin(), slot_keys.begin() + distinct.size()));
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

// A table restored from its slots' keys (as a checkpoint stores them) gives every key its slot
// back; a repeated or invalid key is refused.
TEST(BrickHashParityTest, RestoreGivesEachKeyItsSlotBack) {
  VD_REQUIRE_OCL(ctx);
  std::vector<uint32_t> distinct;
  Keys(500, 7, &distinct);
  std::mt19937 rng(11);
  std::shuffle(distinct.begin(), distinct.end(), rng);
  auto table = ocl::BrickTable::Create(*ctx, 600);
  ASSERT_TRUE(table.ok());
  ocl::Buffer<uint32_t> din = test::ToDevice(ctx, distinct);
  ASSERT_TRUE(table->Restore(*ctx, din, distinct.size()).ok());
  cpu::BrickTable ref(table->capacity(), table->pool());
  cpu::BrickRestore(distinct.data(), distinct.size(), &ref);
  const std::map<uint32_t, int32_t> dev = Contents(ctx, *table);
  EXPECT_EQ(dev, Contents(ref.keys, ref.slots));
  ASSERT_EQ(dev.size(), distinct.size());
  for (size_t s = 0; s < distinct.size(); ++s) EXPECT_EQ(dev.at(distinct[s]), int32_t(s));
  std::vector<uint32_t> slot_keys = test::FromDevice(ctx, table->slot_keys(), distinct.size());
  EXPECT_EQ(slot_keys, distinct);
  auto counts = table->Counts(*ctx);
  ASSERT_TRUE(counts.ok());
  EXPECT_EQ(counts->used, distinct.size());
  EXPECT_EQ(counts->failed, 0u);
  // Inserting afterwards continues behind the restored slots.
  const std::vector<uint32_t> more = {vd_brick_pack(300, 300, 300)};
  ocl::Buffer<uint32_t> dmore = test::ToDevice(ctx, more);
  ASSERT_TRUE(table->Insert(*ctx, dmore, 1).ok());
  EXPECT_EQ(Contents(ctx, *table).at(more[0]), 500);

  // A repeated key, and a word that is no brick key: refused, the table left empty.
  std::vector<uint32_t> bad = {distinct[0], distinct[1], distinct[0]};
  ocl::Buffer<uint32_t> dbad = test::ToDevice(ctx, bad);
  const Status repeated = table->Restore(*ctx, dbad, bad.size());
  EXPECT_EQ(repeated.code(), StatusCode::kDataLoss) << repeated.ToString();
  EXPECT_TRUE(Contents(ctx, *table).empty());
  bad = {distinct[0], 0xC0000001u};
  dbad = test::ToDevice(ctx, bad);
  EXPECT_EQ(table->Restore(*ctx, dbad, bad.size()).code(), StatusCode::kDataLoss);
  cpu::BrickTable ref_bad(table->capacity(), table->pool());
  cpu::BrickRestore(bad.data(), bad.size(), &ref_bad);
  EXPECT_EQ(ref_bad.counters[VD_BRICK_COUNT_FAILED], 1u);
  std::vector<uint32_t> many(601, 0u);
  ocl::Buffer<uint32_t> dmany = test::ToDevice(ctx, many);
  EXPECT_EQ(table->Restore(*ctx, dmany, many.size()).code(), StatusCode::kOutOfRange);
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
  const VdPose pose = TurnedPose();
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

// Allocation and listing in one walk: the same bricks as the two passes, each listed once, on the
// device and the CPU; a second frame lists without allocating; a pool too small lists the bricks
// it could not hold as -1.
TEST(BrickHashParityTest, AllocationAndListingInOnePassMatchTheTwoPasses) {
  VD_REQUIRE_OCL(ctx);
  const VdCamera cam = test::TestCamera(160, 120);
  const std::vector<float> depth = test::SphereDepth(cam, 0.8f, 0.2f, 1.2f);
  const VdPose pose = TurnedPose();
  const float trunc = 0.016f, brick = 0.032f;
  ocl::Buffer<float> dd = test::ToDevice(ctx, depth);
  auto two = ocl::BrickTable::Create(*ctx, 1 << 14);
  auto one = ocl::BrickTable::Create(*ctx, 1 << 14);
  ASSERT_TRUE(two.ok() && one.ok());
  ASSERT_TRUE(two->AllocateFromDepth(*ctx, dd, cam, pose, trunc, brick).ok());
  ASSERT_TRUE(one->AllocateAndList(*ctx, dd, cam, pose, trunc, brick).ok());
  const std::set<uint32_t> keys = KeySet(Contents(ctx, *two));
  EXPECT_EQ(KeySet(Contents(ctx, *one)), keys);
  auto listed_keys = [&](const ocl::BrickTable& t) {
    auto counts = t.Counts(*ctx);
    EXPECT_TRUE(counts.ok());
    const std::vector<int32_t> listed = test::FromDevice(ctx, t.visible(), counts->visible);
    const std::vector<uint32_t> slot_keys = test::FromDevice(ctx, t.slot_keys(), t.pool());
    std::multiset<uint32_t> out;
    for (int32_t sl : listed) out.insert(sl < 0 ? VD_BRICK_EMPTY : slot_keys[sl]);
    return out;
  };
  const std::multiset<uint32_t> all(keys.begin(), keys.end());
  EXPECT_EQ(listed_keys(*one), all);
  // The CPU: the same keys, the same listing.
  cpu::BrickTable ref(one->capacity(), one->pool());
  const std::vector<int32_t> ref_listed = cpu::BrickAllocList(depth.data(), cam, pose, trunc, brick, &ref);
  EXPECT_EQ(KeySet(Contents(ref.keys, ref.slots)), keys);
  std::multiset<uint32_t> ref_keys;
  for (int32_t sl : ref_listed) ref_keys.insert(ref.slot_keys[sl]);
  EXPECT_EQ(ref_keys, all);
  // The next frame: nothing new to allocate, every brick listed once again, stamped with it.
  ASSERT_TRUE(one->AllocateAndList(*ctx, dd, cam, pose, trunc, brick).ok());
  EXPECT_EQ(listed_keys(*one), all);
  auto counts = one->Counts(*ctx);
  ASSERT_TRUE(counts.ok());
  EXPECT_EQ(counts->used, keys.size());
  const std::vector<uint32_t> stamps = test::FromDevice(ctx, one->stamps(), counts->used);
  EXPECT_TRUE(std::all_of(stamps.begin(), stamps.end(), [&](uint32_t st) { return st == one->frame(); }));
  // A pool of 3000 bricks (a table with room for every key): 3000 listed with their slots, the
  // others as -1, each counted once as a failure.
  auto small = ocl::BrickTable::Create(*ctx, 3000);
  ASSERT_TRUE(small.ok());
  ASSERT_TRUE(small->AllocateAndList(*ctx, dd, cam, pose, trunc, brick).ok());
  const std::multiset<uint32_t> partial = listed_keys(*small);
  EXPECT_EQ(partial.size(), keys.size());
  EXPECT_EQ(partial.count(VD_BRICK_EMPTY), keys.size() - 3000);
  auto small_counts = small->Counts(*ctx);
  ASSERT_TRUE(small_counts.ok());
  EXPECT_EQ(small_counts->failed, keys.size() - 3000);
  EXPECT_EQ(small_counts->unfused, keys.size() - 3000);
  // The next frame fails no insert (the keys are in the table) but still says what it cannot fuse.
  ASSERT_TRUE(small->AllocateAndList(*ctx, dd, cam, pose, trunc, brick).ok());
  small_counts = small->Counts(*ctx);
  ASSERT_TRUE(small_counts.ok());
  EXPECT_EQ(small_counts->failed, keys.size() - 3000);
  EXPECT_EQ(small_counts->unfused, keys.size() - 3000);
  cpu::BrickTable ref_small(small->capacity(), small->pool());
  cpu::BrickAllocList(depth.data(), cam, pose, trunc, brick, &ref_small);
  EXPECT_EQ(ref_small.counters[VD_BRICK_COUNT_UNFUSED], keys.size() - 3000);
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
  EXPECT_EQ(test::FromDevice(ctx, table->slot_keys(), table->pool()), ref.slot_keys);
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

// Rigid fusion into the pool: device == CPU reference, and the same values as the dense grid's
// fusion at the same voxels, with every observed near-surface voxel of the dense grid in a brick.
TEST(BrickHashParityTest, FusionIntoThePoolMatchesTheCpuAndTheDenseGrid) {
  VD_REQUIRE_OCL(ctx);
  test::FusedBricks f;
  test::FuseSphere(ctx, 2, &f);
  if (HasFatalFailure()) return;
  const ocl::BrickCounts& counts = f.counts;
  const size_t n = size_t(counts.used) * VD_BRICK_VOXELS;
  ASSERT_GT(counts.used, 100u);
  // The frame lists every brick it allocated, each once (the second frame's list too).
  EXPECT_EQ(counts.visible, counts.used);
  std::vector<int32_t> listed = test::FromDevice(ctx, f.table->visible(), counts.visible);
  std::sort(listed.begin(), listed.end());
  const std::vector<float> tsdf = test::FromDevice(ctx, f.pool->tsdf, n),
                           weight = test::FromDevice(ctx, f.pool->weight, n);
  const std::vector<uint32_t> color = test::FromDevice(ctx, f.pool->color, n);

  const cpu::BrickTable ref = f.Reference(ctx);
  std::vector<int32_t> ref_listed =
      cpu::BrickListVisible(f.depth.data(), f.cam, f.cam_to_world, f.vol.truncation, f.brick, ref);
  std::sort(ref_listed.begin(), ref_listed.end());
  EXPECT_EQ(listed, ref_listed);
  std::vector<float> rt(n, 1.f), rw(n, 0.f);
  std::vector<uint32_t> rc(n, 0u);
  for (int frame = 0; frame < 2; ++frame)
    cpu::SparseIntegrate(ref, ref_listed, rt.data(), rw.data(), rc.data(), f.vol, f.cam, f.world_to_cam, f.depth.data(),
                         f.rgba.data());
  EXPECT_EQ(weight, rw);
  EXPECT_TRUE(test::AllClose(tsdf, rt, 1e-6f, 0.f));
  EXPECT_EQ(color, rc);
  size_t fused = 0;
  for (float w : weight) fused += w > 0.f;
  EXPECT_GT(fused, n / 8);

  // The dense grid over the bricks' bounding box, on the same global voxel lattice.
  std::map<std::array<int, 3>, size_t> pool_index;
  for (size_t i = 0; i < n; ++i) {
    int g[3];
    vd_brick_voxel(ref.slot_keys[i / VD_BRICK_VOXELS], int(i % VD_BRICK_VOXELS), &g[0], &g[1], &g[2]);
    pool_index[{g[0], g[1], g[2]}] = i;
  }
  std::vector<float> dt, dw;
  std::vector<uint32_t> dcol;
  int lo[3];
  const VdVolume dense = f.DenseOver(ref, 0, &dt, &dw, &dcol, lo);
  size_t near = 0, outside = 0, differ = 0;
  for (int z = 0; z < dense.dim_z; ++z)
    for (int y = 0; y < dense.dim_y; ++y)
      for (int x = 0; x < dense.dim_x; ++x) {
        const size_t d = x + size_t(dense.dim_x) * (y + size_t(dense.dim_y) * z);
        const auto it = pool_index.find({lo[0] + x, lo[1] + y, lo[2] + z});
        if (dw[d] > 0.f && std::fabs(dt[d]) < 1.f) {
          ++near;
          if (it == pool_index.end()) ++outside;
        }
        if (it == pool_index.end()) continue;
        // The two place a voxel by different float sums (origin + k * size against k * size): a
        // voxel whose centre projects within rounding of a pixel boundary may take the other pixel.
        if (dw[d] != weight[it->second] || std::fabs(dt[d] - tsdf[it->second]) > 1e-4f) ++differ;
      }
  EXPECT_GT(near, 100000u);
  EXPECT_EQ(outside, 0u) << "an observed near-surface voxel outside every allocated brick";
  EXPECT_LE(differ, n / 10000) << differ << " of " << n;  // measured: 0 of 493568
}

// The laned fusion (VD_LANES voxels per work item) against the CPU reference at every lane count a
// device may be built with: one lane (a GPU), 4, 8 and 16.
TEST(BrickHashParityTest, FusionMatchesTheCpuAtEveryLaneCount) {
  VD_REQUIRE_OCL(ctx);
  for (const char* lanes : {"1", "4", "8", "16"}) {
    auto other = test::ContextWithLanes(*ctx, lanes);
    ASSERT_TRUE(other.ok()) << other.status().ToString();
    ocl::Context* lctx = other->get();
    test::FusedBricks f;
    test::FuseSphere(lctx, 2, &f);
    if (HasFatalFailure()) return;
    const size_t n = size_t(f.counts.used) * VD_BRICK_VOXELS;
    const cpu::BrickTable ref = f.Reference(lctx);
    std::vector<int32_t> listed = test::FromDevice(lctx, f.table->visible(), f.counts.visible);
    std::vector<float> rt(n, 1.f), rw(n, 0.f);
    std::vector<uint32_t> rc(n, 0u);
    for (int frame = 0; frame < 2; ++frame)
      cpu::SparseIntegrate(ref, listed, rt.data(), rw.data(), rc.data(), f.vol, f.cam, f.world_to_cam, f.depth.data(),
                           f.rgba.data());
    EXPECT_EQ(test::FromDevice(lctx, f.pool->weight, n), rw) << lanes << " lanes";
    EXPECT_TRUE(test::AllClose(test::FromDevice(lctx, f.pool->tsdf, n), rt, 1e-6f, 0.f)) << lanes << " lanes";
    EXPECT_EQ(test::FromDevice(lctx, f.pool->color, n), rc) << lanes << " lanes";
  }
}

// Eviction: the bricks the last listing did not reach go first, oldest listing first; the pool's
// voxels move with the table (against the CPU reference of the move), and the freed slots are at
// rest again.
TEST(BrickHashParityTest, EvictionDropsTheBricksListedLongestAgoAndMovesThePool) {
  VD_REQUIRE_OCL(ctx);
  DeviceOps ops(ctx);
  ASSERT_TRUE(ops.Init().ok());
  test::FusedBricks f;
  test::FuseSphere(ctx, 1, &f);
  if (HasFatalFailure()) return;
  const uint32_t used = f.counts.used;
  const size_t n = size_t(used) * VD_BRICK_VOXELS;
  // Every brick was listed by the last frame: nothing may go.
  auto none = f.table->EvictOldest(ops, *f.pool, 10);
  ASSERT_TRUE(none.ok());
  EXPECT_EQ(*none, 0u);
  // A second listing of the left half of the image only: the bricks only the right half reaches
  // are now the oldest.
  std::vector<float> left = f.depth;
  for (int i = 0; i < f.cam.width * f.cam.height; ++i)
    if (i % f.cam.width >= f.cam.width / 2) left[i] = 0.f;
  ocl::Buffer<float> dleft = test::ToDevice(ctx, left);
  ASSERT_TRUE(f.table->ListVisible(*ctx, dleft, f.cam, f.cam_to_world, f.vol.truncation, f.brick).ok());
  auto listed = f.table->Counts(*ctx);
  ASSERT_TRUE(listed.ok());
  std::vector<int32_t> seen = test::FromDevice(ctx, f.table->visible(), listed->visible);
  ASSERT_LT(listed->visible, used - 50);
  const cpu::BrickTable before = f.Reference(ctx);
  std::set<uint32_t> seen_keys;
  for (int32_t s : seen) seen_keys.insert(before.slot_keys[s]);
  const std::vector<float> tsdf = test::FromDevice(ctx, f.pool->tsdf, n),
                           weight = test::FromDevice(ctx, f.pool->weight, n);
  const std::vector<uint32_t> color = test::FromDevice(ctx, f.pool->color, n);
  std::vector<uint32_t> stamps = test::FromDevice(ctx, f.table->stamps(), used);

  auto dropped = f.table->EvictOldest(ops, *f.pool, 40);
  ASSERT_TRUE(dropped.ok()) << dropped.status().ToString();
  ASSERT_EQ(*dropped, 40u);
  auto after = f.table->Counts(*ctx);
  ASSERT_TRUE(after.ok());
  EXPECT_EQ(after->used, used - 40);
  const std::map<uint32_t, int32_t> kept = Contents(ctx, *f.table);
  ASSERT_EQ(kept.size(), used - 40);
  // The 40 dropped are the first 40 unseen slots in slot order (all unseen ones share one stamp).
  std::vector<uint32_t> keep(f.table->pool(), 0u);
  std::fill(keep.begin(), keep.begin() + used, 1u);
  int chosen = 0;
  for (uint32_t s = 0; s < used && chosen < 40; ++s)
    if (!seen_keys.count(before.slot_keys[s])) keep[s] = 0u, ++chosen;
  for (uint32_t s = 0; s < used; ++s) EXPECT_EQ(kept.count(before.slot_keys[s]) == 1, keep[s] == 1u) << s;
  for (uint32_t k : seen_keys) EXPECT_TRUE(kept.count(k)) << "a brick the last frame listed was dropped";
  // Table against the CPU's compaction (stamps moved too), pool against the CPU's move.
  cpu::BrickTable ref_before = before;
  ref_before.stamp = stamps;
  ref_before.stamp.resize(f.table->pool(), 0u);
  const cpu::BrickTable ref = cpu::BrickCompact(ref_before, keep.data());
  EXPECT_EQ(kept, Contents(ref.keys, ref.slots));
  EXPECT_EQ(test::FromDevice(ctx, f.table->stamps(), f.table->pool()), ref.stamp);
  std::vector<float> rt = tsdf, rw = weight;
  std::vector<uint32_t> rc = color;
  cpu::BrickPoolMove(keep.data(), used, rt.data(), rw.data(), rc.data());
  const size_t n_kept = size_t(used - 40) * VD_BRICK_VOXELS;
  const std::vector<float> t_after = test::FromDevice(ctx, f.pool->tsdf, n),
                           w_after = test::FromDevice(ctx, f.pool->weight, n);
  EXPECT_TRUE(std::equal(t_after.begin(), t_after.begin() + n_kept, rt.begin()));
  EXPECT_TRUE(std::equal(w_after.begin(), w_after.begin() + n_kept, rw.begin()));
  EXPECT_EQ(test::FromDevice(ctx, f.pool->color, n_kept), std::vector<uint32_t>(rc.begin(), rc.begin() + n_kept));
  // Each kept brick's voxels are the ones it had, now at its new slot; the freed slots are at rest.
  for (const auto& [k, s] : kept) {
    const uint32_t old =
        uint32_t(std::find(before.slot_keys.begin(), before.slot_keys.end(), k) - before.slot_keys.begin());
    ASSERT_TRUE(std::equal(t_after.begin() + size_t(s) * VD_BRICK_VOXELS,
                           t_after.begin() + size_t(s + 1) * VD_BRICK_VOXELS,
                           tsdf.begin() + size_t(old) * VD_BRICK_VOXELS));
  }
  EXPECT_TRUE(std::all_of(t_after.begin() + n_kept, t_after.end(), [](float v) { return v == 1.f; }));
  EXPECT_TRUE(std::all_of(w_after.begin() + n_kept, w_after.end(), [](float v) { return v == 0.f; }));
}

// The deformation field on the pool: slots handed out are put at rest from their keys (against the
// CPU, and the dense grid's rest positions on the same lattice), growing keeps it, compaction moves
// it with the bricks.
TEST(BrickHashParityTest, TheFieldStartsAtRestAndMovesWithItsBricks) {
  VD_REQUIRE_OCL(ctx);
  DeviceOps ops(ctx);
  ASSERT_TRUE(ops.Init().ok());
  const VdCamera cam = test::TestCamera(160, 120);
  const std::vector<float> depth = test::SphereDepth(cam, 0.8f, 0.2f, 1.2f);
  ocl::Buffer<float> dd = test::ToDevice(ctx, depth);
  const float voxel = 0.008f, trunc = 0.032f;
  auto table = ocl::BrickTable::Create(*ctx, 1 << 11);
  ASSERT_TRUE(table.ok());
  ASSERT_TRUE(table->AllocateAndList(*ctx, dd, cam, test::IdentityPose(), trunc, VD_BRICK * voxel).ok());
  auto counts = table->Counts(*ctx);
  ASSERT_TRUE(counts.ok());
  const uint32_t used = counts->used;
  ASSERT_GT(used, 100u);
  auto pool = ocl::BrickPool::Create(*ctx, used / 2, true);
  ASSERT_TRUE(pool.ok());
  // Too few slots yet: refused; grown, the first half then the rest put at rest.
  EXPECT_EQ(pool->RestField(*ctx, *table, 0, used, voxel).code(), StatusCode::kOutOfRange);
  ASSERT_TRUE(pool->RestField(*ctx, *table, 0, used / 2, voxel).ok());
  ASSERT_TRUE(pool->Grow(*ctx, used).ok());
  ASSERT_TRUE(pool->RestField(*ctx, *table, used / 2, used - used / 2, voxel).ok());
  const size_t n = size_t(used) * VD_BRICK_VOXELS;
  std::vector<vd_float4> pos = test::FromDevice(ctx, pool->def_pos, n), rot = test::FromDevice(ctx, pool->def_rot, n);
  const cpu::BrickTable ref = [&] {
    cpu::BrickTable t(table->capacity(), table->pool());
    t.keys = test::FromDevice(ctx, table->keys(), table->capacity());
    t.slots = test::FromDevice(ctx, table->slots(), table->capacity());
    t.slot_keys = test::FromDevice(ctx, table->slot_keys(), table->pool());
    t.counters[VD_BRICK_COUNT_TAKEN] = used;
    return t;
  }();
  std::vector<vd_float4> rp(n), rr(n);
  for (size_t i = 0; i < n; ++i) vd_pool_field_rest(ref.slot_keys.data(), int(i), voxel, rp.data(), rr.data());
  EXPECT_EQ(test::Flatten(pos), test::Flatten(rp));
  EXPECT_EQ(test::Flatten(rot), test::Flatten(rr));
  // The dense grid's rest position of the same point, its origin on the lattice.
  VdVolume dense{};
  dense.voxel_size = voxel;
  dense.origin = VD_F4(-80 * voxel, -80 * voxel, 0.f, 1.f);
  for (size_t i = 0; i < n; i += 997) {
    int g[3];
    vd_brick_voxel(ref.slot_keys[i / VD_BRICK_VOXELS], int(i % VD_BRICK_VOXELS), &g[0], &g[1], &g[2]);
    const vd_float4 d = vd_rest_position(dense, g[0] + 80, g[1] + 80, g[2]);
    EXPECT_NEAR(d.x, pos[i].x, 1e-6f);
    EXPECT_NEAR(d.y, pos[i].y, 1e-6f);
    EXPECT_NEAR(d.z, pos[i].z, 1e-6f);
    EXPECT_EQ(pos[i].w, 0.f);
  }
  // A deformed field, then compaction: every kept brick's field goes with it (against the CPU).
  for (size_t i = 0; i < n; ++i) {
    pos[i].x += 1e-4f * float(i % 7);
    pos[i].w = float(i % 5);
    rot[i] = VD_F4(0.f, 0.f, std::sin(1e-3f * float(i % 11)), std::cos(1e-3f * float(i % 11)));
  }
  ASSERT_TRUE(ctx->Upload(pool->def_pos, pos.data(), n).ok());
  ASSERT_TRUE(ctx->Upload(pool->def_rot, rot.data(), n).ok());
  std::vector<uint32_t> keep(table->pool(), 0u);
  for (uint32_t sl = 0; sl < used; ++sl) keep[sl] = sl % 3 != 1;
  ocl::Buffer<uint32_t> dkeep = test::ToDevice(ctx, keep);
  ASSERT_TRUE(table->Compact(ops, dkeep, &*pool).ok());
  cpu::BrickFieldMove(keep.data(), used, pos.data(), rot.data());
  uint32_t kept = 0;
  for (uint32_t sl = 0; sl < used; ++sl) kept += keep[sl];
  const size_t nk = size_t(kept) * VD_BRICK_VOXELS;
  EXPECT_EQ(test::Flatten(test::FromDevice(ctx, pool->def_pos, nk)),
            test::Flatten(std::vector<vd_float4>(pos.begin(), pos.begin() + nk)));
  EXPECT_EQ(test::Flatten(test::FromDevice(ctx, pool->def_rot, nk)),
            test::Flatten(std::vector<vd_float4>(rot.begin(), rot.begin() + nk)));
  // A pool without a field ignores RestField.
  auto plain = ocl::BrickPool::Create(*ctx, 4);
  ASSERT_TRUE(plain.ok());
  EXPECT_TRUE(plain->RestField(*ctx, *table, 0, 100, voxel).ok());
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
  // The one-pass walk counts them as out of the volume's reach, each frame.
  for (int frame = 0; frame < 2; ++frame) {
    ASSERT_TRUE(table->AllocateAndList(*ctx, dfar, cam, test::IdentityPose(), 0.01f, 0.032f).ok());
    counts = table->Counts(*ctx);
    ASSERT_TRUE(counts.ok());
    EXPECT_EQ(counts->used, 0u);
    EXPECT_EQ(counts->visible, 0u);
    EXPECT_GT(counts->out_of_range, 0u) << frame;
  }
}

}  // namespace
}  // namespace vd
