// The brick table's launchers (ocl/brick_hash_ocl.h).
#include "ocl/brick_hash_ocl.h"

#include <algorithm>
#include <utility>
#include <vector>

#include "ocl/device_ops.h"

namespace vd::ocl {

StatusOr<BrickTable> BrickTable::Create(Context& ctx, uint32_t pool) {
  if (pool == 0 || pool > (1u << 28)) return InvalidArgument("brick pool of " + std::to_string(pool) + " bricks");
  BrickTable t;
  t.pool_ = pool;
  t.capacity_ = 1;
  while (t.capacity_ < 2 * pool) t.capacity_ <<= 1;
  VD_ASSIGN_OR_RETURN(t.keys_, ctx.Alloc<uint32_t>(t.capacity_));
  VD_ASSIGN_OR_RETURN(t.slots_, ctx.Alloc<int32_t>(t.capacity_));
  VD_ASSIGN_OR_RETURN(t.slot_keys_, ctx.Alloc<uint32_t>(pool));
  VD_ASSIGN_OR_RETURN(t.stamp_, ctx.Alloc<uint32_t>(pool));
  // One per table entry: AllocateAndList lists entries, of which a frame may name more than the pool holds.
  VD_ASSIGN_OR_RETURN(t.visible_, ctx.Alloc<int32_t>(t.capacity_));
  VD_ASSIGN_OR_RETURN(t.counters_, ctx.Alloc<uint32_t>(VD_BRICK_COUNTERS));
  VD_ASSIGN_OR_RETURN(t.entry_stamp_, ctx.Alloc<uint32_t>(t.capacity_));
  VD_RETURN_IF_ERROR(t.Clear(ctx));
  return t;
}

Status BrickTable::Clear(Context& ctx) {
  VD_RETURN_IF_ERROR(ctx.Fill(keys_, VD_BRICK_EMPTY, capacity_));
  VD_RETURN_IF_ERROR(ctx.Fill(slots_, int32_t(-1), capacity_));
  VD_RETURN_IF_ERROR(ctx.Fill(slot_keys_, VD_BRICK_EMPTY, pool_));
  VD_RETURN_IF_ERROR(ctx.Fill(stamp_, 0u, pool_));
  VD_RETURN_IF_ERROR(ctx.Fill(entry_stamp_, 0u, capacity_));
  frame_ = 0;
  ordered_ = 0;
  return ctx.Fill(counters_, 0u, VD_BRICK_COUNTERS);
}

StatusOr<BrickCounts> BrickTable::OrderNewSlots(Context& ctx) {
  VD_ASSIGN_OR_RETURN(const BrickCounts counts, Counts(ctx));
  const uint32_t first = std::min(ordered_, counts.used), n = counts.used - first;
  ordered_ = counts.used;
  if (n < 2) return counts;
  batch_keys_.resize(n);
  VD_RETURN_IF_ERROR(ctx.Download(slot_keys_, batch_keys_.data(), n, first));
  if (std::is_sorted(batch_keys_.begin(), batch_keys_.end())) return counts;
  std::sort(batch_keys_.begin(), batch_keys_.end());
  VD_RETURN_IF_ERROR(ctx.Upload(slot_keys_, batch_keys_.data(), n, first));
  VD_RETURN_IF_ERROR(kBrickReslot(ctx, n, slot_keys_, int32_t(first), keys_, slots_, capacity_));
  return counts;
}

Status BrickTable::AllocateFromDepth(Context& ctx, const Buffer<float>& depth, VdCamera cam, VdPose cam_to_world,
                                     float truncation, float brick_size) {
  if (!(brick_size > 0.f) || !(truncation >= 0.f)) return InvalidArgument("brick size and truncation must be positive");
  if (depth.size() < size_t(cam.width) * cam.height) return InvalidArgument("depth buffer smaller than the camera");
  VD_RETURN_IF_ERROR(kBrickAllocDepth(ctx, size_t(vd_depth_tiles_x(cam)) * vd_depth_tiles_y(cam), depth, cam,
                                      cam_to_world, truncation, brick_size, keys_, slots_, slot_keys_, capacity_, pool_,
                                      counters_));
  return OrderNewSlots(ctx).status();
}

Status BrickTable::ListVisible(Context& ctx, const Buffer<float>& depth, VdCamera cam, VdPose cam_to_world,
                               float truncation, float brick_size) {
  if (!(brick_size > 0.f) || !(truncation >= 0.f)) return InvalidArgument("brick size and truncation must be positive");
  if (depth.size() < size_t(cam.width) * cam.height) return InvalidArgument("depth buffer smaller than the camera");
  VD_RETURN_IF_ERROR(NextFrame(ctx));
  return kBrickList(ctx, size_t(vd_depth_tiles_x(cam)) * vd_depth_tiles_y(cam), depth, cam, cam_to_world, truncation,
                    brick_size, keys_, slots_, capacity_, stamp_, frame_, visible_, counters_);
}

Status BrickTable::NextFrame(Context& ctx) {
  const uint32_t zero[3] = {0u, 0u, 0u};
  static_assert(
      VD_BRICK_COUNT_UNFUSED == VD_BRICK_COUNT_VISIBLE + 1 && VD_BRICK_COUNT_OUT_OF_RANGE == VD_BRICK_COUNT_VISIBLE + 2,
      "the per-frame counters are adjacent");
  VD_RETURN_IF_ERROR(ctx.Upload(counters_, zero, 3, VD_BRICK_COUNT_VISIBLE));
  if (++frame_ == 0) {  // wrapped: no stamp may match the new number
    VD_RETURN_IF_ERROR(ctx.Fill(stamp_, 0u, pool_));
    VD_RETURN_IF_ERROR(ctx.Fill(entry_stamp_, 0u, capacity_));
    frame_ = 1;
  }
  return Status::Ok();
}

Status BrickTable::AllocateAndList(Context& ctx, const Buffer<float>& depth, VdCamera cam, VdPose cam_to_world,
                                   float truncation, float brick_size) {
  if (!(brick_size > 0.f) || !(truncation >= 0.f)) return InvalidArgument("brick size and truncation must be positive");
  if (depth.size() < size_t(cam.width) * cam.height) return InvalidArgument("depth buffer smaller than the camera");
  VD_RETURN_IF_ERROR(NextFrame(ctx));
  VD_RETURN_IF_ERROR(kBrickAllocList(ctx, size_t(vd_depth_tiles_x(cam)) * vd_depth_tiles_y(cam), depth, cam,
                                     cam_to_world, truncation, brick_size, keys_, slots_, slot_keys_, capacity_, pool_,
                                     entry_stamp_, frame_, visible_, counters_));
  // Listed as table entries: the second pass reads their slots after the batch is ordered.
  VD_ASSIGN_OR_RETURN(const BrickCounts counts, OrderNewSlots(ctx));
  return kBrickEntrySlots(ctx, counts.visible, visible_, slots_, stamp_, frame_, counters_);
}

StatusOr<uint32_t> BrickTable::AllocateRing(Context& ctx, const Buffer<uint8_t>& surface) {
  VD_ASSIGN_OR_RETURN(const BrickCounts before, Counts(ctx));
  if (before.used == 0) return 0u;
  if (surface.size() < size_t(before.used) * VD_BRICK_VOXELS ||
      neighbours_.size() < size_t(VD_BRICK_NEIGHBOURS) * before.used)
    return FailedPrecondition("AllocateRing needs the surface flags and the neighbours of every brick in use");
  VD_RETURN_IF_ERROR(
      kBrickRingAlloc(ctx, before.used, surface, neighbours_, keys_, slots_, slot_keys_, capacity_, pool_, counters_));
  VD_ASSIGN_OR_RETURN(const BrickCounts after, OrderNewSlots(ctx));
  return after.used - before.used;
}

Status BrickTable::Insert(Context& ctx, const Buffer<uint32_t>& keys, size_t n) {
  if (keys.size() < n) return InvalidArgument("fewer keys than asked to insert");
  VD_RETURN_IF_ERROR(kBrickInsertKeys(ctx, n, keys, keys_, slots_, slot_keys_, capacity_, pool_, counters_));
  return OrderNewSlots(ctx).status();
}

Status BrickTable::Restore(Context& ctx, const Buffer<uint32_t>& keys, size_t n) {
  if (n > pool_)
    return OutOfRange(std::to_string(n) + " bricks do not fit a pool of " + std::to_string(pool_) + " bricks");
  if (keys.size() < n) return InvalidArgument("fewer keys than asked to restore");
  VD_RETURN_IF_ERROR(Clear(ctx));
  if (n == 0) return Status::Ok();
  VD_RETURN_IF_ERROR(kBrickRestore(ctx, n, keys, keys_, slots_, slot_keys_, capacity_, counters_));
  const uint32_t taken = uint32_t(n);
  VD_RETURN_IF_ERROR(ctx.Upload(counters_, &taken, 1, VD_BRICK_COUNT_TAKEN));
  ordered_ = taken;  // the slots are the saved ones
  VD_ASSIGN_OR_RETURN(const BrickCounts counts, Counts(ctx));
  if (counts.failed > 0) {
    const Status cleared = Clear(ctx);
    (void)cleared;
    return DataLoss(std::to_string(counts.failed) + " of " + std::to_string(n) +
                    " brick keys to restore are invalid or repeated");
  }
  return Status::Ok();
}

Status BrickTable::Lookup(Context& ctx, const Buffer<uint32_t>& keys, size_t n, Buffer<int32_t>& out) const {
  if (keys.size() < n || out.size() < n) return InvalidArgument("lookup buffers smaller than n");
  return kBrickLookup(ctx, n, keys, keys_, slots_, capacity_, out);
}

Status BrickTable::Compact(DeviceOps& ops, const Buffer<uint32_t>& keep, BrickPool* pool) {
  Context& ctx = ops.ctx();
  if (keep.size() < pool_) return InvalidArgument("compaction needs one keep flag per pool slot");
  // Only the slots handed out hold bricks: the prefix sum runs over them.
  VD_ASSIGN_OR_RETURN(const BrickCounts before, Counts(ctx));
  if (pool && pool->slots < before.used) return InvalidArgument("the brick pool holds fewer bricks than the table");
  VD_RETURN_IF_ERROR(ctx.Reserve(&offsets_, size_t(pool_) + 1));
  uint32_t kept = 0;
  if (before.used > 0) VD_RETURN_IF_ERROR(ops.ScanExclusive(keep, before.used, offsets_, &kept));
  VD_RETURN_IF_ERROR(ctx.Reserve(&new_keys_, capacity_));
  VD_RETURN_IF_ERROR(ctx.Reserve(&new_slots_, capacity_));
  VD_RETURN_IF_ERROR(ctx.Fill(new_keys_, VD_BRICK_EMPTY, capacity_));
  VD_RETURN_IF_ERROR(ctx.Fill(new_slots_, int32_t(-1), capacity_));
  VD_RETURN_IF_ERROR(ctx.Reserve(&new_slot_keys_, pool_));
  VD_RETURN_IF_ERROR(ctx.Fill(new_slot_keys_, VD_BRICK_EMPTY, pool_));
  VD_RETURN_IF_ERROR(ctx.Reserve(&new_stamp_, pool_));
  VD_RETURN_IF_ERROR(ctx.Fill(new_stamp_, 0u, pool_));
  const uint32_t counts[VD_BRICK_COUNTERS] = {kept, 0u, 0u, 0u, 0u};
  VD_RETURN_IF_ERROR(ctx.Upload(counters_, counts, VD_BRICK_COUNTERS));
  VD_RETURN_IF_ERROR(kBrickCompact(ctx, capacity_, keys_, slots_, keep, offsets_, stamp_, new_keys_, new_slots_,
                                   new_slot_keys_, new_stamp_, capacity_, counters_));
  std::swap(keys_, new_keys_);
  std::swap(slots_, new_slots_);
  std::swap(slot_keys_, new_slot_keys_);
  std::swap(stamp_, new_stamp_);
  ordered_ = kept;
  // Entries moved: their stamps mean nothing now.
  VD_RETURN_IF_ERROR(ctx.Fill(entry_stamp_, 0u, capacity_));
  if (pool && before.used > 0) {
    VD_RETURN_IF_ERROR(kBrickPoolMove(ctx, VD_BRICK_VOXELS, keep, offsets_, int32_t(before.used), pool->tsdf,
                                      pool->weight, pool->color));
    if (pool->with_field)
      VD_RETURN_IF_ERROR(
          kBrickFieldMove(ctx, VD_BRICK_VOXELS, keep, offsets_, int32_t(before.used), pool->def_pos, pool->def_rot));
    // Slots kept..used-1 are free again: new bricks there start at rest.
    const size_t from = size_t(kept) * VD_BRICK_VOXELS, n = size_t(before.used - kept) * VD_BRICK_VOXELS;
    VD_RETURN_IF_ERROR(ctx.Fill(pool->tsdf, 1.0f, n, from));
    VD_RETURN_IF_ERROR(ctx.Fill(pool->weight, 0.0f, n, from));
    VD_RETURN_IF_ERROR(ctx.Fill(pool->color, 0u, n, from));
  }
  return Status::Ok();
}

StatusOr<uint32_t> BrickTable::EvictOldest(DeviceOps& ops, BrickPool& pool, uint32_t count) {
  Context& ctx = ops.ctx();
  VD_ASSIGN_OR_RETURN(const BrickCounts counts, Counts(ctx));
  if (counts.used == 0 || count == 0) return 0u;
  std::vector<uint32_t> stamps(counts.used);
  VD_RETURN_IF_ERROR(ctx.Download(stamp_, stamps.data(), counts.used));
  // Candidates: every brick the last listing did not reach, oldest listing first (slot order
  // among equals, so the choice is deterministic).
  std::vector<uint32_t> order;
  for (uint32_t s = 0; s < counts.used; ++s)
    if (stamps[s] != frame_ || frame_ == 0) order.push_back(s);
  const size_t drop = std::min<size_t>(count, order.size());
  if (drop == 0) return 0u;
  std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return stamps[a] < stamps[b]; });
  order.resize(drop);
  return Drop(ops, pool, order);
}

