#pragma once
// The brick table of the sparse volume on the device (kernels/brick_hash.cl, per-item math in
// shared/brick_hash.h; docs/SPARSE_VOLUME.md): typed handles of its kernels and the table they
// work on.
#include <cstdint>
#include <vector>

#include "ocl/kernel.h"
#include "shared/sparse_field.h"

namespace vd {
class DeviceOps;
struct DeviceActiveSet;
}  // namespace vd

namespace vd::ocl {

// One item per depth tile (vd_depth_tiles_x * vd_depth_tiles_y).
inline constexpr Kernel<void(const Buffer<float>& depth, VdCamera cam, VdPose cam_to_world, float truncation,
                             float brick_size, Buffer<uint32_t>& keys, Buffer<int32_t>& slots,
                             Buffer<uint32_t>& slot_keys, uint32_t capacity, uint32_t pool, Buffer<uint32_t>& counters)>
    kBrickAllocDepth{"vd_brick_table_alloc_depth"};
// One item per depth tile.
inline constexpr Kernel<void(
    const Buffer<float>& depth, VdCamera cam, VdPose cam_to_world, float truncation, float brick_size,
    Buffer<uint32_t>& keys, Buffer<int32_t>& slots, Buffer<uint32_t>& slot_keys, uint32_t capacity, uint32_t pool,
    Buffer<uint32_t>& entry_stamp, uint32_t frame, Buffer<int32_t>& visible, Buffer<uint32_t>& counters)>
    kBrickAllocList{"vd_brick_table_alloc_list"};
// One item per listed entry.
inline constexpr Kernel<void(Buffer<int32_t>& visible, const Buffer<int32_t>& slots, Buffer<uint32_t>& slot_stamp,
                             uint32_t frame, Buffer<uint32_t>& counters)>
    kBrickEntrySlots{"vd_brick_entry_slots"};
// One item per key inserted.
inline constexpr Kernel<void(const Buffer<uint32_t>& in, Buffer<uint32_t>& keys, Buffer<int32_t>& slots,
                             Buffer<uint32_t>& slot_keys, uint32_t capacity, uint32_t pool, Buffer<uint32_t>& counters)>
    kBrickInsertKeys{"vd_brick_table_insert"};
// One item per slot in use.
inline constexpr Kernel<void(const Buffer<uint8_t>& surface, const Buffer<int32_t>& nbr, Buffer<uint32_t>& keys,
                             Buffer<int32_t>& slots, Buffer<uint32_t>& slot_keys, uint32_t capacity, uint32_t pool,
                             Buffer<uint32_t>& counters)>
    kBrickRingAlloc{"vd_brick_ring_alloc"};
// One item per slot restored.
inline constexpr Kernel<void(const Buffer<uint32_t>& in, Buffer<uint32_t>& keys, Buffer<int32_t>& slots,
                             Buffer<uint32_t>& slot_keys, uint32_t capacity, Buffer<uint32_t>& counters)>
    kBrickRestore{"vd_brick_table_restore"};
// One item per slot of the batch from `first`.
inline constexpr Kernel<void(const Buffer<uint32_t>& slot_keys, int32_t first, const Buffer<uint32_t>& keys,
                             Buffer<int32_t>& slots, uint32_t capacity)>
    kBrickReslot{"vd_brick_table_reslot"};
// One item per key looked up.
inline constexpr Kernel<void(const Buffer<uint32_t>& in, const Buffer<uint32_t>& keys, const Buffer<int32_t>& slots,
                             uint32_t capacity, Buffer<int32_t>& out)>
    kBrickLookup{"vd_brick_table_lookup"};
// One item per entry of the old table.
inline constexpr Kernel<void(
    const Buffer<uint32_t>& old_keys, const Buffer<int32_t>& old_slots, const Buffer<uint32_t>& keep,
    const Buffer<uint32_t>& offsets, const Buffer<uint32_t>& old_stamp, Buffer<uint32_t>& keys, Buffer<int32_t>& slots,
    Buffer<uint32_t>& slot_keys, Buffer<uint32_t>& stamp, uint32_t capacity, Buffer<uint32_t>& counters)>
    kBrickCompact{"vd_brick_table_compact"};
// One item per voxel lane (VD_BRICK_VOXELS).
inline constexpr Kernel<void(const Buffer<uint32_t>& keep, const Buffer<uint32_t>& offsets, int32_t used,
                             Buffer<float>& tsdf, Buffer<float>& weight, Buffer<uint32_t>& color)>
    kBrickPoolMove{"vd_brick_pool_move"};
// One item per depth tile (the table is only read).
inline constexpr Kernel<void(const Buffer<float>& depth, VdCamera cam, VdPose cam_to_world, float truncation,
                             float brick_size, Buffer<uint32_t>& keys, Buffer<int32_t>& slots, uint32_t capacity,
                             Buffer<uint32_t>& stamp, uint32_t frame, Buffer<int32_t>& visible,
                             Buffer<uint32_t>& counters)>
    kBrickList{"vd_brick_table_list"};
// One item per voxel of the slots put at rest.
inline constexpr Kernel<void(const Buffer<uint32_t>& slot_keys, int32_t first, float voxel_size,
                             Buffer<vd_float4>& def_pos, Buffer<vd_float4>& def_rot)>
    kBrickFieldRest{"vd_brick_field_rest"};
// One item per voxel lane (VD_BRICK_VOXELS).
inline constexpr Kernel<void(const Buffer<uint32_t>& keep, const Buffer<uint32_t>& offsets, int32_t used,
                             Buffer<vd_float4>& def_pos, Buffer<vd_float4>& def_rot)>
    kBrickFieldMove{"vd_brick_field_move"};
// One item per active point (pool indices in list).
inline constexpr Kernel<void(const Buffer<int32_t>& list, const Buffer<int32_t>& nbr, const Buffer<vd_float4>& def_pos,
                             const Buffer<vd_float4>& def_rot, float voxel_size, Buffer<vd_float4>& pos_out,
                             Buffer<vd_float4>& rot_out)>
    kSparseExtrapolate{"vd_sparse_extrapolate"};
// One item per member of M (pool indices; the ring points write, surface: 1 at the solved ones).
inline constexpr Kernel<void(const Buffer<int32_t>& list, const Buffer<uint8_t>& surface, const Buffer<int32_t>& nbr,
                             Buffer<vd_float4>& def_pos, Buffer<vd_float4>& def_rot, float voxel_size)>
    kSparseFollow{"vd_sparse_follow"};
// One item per voxel of the listed slots (-1: skipped).
inline constexpr Kernel<void(const Buffer<int32_t>& grow_slots, const Buffer<VdPose>& motion,
                             const Buffer<uint32_t>& slot_keys, Buffer<float>& tsdf, Buffer<float>& weight,
                             Buffer<uint32_t>& color, Buffer<vd_float4>& def_pos, VdVolume vol, VdCamera cam,
                             VdPose world_to_cam, const Buffer<float>& depth, const Buffer<uint32_t>& rgba)>
    kSparseGrow{"vd_sparse_grow"};
// One item per vertex.
inline constexpr Kernel<void(const Buffer<vd_float4>& grid_pos, const Buffer<uint32_t>& keys,
                             const Buffer<int32_t>& slots, uint32_t capacity, const Buffer<int32_t>& nbr,
                             const Buffer<vd_float4>& def_pos, float voxel_size, Buffer<vd_float4>& out)>
    kSparseDeformVertices{"vd_sparse_deform_vertices"};
// One item per vertex of the mesh over the bricks (DeviceMesh::brick_slots).
inline constexpr Kernel<void(const Buffer<vd_float4>& grid_pos, const Buffer<int32_t>& owner, int32_t num_slots,
                             const Buffer<uint32_t>& slot_keys, const Buffer<uint32_t>& keys,
                             const Buffer<int32_t>& slots, uint32_t capacity, const Buffer<int32_t>& nbr,
                             const Buffer<vd_float4>& def_pos, float voxel_size, Buffer<vd_float4>& out)>
    kSparseDeformMeshVertices{"vd_sparse_deform_mesh_vertices"};
// One item per per-pixel constraint.
inline constexpr Kernel<void(const Buffer<VdCorrespondence>& corr, int32_t num_slots, const Buffer<uint32_t>& slot_keys,
                             const Buffer<uint32_t>& keys, const Buffer<int32_t>& slots, uint32_t capacity,
                             const Buffer<int32_t>& nbr, const Buffer<int32_t>& compact, Buffer<int32_t>& cell_of,
                             Buffer<uint32_t>& counts)>
    kSparseConstraintCount{"vd_sparse_constraint_count"};
// Laned, one item per voxel of the listed bricks.
inline constexpr Kernel<void(const Buffer<int32_t>& visible, const Buffer<uint32_t>& slot_keys, Buffer<float>& tsdf,
                             Buffer<float>& weight, Buffer<uint32_t>& color, VdVolume vol, VdCamera cam,
                             VdPose world_to_cam, const Buffer<float>& depth, const Buffer<uint32_t>& rgba)>
    kSparseIntegrate{"vd_sparse_integrate", kLaned};

// One item per pool slot handed out.
inline constexpr Kernel<void(const Buffer<uint32_t>& slot_keys, const Buffer<uint32_t>& keys,
                             const Buffer<int32_t>& slots, uint32_t capacity, Buffer<int32_t>& nbr)>
    kBrickNeighbours{"vd_brick_neighbours"};

struct BrickPool;

// What the inserting kernels counted since the table was cleared.
struct BrickCounts {
  // Pool slots handed out (at most the pool; inserts past it failed).
  uint32_t used = 0;
  // Inserts that found no table entry within VD_BRICK_MAX_PROBE, no pool slot, or coordinates
  // outside the table's range.
  uint32_t failed = 0;
  // Bricks the last ListVisible or AllocateAndList listed.
  uint32_t visible = 0;
  // Of those, the ones AllocateAndList found no slot for (the pool is full): not fused this frame.
  uint32_t unfused = 0;
  // Visits of AllocateAndList's walk to bricks beyond the coordinates a key can name (+-512 bricks
  // from the origin): surface out of the volume's reach, not fused.
  uint32_t out_of_range = 0;
};

// A brick table on the device: `capacity` entries (a power of two, at least twice the pool, so
// probe runs stay short) mapping packed brick coordinates to slots of a pool of `pool` bricks.
class BrickTable {
 public:
  static StatusOr<BrickTable> Create(Context& ctx, uint32_t pool);
  uint32_t capacity() const { return capacity_; }
  uint32_t pool() const { return pool_; }
  const Buffer<uint32_t>& keys() const { return keys_; }
  const Buffer<int32_t>& slots() const { return slots_; }
  // The key of each pool slot's brick (VD_BRICK_EMPTY: none).
  const Buffer<uint32_t>& slot_keys() const { return slot_keys_; }

