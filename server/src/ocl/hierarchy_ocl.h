#pragma once
// The kernels of kernels/hierarchy.cl, per-item math in shared/hierarchy.h. One typed handle
// each (ocl/kernel.h), its parameters those of the __kernel in order; kFoo(ctx, items, args...)
// runs it over `items` work items (what one item is, above each).
#include <cstdint>

#include "ocl/device_ops.h"
#include "ocl/kernel.h"
#include "shared/hierarchy.h"

namespace vd::ocl {

// The fine and the coarse active sets on their lattices, the kernels' VD_LEVELS_ARGS in order.
#define VD_LEVELS_PARAMS                                                                            \
  VdLattice lat_f, const Buffer<int32_t>&list_f, const Buffer<int32_t>&compact_f, VdLattice lat_c,  \
      const Buffer<int32_t>&list_c, const Buffer<int32_t>&compact_c, const Buffer<int32_t>&lat_nbr, \
      const Buffer<uint32_t>&slot_keys

// One item per fine active point.
inline constexpr Kernel<void(VdLattice fine, const Buffer<int32_t>& lat_nbr, const Buffer<int32_t>& list_f, int s,
                             VdLattice coarse, Buffer<uint8_t>& member)>
    kLevelMark{"vd_level_mark"};
// One item per row of `row` entries.
inline constexpr Kernel<void(const Buffer<uint8_t>& member, int row, Buffer<uint32_t>& row_count)> kLevelRowCount{
    "vd_level_row_count"};
// One item per coarse active point.
inline constexpr Kernel<void(VdLattice lat, const Buffer<int32_t>& lat_nbr, const Buffer<int32_t>& list,
                             const Buffer<int32_t>& compact, Buffer<int32_t>& neighbours)>
    kLevelNeighbours{"vd_level_neighbours"};
// One item per coarse active point.
inline constexpr Kernel<void(VD_LEVELS_PARAMS, int s, const Buffer<vd_float4>& x_f, const Buffer<vd_float4>& rot_f,
                             Buffer<vd_float4>& x0_c, Buffer<vd_float4>& rot_c)>
    kLevelRestrict{"vd_level_restrict_kernel"};
// One item per sorted fine constraint.
inline constexpr Kernel<void(VD_LEVELS_PARAMS, int s, const Buffer<VdCorrespondence>& cons_f,
                             const Buffer<int32_t>& cell_f, const Buffer<vd_float4>& x_f, const Buffer<vd_float4>& x0_c,
                             Buffer<VdCorrespondence>& cons_c)>
    kLevelConstraints{"vd_level_constraints"};
// One item per fine active point; adds to x_f.
inline constexpr Kernel<void(VD_LEVELS_PARAMS, int s, const Buffer<vd_float4>& x_c, const Buffer<vd_float4>& x0_c,
                             Buffer<vd_float4>& x_f)>
    kLevelProlongate{"vd_level_prolongate_kernel"};
// One item per coarse active point, as the first corner of a cell.
inline constexpr Kernel<void(VD_LEVELS_PARAMS, int s, const Buffer<VdCorrespondence>& cons,
                             const Buffer<uint32_t>& cell_start, const Buffer<vd_float4>& x_f,
                             Buffer<float>& moments_c)>
    kLevelMoments{"vd_level_moments_kernel"};

// One item per point of the upper level (coarse), from the level below it (fine, spacing ratio 2).
inline constexpr Kernel<void(VD_LEVELS_PARAMS, const Buffer<float>& moments_f, Buffer<float>& moments_c)>
    kLevelMomentsUp{"vd_level_moments_up_kernel"};

// One item per fine active point on the bricks.
inline constexpr Kernel<void(const Buffer<int32_t>& list_f, int s, const Buffer<int32_t>& lat_nbr,
                             Buffer<uint32_t>& keys, Buffer<int32_t>& slots, Buffer<uint32_t>& slot_keys,
                             uint32_t capacity, uint32_t pool, Buffer<uint32_t>& counters)>
    kBrickLevelAlloc{"vd_brick_level_alloc"};

// Launchers of HierarchicalSolver (core/hierarchy.cpp), which orders them coarse to fine. `fine`
// and `coarse` are the two levels' active sets on lattices fl and cl (cl = fl.Level(s)).

// Flags the coarse points (member: one flag per coarse entry) whose cells hold a fine active point.
Status MarkLevel(Context& ctx, const DeviceLattice& fl, const DeviceActiveSet& fine, int s, const DeviceLattice& cl,
                 Buffer<uint8_t>& member);
// The coarse active set from its flags over `entries` entries: per-row counts, their scan, the
// list, the map and the neighbour table. row_count and row_offset are scratch.
Status CompactLevel(DeviceOps& ops, const DeviceLattice& cl, size_t entries, const Buffer<uint8_t>& member,
                    Buffer<uint32_t>& row_count, Buffer<uint32_t>& row_offset, DeviceActiveSet* coarse);
// The coarse points' starting positions x0_c and rotations rot_c from the fine state.
Status RestrictState(Context& ctx, const DeviceLattice& fl, const DeviceActiveSet& fine, const DeviceLattice& cl,
                     const DeviceActiveSet& coarse, int s, const Buffer<vd_float4>& x_f, const Buffer<vd_float4>& rot_f,
                     Buffer<vd_float4>& x0_c, Buffer<vd_float4>& rot_c);
// The n sorted fine constraints (cell_f: their cells) re-expressed on the coarse level, so the
// level solves for an increment.
Status RestrictConstraints(Context& ctx, const DeviceLattice& fl, const DeviceActiveSet& fine, const DeviceLattice& cl,
                           const DeviceActiveSet& coarse, int s, size_t n, const Buffer<VdCorrespondence>& cons_f,
                           const Buffer<int32_t>& cell_f, const Buffer<vd_float4>& x_f, const Buffer<vd_float4>& x0_c,
                           Buffer<VdCorrespondence>& cons_c);
// The coarse cells' moments (spacing s) from the fine level's constraints sorted by cell, their
// right-hand sides from the residuals under the fine state x_f.
Status LevelMoments(Context& ctx, const DeviceLattice& fl, const DeviceActiveSet& fine, const DeviceLattice& cl,
                    const DeviceActiveSet& coarse, int s, const Buffer<VdCorrespondence>& cons,
                    const Buffer<uint32_t>& cell_start, const Buffer<vd_float4>& x_f, Buffer<float>& moments_c);
// The moments of level cl from those of the level fl below it (cl = fl.Level(2)): the same sums as
// LevelMoments from the constraints under the same fine state, without walking them again.
Status LevelMomentsUp(Context& ctx, const DeviceLattice& fl, const DeviceActiveSet& fine, const DeviceLattice& cl,
                      const DeviceActiveSet& coarse, const Buffer<float>& moments_f, Buffer<float>& moments_c);
// Adds the coarse increment x_c - x0_c, interpolated, to the fine active points' x_f.
Status ProlongateIncrement(Context& ctx, const DeviceLattice& fl, const DeviceActiveSet& fine, const DeviceLattice& cl,
                           const DeviceActiveSet& coarse, int s, const Buffer<vd_float4>& x_c,
                           const Buffer<vd_float4>& x0_c, Buffer<vd_float4>& x_f);

}  // namespace vd::ocl