StatusOr<uint32_t> BrickTable::Drop(DeviceOps& ops, BrickPool& pool, const std::vector<uint32_t>& slots) {
  Context& ctx = ops.ctx();
  if (slots.empty()) return 0u;
  VD_ASSIGN_OR_RETURN(const BrickCounts counts, Counts(ctx));
  std::vector<uint32_t> keep(pool_, 0u);
  std::fill(keep.begin(), keep.begin() + counts.used, 1u);
  uint32_t dropped = 0;
  for (const uint32_t s : slots) {
    if (s >= counts.used) return InvalidArgument("a slot to drop that holds no brick");
    dropped += keep[s];
    keep[s] = 0u;
  }
  VD_RETURN_IF_ERROR(ctx.Reserve(&keep_, pool_));
  VD_RETURN_IF_ERROR(ctx.Upload(keep_, keep.data(), pool_));
  VD_RETURN_IF_ERROR(Compact(ops, keep_, &pool));
  return dropped;
}

StatusOr<std::vector<uint32_t>> BrickTable::DownloadSlotKeys(Context& ctx, uint32_t used) const {
  if (used > pool_) return InvalidArgument("more slots in use than the pool holds");
  std::vector<uint32_t> keys(used);
  if (used > 0) VD_RETURN_IF_ERROR(ctx.Download(slot_keys_, keys.data(), used));
  return keys;
}