  // Empties the table and the counters.
  Status Clear(Context& ctx);
  // The bricks the truncation band of a depth image (metres, 0 = none) crosses, at camera pose
  // cam_to_world, for bricks of brick_size metres.
  Status AllocateFromDepth(Context& ctx, const Buffer<float>& depth, VdCamera cam, VdPose cam_to_world,
                           float truncation, float brick_size);
  // Lists the slots of the bricks the same depth image's band reaches (after AllocateFromDepth), each
  // once: the bricks this frame can change.
  Status ListVisible(Context& ctx, const Buffer<float>& depth, VdCamera cam, VdPose cam_to_world, float truncation,
                     float brick_size);
  const Buffer<int32_t>& visible() const { return visible_; }
  // AllocateFromDepth and ListVisible in one walk over the depth (the list may hold -1 for a brick
  // the pool had no room for).
  Status AllocateAndList(Context& ctx, const Buffer<float>& depth, VdCamera cam, VdPose cam_to_world, float truncation,
                         float brick_size);
  // Inserts n packed keys (a key already there keeps its slot).
  Status Insert(Context& ctx, const Buffer<uint32_t>& keys, size_t n);
  // Empties the table and gives slot s the key keys[s] for s < n (a table saved as its slots' keys,
  // so the pool's data goes back where it was): DataLoss when a key is not a brick's or repeats,
  // OutOfRange when n exceeds the pool.
  Status Restore(Context& ctx, const Buffer<uint32_t>& keys, size_t n);
  // The slots of n packed keys (-1: not in the table).
  Status Lookup(Context& ctx, const Buffer<uint32_t>& keys, size_t n, Buffer<int32_t>& out) const;
  // Keeps the bricks whose slot s has keep[s] != 0 (keep: one flag per pool slot), renumbered
  // 0..kept-1 in the order of their old slots, with the frame each was last listed in; `pool`,
  // when given, moves its voxels by the same map and puts the freed slots back at rest.
  Status Compact(DeviceOps& ops, const Buffer<uint32_t>& keep, BrickPool* pool = nullptr);
  // Drops the bricks listed longest ago (never one listed by the last ListVisible), at most
  // `count` of them, moving `pool` with the table (Compact); returns how many were dropped. The
  // frame numbers of ListVisible order them.
  StatusOr<uint32_t> EvictOldest(DeviceOps& ops, BrickPool& pool, uint32_t count);
  // Drops the bricks of the given slots (each below the slots handed out; repeats count once),
  // moving `pool` with the table (Compact); returns how many were dropped.
  StatusOr<uint32_t> Drop(DeviceOps& ops, BrickPool& pool, const std::vector<uint32_t>& slots);
  // The keys of the first `used` slots (the host's copy of slot_keys()).
  StatusOr<std::vector<uint32_t>> DownloadSlotKeys(Context& ctx, uint32_t used) const;
  // The frame number the last ListVisible stamped its bricks with.
  uint32_t frame() const { return frame_; }
  // The frame each slot's brick was last listed in (0: never).
  const Buffer<uint32_t>& stamps() const { return stamp_; }
  StatusOr<BrickCounts> Counts(Context& ctx) const;
  // The slots of the 27 bricks around each of the first `used` slots' bricks (shared/sparse_mesh.h:
  // VD_BRICK_NEIGHBOURS per slot, -1 where none), for the passes that read across brick faces.
  Status BuildNeighbours(Context& ctx, uint32_t used);
  const Buffer<int32_t>& neighbours() const { return neighbours_; }
  // Allocates, for each brick, the missing face neighbours that a surface point of it (surface:
  // one flag per pool voxel, as the active set's first pass writes them) has a 6-neighbour in, so
  // the active set can hold its one-ring (shared/sparse_mesh.h vd_brick_ring_allocate; after
  // BuildNeighbours). Returns how many bricks it added.
  StatusOr<uint32_t> AllocateRing(Context& ctx, const Buffer<uint8_t>& surface);
  // Allocates the bricks the coarse levels of the non-rigid solver need (up to spacing s): the
  // missing +x / +y / +z neighbours that a fine active point's coarse cell reaches into
  // (shared/hierarchy.h vd_brick_level_allocate; after BuildNeighbours; defined in
  // hierarchy_ocl.cpp). Returns how many bricks it added.
  StatusOr<uint32_t> AllocateLevelCorners(Context& ctx, const DeviceActiveSet& fine, int s);

