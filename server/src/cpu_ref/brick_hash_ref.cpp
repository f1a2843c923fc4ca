#include "cpu_ref/brick_hash_ref.h"

#include <algorithm>

namespace vd::cpu {

BrickTable::BrickTable(uint32_t capacity_, uint32_t pool_)
    : capacity(capacity_),
      pool(pool_),
      keys(capacity_, VD_BRICK_EMPTY),
      slots(capacity_, -1),
      slot_keys(pool_, VD_BRICK_EMPTY) {}

void BrickAllocDepth(const float* depth, VdCamera cam, VdPose cam_to_world, float truncation, float brick_size,
                     BrickTable* t) {
  for (int i = 0; i < vd_depth_tiles_x(cam) * vd_depth_tiles_y(cam); ++i)
    vd_brick_take_tile(VD_BRICK_ALLOCATE, i, depth, cam, cam_to_world, truncation, brick_size, t->keys.data(),
                       t->slots.data(), t->slot_keys.data(), t->capacity, t->pool, nullptr, 0u, nullptr, t->counters);
}

void BrickInsertKeys(const uint32_t* in, size_t n, BrickTable* t) {
  for (size_t i = 0; i < n; ++i)
    vd_brick_allocate(t->keys.data(), t->slots.data(), t->slot_keys.data(), t->capacity, t->pool, t->counters, in[i]);
}

void BrickLookup(const uint32_t* in, size_t n, const BrickTable& t, int32_t* out) {
  for (size_t i = 0; i < n; ++i) out[i] = vd_brick_find(t.keys.data(), t.slots.data(), t.capacity, in[i]);
}

BrickTable BrickCompact(const BrickTable& old, const uint32_t* keep) {
  std::vector<uint32_t> offsets(old.pool);
  uint32_t kept = 0;
  const uint32_t used = std::min(old.counters[VD_BRICK_COUNT_TAKEN], old.pool);
  for (uint32_t s = 0; s < used; ++s) {
    offsets[s] = kept;
    kept += keep[s] ? 1u : 0u;
  }
  BrickTable t(old.capacity, old.pool);
  t.counters[VD_BRICK_COUNT_TAKEN] = kept;
  for (uint32_t e = 0; e < old.capacity; ++e)
    vd_brick_reinsert(e, old.keys.data(), old.slots.data(), keep, offsets.data(), t.keys.data(), t.slots.data(),
                      t.slot_keys.data(), t.capacity, t.counters);
  return t;
}

std::vector<int32_t> BrickListVisible(const float* depth, VdCamera cam, VdPose cam_to_world, float truncation,
                                      float brick_size, const BrickTable& table) {
  std::vector<uint32_t> stamp(table.pool, 0u), keys = table.keys;
  std::vector<int32_t> visible(table.pool), slots = table.slots;
  uint32_t counters[VD_BRICK_COUNTERS] = {};
  for (int i = 0; i < vd_depth_tiles_x(cam) * vd_depth_tiles_y(cam); ++i)
    vd_brick_take_tile(VD_BRICK_LIST, i, depth, cam, cam_to_world, truncation, brick_size, keys.data(), slots.data(),
                       nullptr, table.capacity, 0u, stamp.data(), 1u, visible.data(), counters);
  visible.resize(counters[VD_BRICK_COUNT_VISIBLE]);
  return visible;
}

void SparseIntegrate(const BrickTable& table, const std::vector<int32_t>& visible, float* tsdf, float* weight,
                     uint32_t* color, VdVolume vol, VdCamera cam, VdPose world_to_cam, const float* depth,
                     const uint32_t* rgba) {
  for (int32_t slot : visible)
    for (int r = 0; r < VD_BRICK * VD_BRICK; ++r)
      vd_sparse_integrate_row(slot, r, table.slot_keys.data(), tsdf, weight, color, vol, cam, world_to_cam, depth,
                              rgba);
}

}  // namespace vd::cpu