StatusOr<BrickCounts> BrickTable::Counts(Context& ctx) const {
  uint32_t c[VD_BRICK_COUNTERS] = {};
  VD_RETURN_IF_ERROR(ctx.Download(counters_, c, VD_BRICK_COUNTERS));
  BrickCounts out;
  out.used = c[VD_BRICK_COUNT_TAKEN] < pool_ ? c[VD_BRICK_COUNT_TAKEN] : pool_;
  out.failed = c[VD_BRICK_COUNT_FAILED];
  out.visible = c[VD_BRICK_COUNT_VISIBLE];
  out.unfused = c[VD_BRICK_COUNT_UNFUSED];
  out.out_of_range = c[VD_BRICK_COUNT_OUT_OF_RANGE];
  return out;
}

Status BrickTable::BuildNeighbours(Context& ctx, uint32_t used) {
  if (used > pool_) return InvalidArgument("more slots in use than the pool holds");
  if (used == 0) return Status::Ok();
  // Grows with the slots in use, as the pool's voxels do.
  VD_RETURN_IF_ERROR(ctx.Reserve(&neighbours_, size_t(VD_BRICK_NEIGHBOURS) * used));
  return kBrickNeighbours(ctx, used, slot_keys_, keys_, slots_, capacity_, neighbours_);
}