 private:
  // Puts the slots handed out since the last call (a batch of inserts) in key order, their table
  // entries with them, and returns the counts. The inserts' atomics hand out slots in whatever
  // order the work-items ran; every later pass runs in slot order (the active set, the solver's
  // sums), so without this no two runs would be the same. Every method that allocates calls it.
  StatusOr<BrickCounts> OrderNewSlots(Context& ctx);
  uint32_t capacity_ = 0, pool_ = 0;
  // Slots [0, ordered_) are in order (OrderNewSlots); the host's copy of a new batch's keys.
  uint32_t ordered_ = 0;
  std::vector<uint32_t> batch_keys_;
  // The frame number ListVisible stamps slots with (0: never listed).
  uint32_t frame_ = 0;
  Buffer<uint32_t> keys_, slot_keys_, counters_, stamp_;
  // AllocateAndList's stamps, one per table entry (entries move at compaction: cleared then).
  Buffer<uint32_t> entry_stamp_;
  // The next frame number for a listing (wraps: every stamp is cleared then).
  Status NextFrame(Context& ctx);
  Buffer<int32_t> slots_, visible_;
  // VD_BRICK_NEIGHBOURS slots per slot in use (BuildNeighbours).
  Buffer<int32_t> neighbours_;
  // Compaction scratch: the prefix sum of keep, and the new table.
  Buffer<uint32_t> offsets_, new_keys_, new_slot_keys_, new_stamp_;
  // EvictOldest's keep flags.
  Buffer<uint32_t> keep_;
  Buffer<int32_t> new_slots_;
};

// The voxels of a brick pool: TSDF (normalised, 1 at rest), weight and colour, 512 per slot, slot
// s's brick is the table's slot_keys[s]. It may hold fewer slots than its table hands out, and
// grows as they are taken (Grow), so its memory follows the surface.
struct BrickPool {
  Buffer<float> tsdf, weight;
  Buffer<uint32_t> color;
  // The deformation field (shared/sparse_tsdf.h: t_i in world metres, R_i as a quaternion), one per
  // voxel, with_field only: 44 bytes a voxel with it, 12 without.
  Buffer<vd_float4> def_pos, def_rot;
  bool with_field = false;
  uint32_t slots = 0;
  // A pool of `slots` bricks at rest.
  static StatusOr<BrickPool> Create(Context& ctx, uint32_t slots, bool with_field = false);
  // Puts the deformation of slots [first, first + count) at rest (their rest positions come from
  // their keys: call it once the table has handed them out). A no-op without a field.
  Status RestField(Context& ctx, const BrickTable& table, uint32_t first, uint32_t count, float voxel_size);
  // Grows to `slots` bricks (no-op when it holds as many), keeping the bricks it has; the new ones
  // start at rest.
  Status Grow(Context& ctx, uint32_t slots);
  // Puts every brick back at rest.
  Status Reset(Context& ctx);
};

// Rigid fusion of a depth frame (metres, 0 = none) and its colour into the bricks of `table` its
// ListVisible listed (the pool must hold every slot the table has handed out), seen through world_to_cam; vol gives voxel_size, truncation and max_weight (the bricks tile space
// from the world origin).
Status IntegrateBricks(Context& ctx, const BrickTable& table, BrickPool& pool, VdVolume vol, VdCamera cam,
                       VdPose world_to_cam, const Buffer<float>& depth, const Buffer<uint32_t>& rgba);

// Growth (core/growth.h): the voxels of `count` slots (slots[i], -1 skipped; motion[i] their
// planned rigid motion) that were never fused, fused once ungated through the field (shared/
// sparse_field.h vd_grow_point); vol: voxel size, truncation and weight cap.
Status GrowBricks(Context& ctx, const BrickTable& table, BrickPool& pool, size_t count, const Buffer<int32_t>& slots,
                  const Buffer<VdPose>& motion, VdVolume vol, VdCamera cam, VdPose world_to_cam,
                  const Buffer<float>& depth, const Buffer<uint32_t>& rgba);

// The solver's constraint grouping on a sparse volume (CountConstraints' twin): cell_of[i] the
// compact index of constraint i's cell's first corner (-1: unusable), counts[cell] += 1. compact:
// the active set over the pool (DeviceOps::BuildActiveSet(table, ...), which builds the table's
// neighbours).
Status CountConstraints(Context& ctx, size_t n, const Buffer<VdCorrespondence>& corr, const BrickTable& table,
                        const Buffer<int32_t>& compact, Buffer<int32_t>& cell_of, Buffer<uint32_t>& counts);

}  // namespace vd::ocl
