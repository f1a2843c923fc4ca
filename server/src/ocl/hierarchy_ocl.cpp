// The launchers of kernels/hierarchy.cl that HierarchicalSolver (core/hierarchy.cpp) calls.
#include "ocl/hierarchy_ocl.h"

#include <algorithm>

#include "ocl/active_set_ocl.h"
#include "ocl/brick_hash_ocl.h"

namespace vd::ocl {

// The eight VD_LEVELS_PARAMS of two levels.
#define VD_LEVELS_OF(fl, fine, cl, coarse) \
  (fl).lat, (fine).list, (fine).compact, (cl).lat, (coarse).list, (coarse).compact, *(fl).nbr, *(fl).slot_keys

StatusOr<uint32_t> BrickTable::AllocateLevelCorners(Context& ctx, const DeviceActiveSet& fine, int s) {
  if (s < 2 || s > VD_BRICK || (VD_BRICK % s) != 0) return InvalidArgument("a level's spacing divides the brick side");
  VD_ASSIGN_OR_RETURN(const BrickCounts before, Counts(ctx));
  if (fine.count == 0) return 0u;
  if (neighbours_.size() < size_t(VD_BRICK_NEIGHBOURS) * before.used)
    return FailedPrecondition("AllocateLevelCorners needs the neighbours of every brick in use");
  VD_RETURN_IF_ERROR(kBrickLevelAlloc(ctx, fine.count, fine.list, s, neighbours_, keys_, slots_, slot_keys_, capacity_,
                                      pool_, counters_));
  VD_ASSIGN_OR_RETURN(const BrickCounts after, OrderNewSlots(ctx));
  return after.used - before.used;
}

Status MarkLevel(Context& ctx, const DeviceLattice& fl, const DeviceActiveSet& fine, int s, const DeviceLattice& cl,
                 Buffer<uint8_t>& member) {
  return kLevelMark(ctx, fine.count, fl.lat, *fl.nbr, fine.list, s, cl.lat, member);
}

Status CompactLevel(DeviceOps& ops, const DeviceLattice& cl, size_t entries, const Buffer<uint8_t>& member,
                    Buffer<uint32_t>& row_count, Buffer<uint32_t>& row_offset, DeviceActiveSet* coarse) {
  Context& ctx = ops.ctx();
  const int row = cl.lat.dim_x;
  const size_t rows = entries / size_t(row);
  VD_RETURN_IF_ERROR(ctx.Reserve(&row_count, std::max<size_t>(rows, 1)));
  VD_RETURN_IF_ERROR(ctx.Reserve(&row_offset, rows + 1));
  VD_RETURN_IF_ERROR(ctx.Reserve(&coarse->compact, std::max<size_t>(entries, 1)));
  VD_RETURN_IF_ERROR(kLevelRowCount(ctx, rows, member, row, row_count));
  uint32_t total = 0;
  VD_RETURN_IF_ERROR(ops.ScanExclusive(row_count, rows, row_offset, &total));
  coarse->count = total;
  coarse->kept = VdVolume{};
  VD_RETURN_IF_ERROR(ctx.Reserve(&coarse->list, std::max<size_t>(total, 1)));
  VD_RETURN_IF_ERROR(ctx.Reserve(&coarse->neighbours, 6 * std::max<size_t>(total, 1)));
  // The compaction walks rows of `row` entries: as a grid of that row length and rows * row entries.
  VdVolume rows_of{};
  rows_of.dim_x = row;
  rows_of.dim_y = 1;
  rows_of.dim_z = int(rows);
  VD_RETURN_IF_ERROR(kActiveCompact(ctx, rows, member, row_offset, rows_of, 0, coarse->list, coarse->compact));
  return kLevelNeighbours(ctx, total, cl.lat, *cl.nbr, coarse->list, coarse->compact, coarse->neighbours);
}

Status RestrictState(Context& ctx, const DeviceLattice& fl, const DeviceActiveSet& fine, const DeviceLattice& cl,
                     const DeviceActiveSet& coarse, int s, const Buffer<vd_float4>& x_f, const Buffer<vd_float4>& rot_f,
                     Buffer<vd_float4>& x0_c, Buffer<vd_float4>& rot_c) {
  return kLevelRestrict(ctx, coarse.count, VD_LEVELS_OF(fl, fine, cl, coarse), s, x_f, rot_f, x0_c, rot_c);
}

Status RestrictConstraints(Context& ctx, const DeviceLattice& fl, const DeviceActiveSet& fine, const DeviceLattice& cl,
                           const DeviceActiveSet& coarse, int s, size_t n, const Buffer<VdCorrespondence>& cons_f,
                           const Buffer<int32_t>& cell_f, const Buffer<vd_float4>& x_f, const Buffer<vd_float4>& x0_c,
                           Buffer<VdCorrespondence>& cons_c) {
  return kLevelConstraints(ctx, n, VD_LEVELS_OF(fl, fine, cl, coarse), s, cons_f, cell_f, x_f, x0_c, cons_c);
}

Status LevelMoments(Context& ctx, const DeviceLattice& fl, const DeviceActiveSet& fine, const DeviceLattice& cl,
                    const DeviceActiveSet& coarse, int s, const Buffer<VdCorrespondence>& cons,
                    const Buffer<uint32_t>& cell_start, const Buffer<vd_float4>& x_f, Buffer<float>& moments_c) {
  return kLevelMoments(ctx, coarse.count, VD_LEVELS_OF(fl, fine, cl, coarse), s, cons, cell_start, x_f, moments_c);
}

Status LevelMomentsUp(Context& ctx, const DeviceLattice& fl, const DeviceActiveSet& fine, const DeviceLattice& cl,
                      const DeviceActiveSet& coarse, const Buffer<float>& moments_f, Buffer<float>& moments_c) {
  return kLevelMomentsUp(ctx, coarse.count, VD_LEVELS_OF(fl, fine, cl, coarse), moments_f, moments_c);
}

Status ProlongateIncrement(Context& ctx, const DeviceLattice& fl, const DeviceActiveSet& fine, const DeviceLattice& cl,
                           const DeviceActiveSet& coarse, int s, const Buffer<vd_float4>& x_c,
                           const Buffer<vd_float4>& x0_c, Buffer<vd_float4>& x_f) {
  return kLevelProlongate(ctx, fine.count, VD_LEVELS_OF(fl, fine, cl, coarse), s, x_c, x0_c, x_f);
}

}  // namespace vd::ocl
