#pragma once
// The kernels of kernels/hierarchy.cl, per-item math in shared/hierarchy.h. One typed handle
// each (ocl/kernel.h), its parameters those of the __kernel in order; kFoo(ctx, items, args...)
// runs it over `items` work items (what one item is, above each).
#include <cstdint>

#include "ocl/kernel.h"
#include "shared/hierarchy.h"

namespace vd::ocl {

// One item per fine active point.
inline constexpr Kernel<void(const Buffer<int32_t>& list_f, VdVolume fine, int s, VdVolume coarse,
                             Buffer<uint8_t>& member)> kLevelMark{"vd_level_mark"};
// One item per coarse grid row.
inline constexpr Kernel<void(const Buffer<uint8_t>& member, VdVolume coarse,
                             Buffer<uint32_t>& row_count)> kLevelRowCount{"vd_level_row_count"};
// One item per coarse active point.
inline constexpr Kernel<void(const Buffer<int32_t>& list_c, VdVolume coarse, int s, const Buffer<int32_t>& compact_f,
                             VdVolume fine, const Buffer<vd_float4>& x_f, const Buffer<vd_float4>& rot_f,
                             Buffer<vd_float4>& x0_c, Buffer<vd_float4>& rot_c)> kLevelRestrict{"vd_level_restrict_kernel"};
// One item per fine constraint.
inline constexpr Kernel<void(const Buffer<VdCorrespondence>& cons_f, const Buffer<int32_t>& compact_f, VdVolume fine,
                             const Buffer<vd_float4>& x_f, int s, const Buffer<int32_t>& compact_c, VdVolume coarse,
                             const Buffer<vd_float4>& x0_c,
                             Buffer<VdCorrespondence>& cons_c)> kLevelConstraints{"vd_level_constraints"};
// One item per fine active point; adds to x_f.
inline constexpr Kernel<void(const Buffer<int32_t>& list_f, VdVolume fine, int s, const Buffer<int32_t>& compact_c,
                             VdVolume coarse, const Buffer<vd_float4>& x_c, const Buffer<vd_float4>& x0_c,
                             Buffer<vd_float4>& x_f)> kLevelProlongate{"vd_level_prolongate_kernel"};
// One item per coarse active point, as the first corner of a cell.
inline constexpr Kernel<void(const Buffer<int32_t>& list_c, VdVolume coarse, int s, const Buffer<int32_t>& compact_f,
                             VdVolume fine, const Buffer<VdCorrespondence>& cons, const Buffer<uint32_t>& cell_start,
                             const Buffer<vd_float4>& x_f, Buffer<float>& moments_c)>
    kLevelMoments{"vd_level_moments_kernel"};

// Launchers of HierarchicalSolver (core/hierarchy.cpp), which orders them coarse to fine.

// Flags the coarse grid points whose cells hold one of the n fine active points.
Status MarkLevel(Context& ctx, size_t n, const Buffer<int32_t>& list_f, VdVolume fine, int s, VdVolume coarse,
                 Buffer<uint8_t>& member);
// Members per coarse grid row, for the scan that places each row's members in the list.
Status CountLevelRows(Context& ctx, const Buffer<uint8_t>& member, VdVolume coarse, Buffer<uint32_t>& row_count);
// The n coarse points' starting positions x0_c and rotations rot_c from the fine state.
Status RestrictState(Context& ctx, size_t n, const Buffer<int32_t>& list_c, VdVolume coarse, int s,
                     const Buffer<int32_t>& compact_f, VdVolume fine, const Buffer<vd_float4>& x_f,
                     const Buffer<vd_float4>& rot_f, Buffer<vd_float4>& x0_c, Buffer<vd_float4>& rot_c);
// The n fine constraints re-expressed on the coarse grid, so the level solves for an increment.
Status RestrictConstraints(Context& ctx, size_t n, const Buffer<VdCorrespondence>& cons_f,
                           const Buffer<int32_t>& compact_f, VdVolume fine, const Buffer<vd_float4>& x_f, int s,
                           const Buffer<int32_t>& compact_c, VdVolume coarse, const Buffer<vd_float4>& x0_c,
                           Buffer<VdCorrespondence>& cons_c);
// The n coarse cells' moments (spacing s) from the fine level's constraints sorted by cell,
// their right-hand sides from the residuals under the fine state x_f.
Status LevelMoments(Context& ctx, size_t n, const Buffer<int32_t>& list_c, VdVolume coarse, int s,
                    const Buffer<int32_t>& compact_f, VdVolume fine, const Buffer<VdCorrespondence>& cons,
                    const Buffer<uint32_t>& cell_start, const Buffer<vd_float4>& x_f, Buffer<float>& moments_c);
// Adds the coarse increment x_c - x0_c, interpolated, to the n fine active points' x_f.
Status ProlongateIncrement(Context& ctx, size_t n, const Buffer<int32_t>& list_f, VdVolume fine, int s,
                           const Buffer<int32_t>& compact_c, VdVolume coarse, const Buffer<vd_float4>& x_c,
                           const Buffer<vd_float4>& x0_c, Buffer<vd_float4>& x_f);

}  // namespace vd::ocl