StatusOr<BrickPool> BrickPool::Create(Context& ctx, uint32_t slots, bool with_field) {
  if (slots == 0) return InvalidArgument("a brick pool needs at least one slot");
  BrickPool p;
  p.with_field = with_field;
  VD_RETURN_IF_ERROR(p.Grow(ctx, slots));
  return p;
}

Status BrickPool::Grow(Context& ctx, uint32_t new_slots) {
  if (new_slots <= slots) return Status::Ok();
  const size_t old_n = size_t(slots) * VD_BRICK_VOXELS, n = size_t(new_slots) * VD_BRICK_VOXELS;
  auto grow = [&](auto& buffer, auto rest) -> Status {
    using T = decltype(rest);
    VD_ASSIGN_OR_RETURN(Buffer<T> bigger, ctx.Alloc<T>(n));
    VD_RETURN_IF_ERROR(ctx.Copy(buffer, bigger, old_n));
    VD_RETURN_IF_ERROR(ctx.Fill(bigger, rest, n - old_n, old_n));
    buffer = std::move(bigger);
    return Status::Ok();
  };
  VD_RETURN_IF_ERROR(grow(tsdf, 1.0f));
  VD_RETURN_IF_ERROR(grow(weight, 0.0f));
  VD_RETURN_IF_ERROR(grow(color, 0u));
  if (with_field) {
    // The new slots' rest positions are not known before the table hands them out (RestField).
    VD_RETURN_IF_ERROR(grow(def_pos, vd_float4{0.f, 0.f, 0.f, 0.f}));
    VD_RETURN_IF_ERROR(grow(def_rot, vd_float4{0.f, 0.f, 0.f, 1.f}));
  }
  slots = new_slots;
  return Status::Ok();
}

