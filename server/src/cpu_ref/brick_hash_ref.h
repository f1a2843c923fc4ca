#pragma once
// CPU reference of the brick table (server/kernels/brick_hash.cl): the same per-item functions of
// shared/brick_hash.h looped on the host, in item order. Each call that allocates puts the slots
// it handed out in key order, as the device does (BrickTable::OrderNewSlots), so that slots compare
// exactly while the pool has room.
#include <cstdint>
#include <vector>

#include "cpu_ref/cpu_ref.h"
#include "shared/hierarchy.h"
#include "shared/sparse_mesh.h"

namespace vd::cpu {

struct BrickTable {
  uint32_t capacity = 0, pool = 0;
  std::vector<uint32_t> keys;
  std::vector<int32_t> slots;
  std::vector<uint32_t> slot_keys;
  // The frame each slot was last listed in (moved by compaction).
  std::vector<uint32_t> stamp;
  uint32_t counters[VD_BRICK_COUNTERS] = {};
  // An empty table of `capacity` entries (a power of two) for a pool of `pool` bricks.
  BrickTable(uint32_t capacity, uint32_t pool);
};

void BrickAllocDepth(const float* depth, VdCamera cam, VdPose cam_to_world, float truncation, float brick_size,
                     BrickTable* table);
// Allocation and listing in one pass (BrickTable::AllocateAndList): the listed slots (-1 where the
// pool had no room), each brick once.
std::vector<int32_t> BrickAllocList(const float* depth, VdCamera cam, VdPose cam_to_world, float truncation,
                                    float brick_size, BrickTable* table);
void BrickInsertKeys(const uint32_t* in, size_t n, BrickTable* table);
// Slot s gets key in[s] (the table must be empty); failures counted as the device counts them.
void BrickRestore(const uint32_t* in, size_t n, BrickTable* table);
void BrickLookup(const uint32_t* in, size_t n, const BrickTable& table, int32_t* out);
// Keeps the bricks whose slot s has keep[s] != 0, renumbered by the exclusive prefix sum of keep.
BrickTable BrickCompact(const BrickTable& old, const uint32_t* keep);
// The slots of the bricks a depth image's band reaches, each once (in the device's order they are
// a set: compare sorted).
std::vector<int32_t> BrickListVisible(const float* depth, VdCamera cam, VdPose cam_to_world, float truncation,
                                      float brick_size, const BrickTable& table);
// Rigid fusion into a pool (tsdf, weight, colour: 512 per slot of table.slot_keys) of the listed slots.
void SparseIntegrate(const BrickTable& table, const std::vector<int32_t>& visible, float* tsdf, float* weight,
                     uint32_t* color, VdVolume vol, VdCamera cam, VdPose world_to_cam, const float* depth,
                     const uint32_t* rgba);

// Growth (vd_grow_point) into the voxels of the listed slots (-1 skipped), each slot with its
// rigid motion.
void SparseGrow(const BrickTable& table, const std::vector<int32_t>& slots, const std::vector<VdPose>& motion,
                float* tsdf, float* weight, uint32_t* color, vd_float4* def_pos, VdVolume vol, VdCamera cam,
                VdPose world_to_cam, const float* depth, const uint32_t* rgba);

// Moves the kept bricks' voxels (512 per slot of tsdf, weight, colour) to their compacted slots, as
// the device's vd_brick_pool_move does, for the first `used` slots.
void BrickPoolMove(const uint32_t* keep, uint32_t used, float* tsdf, float* weight, uint32_t* color);
// The field's moves of the same compaction (vd_brick_field_move_lane).
void BrickFieldMove(const uint32_t* keep, uint32_t used, vd_float4* def_pos, vd_float4* def_rot);
// The 27 neighbour slots of each of the first `used` slots (VD_BRICK_NEIGHBOURS per slot).
std::vector<int32_t> BrickNeighbours(const BrickTable& table, uint32_t used);
// vd_sparse_mc_weighted for the first `used` slots: 1 where an allocated brick holds weight.
std::vector<uint8_t> SparseBricksWeighted(const BrickTable& table, uint32_t used, const float* weight);
// Marching cubes over the first `used` slots of a pool (shared/sparse_mesh.h), in the device's
// order (slot, then row, then x), with the standard library's scan: positions_grid in global grid
// coordinates; codes one per pool voxel. Every allocated brick is classified here; the device
// skips those SparseBricksWeighted leaves out, which must not change the mesh.
McMesh SparseMarchingCubes(const BrickTable& table, uint32_t used, const float* tsdf, const float* weight,
                           const uint32_t* color);

// vd_brick_ring_allocate for each of the first `used` slots (surface: one flag per pool voxel).
void BrickRingAllocate(const uint8_t* surface, uint32_t used, BrickTable* table);
// The bricks a hierarchy of spacing up to s needs for the n fine active entries (pool indices)
// `list` (vd_brick_level_allocate), one entry after the other.
void BrickLevelAllocate(const int32_t* list, size_t n, int s, uint32_t used, BrickTable* table);
// The active set over the first `used` slots from SparseMarchingCubes' codes: list and compact in
// pool voxel indices, 6 neighbours per member.
// solved: also the surface points alone (the solver's unknowns).
ActiveSet SparseActiveSet(const BrickTable& table, uint32_t used, const uint16_t* codes, ActiveSet* solved = nullptr);

}  // namespace vd::cpu
