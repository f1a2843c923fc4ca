#include "cpu_ref/brick_hash_ref.h"

#include <algorithm>
#include <numeric>

#include "ocl/mc_table.h"
#include "shared/sparse_field.h"

namespace vd::cpu {

BrickTable::BrickTable(uint32_t capacity_, uint32_t pool_)
    : capacity(capacity_),
      pool(pool_),
      keys(capacity_, VD_BRICK_EMPTY),
      slots(capacity_, -1),
      slot_keys(pool_, VD_BRICK_EMPTY),
      stamp(pool_, 0u) {}

namespace {
uint32_t Used(const BrickTable& t) { return std::min(t.counters[VD_BRICK_COUNT_TAKEN], t.pool); }

// BrickTable::OrderNewSlots: the slots a batch handed out (from `first`) in key order, with their
// entries (vd_brick_reslot).
void OrderNewSlots(uint32_t first, BrickTable* t) {
  const uint32_t used = Used(*t);
  if (used <= first + 1) return;
  std::sort(t->slot_keys.begin() + first, t->slot_keys.begin() + used);
  for (uint32_t s = first; s < used; ++s)
    vd_brick_reslot(int(s), t->slot_keys.data(), t->keys.data(), t->slots.data(), t->capacity);
}
}  // namespace

void BrickAllocDepth(const float* depth, VdCamera cam, VdPose cam_to_world, float truncation, float brick_size,
                     BrickTable* t) {
  const uint32_t first = Used(*t);
  for (int i = 0; i < vd_depth_tiles_x(cam) * vd_depth_tiles_y(cam); ++i)
    vd_brick_take_tile(VD_BRICK_ALLOCATE, i, depth, cam, cam_to_world, truncation, brick_size, t->keys.data(),
                       t->slots.data(), t->slot_keys.data(), t->capacity, t->pool, nullptr, 0u, nullptr, t->counters);
  OrderNewSlots(first, t);
}

std::vector<int32_t> BrickAllocList(const float* depth, VdCamera cam, VdPose cam_to_world, float truncation,
                                    float brick_size, BrickTable* t) {
  std::vector<uint32_t> entry_stamp(t->capacity, 0u);
  std::vector<int32_t> visible(t->capacity);
  t->counters[VD_BRICK_COUNT_VISIBLE] = 0;
  const uint32_t first = Used(*t);
  for (int i = 0; i < vd_depth_tiles_x(cam) * vd_depth_tiles_y(cam); ++i)
    vd_brick_take_tile(VD_BRICK_ALLOCATE_LIST, i, depth, cam, cam_to_world, truncation, brick_size, t->keys.data(),
                       t->slots.data(), t->slot_keys.data(), t->capacity, t->pool, entry_stamp.data(), 1u,
                       visible.data(), t->counters);
  visible.resize(t->counters[VD_BRICK_COUNT_VISIBLE]);
  OrderNewSlots(first, t);
  t->counters[VD_BRICK_COUNT_UNFUSED] = 0;
  for (size_t i = 0; i < visible.size(); ++i)
    vd_brick_entry_slot(int(i), visible.data(), t->slots.data(), t->stamp.data(), 1u, t->counters);
  return visible;
}

void BrickInsertKeys(const uint32_t* in, size_t n, BrickTable* t) {
  const uint32_t first = Used(*t);
  for (size_t i = 0; i < n; ++i)
    vd_brick_allocate(t->keys.data(), t->slots.data(), t->slot_keys.data(), t->capacity, t->pool, t->counters, in[i]);
  OrderNewSlots(first, t);
}

void BrickRestore(const uint32_t* in, size_t n, BrickTable* t) {
  for (size_t s = 0; s < n; ++s)
    vd_brick_restore(t->keys.data(), t->slots.data(), t->slot_keys.data(), t->capacity, t->counters, in[s], int(s));
  t->counters[VD_BRICK_COUNT_TAKEN] = uint32_t(n);
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
    vd_brick_reinsert(e, old.keys.data(), old.slots.data(), keep, offsets.data(), old.stamp.data(), t.keys.data(),
                      t.slots.data(), t.slot_keys.data(), t.stamp.data(), t.capacity, t.counters);
  return t;
}

namespace {
// The exclusive prefix sum of keep over the first `used` slots (independent of the device's scan).
std::vector<uint32_t> KeptOffsets(const uint32_t* keep, uint32_t used) {
  std::vector<uint32_t> offsets(used);
  uint32_t kept = 0;
  for (uint32_t s = 0; s < used; ++s) {
    offsets[s] = kept;
    kept += keep[s] ? 1u : 0u;
  }
  return offsets;
}
}  // namespace

void BrickPoolMove(const uint32_t* keep, uint32_t used, float* tsdf, float* weight, uint32_t* color) {
  const std::vector<uint32_t> offsets = KeptOffsets(keep, used);
  for (int v = 0; v < VD_BRICK_VOXELS; ++v)
    vd_brick_pool_move_lane(v, keep, offsets.data(), int(used), tsdf, weight, color);
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

void SparseGrow(const BrickTable& table, const std::vector<int32_t>& slots, const std::vector<VdPose>& motion,
                float* tsdf, float* weight, uint32_t* color, vd_float4* def_pos, VdVolume vol, VdCamera cam,
                VdPose world_to_cam, const float* depth, const uint32_t* rgba) {
  for (size_t b = 0; b < slots.size(); ++b)
    if (slots[b] >= 0)
      for (int v = 0; v < VD_BRICK_VOXELS; ++v)
        vd_grow_point(slots[b] * VD_BRICK_VOXELS + v, motion[b], table.slot_keys.data(), tsdf, weight, color, def_pos,
                      vol, cam, world_to_cam, depth, rgba);
}

void BrickFieldMove(const uint32_t* keep, uint32_t used, vd_float4* def_pos, vd_float4* def_rot) {
  const std::vector<uint32_t> offsets = KeptOffsets(keep, used);
  for (int v = 0; v < VD_BRICK_VOXELS; ++v)
    vd_brick_field_move_lane(v, keep, offsets.data(), int(used), def_pos, def_rot);
}

std::vector<int32_t> BrickNeighbours(const BrickTable& t, uint32_t used) {
  std::vector<int32_t> nbr(size_t(VD_BRICK_NEIGHBOURS) * t.pool, 0);
  for (uint32_t s = 0; s < used; ++s)
    vd_brick_neighbours_of(int(s), t.slot_keys.data(), t.keys.data(), t.slots.data(), t.capacity, nbr.data());
  return nbr;
}

std::vector<uint8_t> SparseBricksWeighted(const BrickTable& t, uint32_t used, const float* weight) {
  std::vector<uint8_t> out(used, 0);
  for (uint32_t slot = 0; slot < used; ++slot)
    out[slot] = uint8_t(t.slot_keys[slot] != VD_BRICK_EMPTY && vd_sparse_brick_weighted(weight, int(slot)));
  return out;
}

McMesh SparseMarchingCubes(const BrickTable& t, uint32_t used, const float* tsdf, const float* weight,
                           const uint32_t* color) {
  const McTable& table = GetMcTable();
  const std::vector<int32_t> nbr = BrickNeighbours(t, used);
  const size_t n = size_t(used) * VD_BRICK_VOXELS;
  std::vector<uint16_t> codes(n, 0);
  std::vector<uint8_t> masks(n, 0);
  std::vector<uint32_t> vert_count(n, 0), tri_count(n, 0);
  // Local coordinates of pool voxel i.
  auto local = [](size_t i, int* x, int* y, int* z) {
    const int v = int(i % VD_BRICK_VOXELS);
    *x = v % VD_BRICK, *y = (v / VD_BRICK) % VD_BRICK, *z = v / VD_BRICK_ROWS;
  };
  auto present = [&](int slot) { return nbr[VD_BRICK_NEIGHBOURS * size_t(slot) + VD_BRICK_SELF] >= 0; };
  for (size_t i = 0; i < n; ++i) {
    const int slot = int(i / VD_BRICK_VOXELS);
    if (!present(slot)) continue;
    int x, y, z;
    local(i, &x, &y, &z);
    codes[i] = uint16_t(vd_sparse_cell_code(tsdf, weight, nbr.data(), slot, x, y, z));
    tri_count[i] = (codes[i] & VD_MC_VALID) ? table.counts[codes[i] & 255] : 0;
  }
  for (size_t i = 0; i < n; ++i) {
    const int slot = int(i / VD_BRICK_VOXELS);
    if (!present(slot)) continue;
    int x, y, z;
    local(i, &x, &y, &z);
    masks[i] = uint8_t(vd_sparse_vertex_mask(tsdf, codes.data(), nbr.data(), slot, x, y, z));
    vert_count[i] = uint32_t(vd_popcount3(masks[i]));
  }
  std::vector<uint32_t> vert_offset(n), tri_offset(n);
  std::exclusive_scan(vert_count.begin(), vert_count.end(), vert_offset.begin(), 0u);
  std::exclusive_scan(tri_count.begin(), tri_count.end(), tri_offset.begin(), 0u);
  const uint32_t nv = n ? vert_offset[n - 1] + vert_count[n - 1] : 0;
  const uint32_t nt = n ? tri_offset[n - 1] + tri_count[n - 1] : 0;
  // Each row's first vertex (rows of VD_BRICK points), which the edge lookup counts on from.
  std::vector<uint32_t> row_vert_offset(n / VD_BRICK);
  for (size_t r = 0; r < row_vert_offset.size(); ++r) row_vert_offset[r] = vert_offset[r * VD_BRICK];
  McMesh mesh;
  mesh.positions_grid.resize(nv);
  mesh.normals.resize(nv);
  mesh.colors.resize(nv);
  mesh.triangles.resize(3 * size_t(nt));
  for (size_t i = 0; i < n; ++i) {
    if (!masks[i]) continue;
    const int slot = int(i / VD_BRICK_VOXELS);
    int x, y, z;
    local(i, &x, &y, &z);
    uint32_t out = vert_offset[i];
    for (int a = 0; a < 3; ++a) {
      if (!(masks[i] & (1u << a))) continue;
      vd_sparse_make_vertex(tsdf, color, nbr.data(), slot, t.slot_keys[slot], x, y, z, a, &mesh.positions_grid[out],
                            &mesh.normals[out], &mesh.colors[out]);
      ++out;
    }
  }
  for (size_t i = 0; i < n; ++i) {
    if (!(codes[i] & VD_MC_VALID)) continue;
    const int slot = int(i / VD_BRICK_VOXELS);
    int x, y, z;
    local(i, &x, &y, &z);
    const int8_t* row = &table.triangles[16 * (codes[i] & 255)];
    for (int k = 0; row[k] >= 0; ++k)
      mesh.triangles[3 * size_t(tri_offset[i]) + k] =
          vd_sparse_edge_vertex(masks.data(), row_vert_offset.data(), nbr.data(), slot, x, y, z, row[k]);
  }
  mesh.codes = std::move(codes);
  return mesh;
}

void BrickRingAllocate(const uint8_t* surface, uint32_t used, BrickTable* t) {
  const std::vector<int32_t> nbr = BrickNeighbours(*t, used);
  const uint32_t first = Used(*t);
  for (uint32_t s = 0; s < used; ++s)
    vd_brick_ring_allocate(int(s), surface, nbr.data(), t->keys.data(), t->slots.data(), t->slot_keys.data(),
                           t->capacity, t->pool, t->counters);
  OrderNewSlots(first, t);
}

void BrickLevelAllocate(const int32_t* list, size_t n, int s, uint32_t used, BrickTable* t) {
  const std::vector<int32_t> nbr = BrickNeighbours(*t, used);
  const uint32_t first = Used(*t);
  for (size_t k = 0; k < n; ++k)
    vd_brick_level_allocate(list[k], s, nbr.data(), t->keys.data(), t->slots.data(), t->slot_keys.data(), t->capacity,
                            t->pool, t->counters);
  OrderNewSlots(first, t);
}

ActiveSet SparseActiveSet(const BrickTable& t, uint32_t used, const uint16_t* codes, ActiveSet* solved) {
  const McTable& table = GetMcTable();
  const std::vector<int32_t> nbr = BrickNeighbours(t, used);
  const size_t n = size_t(used) * VD_BRICK_VOXELS;
  std::vector<uint8_t> surface(n, 0), member(n, 0);
  auto each = [&](auto&& f) {
    for (size_t i = 0; i < n; ++i) {
      const int slot = int(i / VD_BRICK_VOXELS), v = int(i % VD_BRICK_VOXELS);
      if (nbr[VD_BRICK_NEIGHBOURS * size_t(slot) + VD_BRICK_SELF] < 0) continue;
      f(i, slot, v % VD_BRICK, (v / VD_BRICK) % VD_BRICK, v / VD_BRICK_ROWS);
    }
  };
  each([&](size_t i, int s, int x, int y, int z) {
    surface[i] = vd_sparse_surface_point(codes, table.counts.data(), nbr.data(), s, x, y, z);
  });
  each([&](size_t i, int s, int x, int y, int z) {
    member[i] = vd_sparse_dilate_point(surface.data(), nbr.data(), s, x, y, z);
  });
  // Independent of the device's scan: a sequential compaction.
  auto compact = [&](const std::vector<uint8_t>& flags) {
    ActiveSet out;
    out.compact.assign(n, -1);
    for (size_t i = 0; i < n; ++i) {
      if (!flags[i]) continue;
      out.compact[i] = int32_t(out.list.size());
      out.list.push_back(int32_t(i));
    }
    out.neighbours.resize(6 * out.list.size());
    for (size_t k = 0; k < out.list.size(); ++k) {
      const int v = out.list[k] % VD_BRICK_VOXELS;
      vd_sparse_neighbours_of(out.compact.data(), nbr.data(), out.list[k] / VD_BRICK_VOXELS, v % VD_BRICK,
                              (v / VD_BRICK) % VD_BRICK, v / VD_BRICK_ROWS, &out.neighbours[6 * k]);
    }
    return out;
  };
  if (solved) *solved = compact(surface);
  return compact(member);
}

}  // namespace vd::cpu