Status BrickPool::RestField(Context& ctx, const BrickTable& table, uint32_t first, uint32_t count, float voxel_size) {
  if (!with_field || count == 0) return Status::Ok();
  if (uint64_t(first) + count > slots || uint64_t(first) + count > table.pool())
    return OutOfRange("slots " + std::to_string(first) + ".." + std::to_string(first + count) +
                      " are past the pool's " + std::to_string(slots));
  return kBrickFieldRest(ctx, size_t(count) * VD_BRICK_VOXELS, table.slot_keys(), int32_t(first), voxel_size, def_pos,
                         def_rot);
}

Status BrickPool::Reset(Context& ctx) {
  const size_t n = size_t(slots) * VD_BRICK_VOXELS;
  VD_RETURN_IF_ERROR(ctx.Fill(tsdf, 1.0f, n));
  VD_RETURN_IF_ERROR(ctx.Fill(weight, 0.0f, n));
  return ctx.Fill(color, 0u, n);
}

Status IntegrateBricks(Context& ctx, const BrickTable& table, BrickPool& pool, VdVolume vol, VdCamera cam,
                       VdPose world_to_cam, const Buffer<float>& depth, const Buffer<uint32_t>& rgba) {
  if (depth.size() < size_t(cam.width) * cam.height || rgba.size() < size_t(cam.width) * cam.height)
    return InvalidArgument("depth or colour buffer smaller than the camera");
  VD_ASSIGN_OR_RETURN(const BrickCounts counts, table.Counts(ctx));
  if (pool.slots < counts.used)
    return InvalidArgument("the brick pool holds " + std::to_string(pool.slots) + " bricks; the table has handed out " +
                           std::to_string(counts.used));
  return kSparseIntegrate(ctx, size_t(counts.visible) * VD_BRICK_VOXELS, table.visible(), table.slot_keys(), pool.tsdf,
                          pool.weight, pool.color, vol, cam, world_to_cam, depth, rgba);
}

Status CountConstraints(Context& ctx, size_t n, const Buffer<VdCorrespondence>& corr, const BrickTable& table,
                        const Buffer<int32_t>& compact, Buffer<int32_t>& cell_of, Buffer<uint32_t>& counts) {
  if (corr.size() < n || cell_of.size() < n) return InvalidArgument("constraint buffers smaller than n");
  if (n == 0) return Status::Ok();
  return kSparseConstraintCount(ctx, n, corr, int32_t(table.pool()), table.slot_keys(), table.keys(), table.slots(),
                                table.capacity(), table.neighbours(), compact, cell_of, counts);
}

Status GrowBricks(Context& ctx, const BrickTable& table, BrickPool& pool, size_t count, const Buffer<int32_t>& slots,
                  const Buffer<VdPose>& motion, VdVolume vol, VdCamera cam, VdPose world_to_cam,
                  const Buffer<float>& depth, const Buffer<uint32_t>& rgba) {
  if (!pool.with_field) return FailedPrecondition("GrowBricks needs a brick pool with a deformation field");
  if (slots.size() < count || motion.size() < count) return InvalidArgument("fewer slots than asked to grow");
  if (count == 0) return Status::Ok();
  return kSparseGrow(ctx, count * VD_BRICK_VOXELS, slots, motion, table.slot_keys(), pool.tsdf, pool.weight, pool.color,
                     pool.def_pos, vol, cam, world_to_cam, depth, rgba);
}

}  // namespace vd::ocl
