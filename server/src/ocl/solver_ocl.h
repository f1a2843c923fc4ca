#pragma once
// The kernels of kernels/solver.cl, per-item math in shared/solver.h. One typed handle
// each (ocl/kernel.h), its parameters those of the __kernel in order; kFoo(ctx, items, args...)
// runs it over `items` work items (what one item is, above each).
#include <cstdint>

#include "ocl/kernel.h"
#include "shared/solver.h"

namespace vd::ocl {

// One item per active point, as for every solver kernel unless said otherwise.
inline constexpr Kernel<void(const Buffer<int32_t>& list, const Buffer<vd_float4>& def_pos,
                             const Buffer<vd_float4>& def_rot, Buffer<vd_float4>& x,
                             Buffer<vd_float4>& rot)> kSolverGatherState{"vd_solver_gather_state"};
inline constexpr Kernel<void(const Buffer<int32_t>& list, const Buffer<vd_float4>& x, const Buffer<vd_float4>& rot,
                             Buffer<vd_float4>& def_pos,
                             Buffer<vd_float4>& def_rot)> kSolverScatterState{"vd_solver_scatter_state"};
// One item per per-pixel constraint.
inline constexpr Kernel<void(const Buffer<VdCorrespondence>& corr, const Buffer<int32_t>& compact, VdVolume vol,
                             Buffer<int32_t>& cell_of,
                             Buffer<uint32_t>& counts)> kConstraintCount{"vd_constraint_count"};
// One item per per-pixel constraint.
inline constexpr Kernel<void(const Buffer<VdCorrespondence>& corr, const Buffer<int32_t>& cell_of,
                             const Buffer<uint32_t>& cell_start, Buffer<uint32_t>& cursor,
                             Buffer<VdCorrespondence>& sorted)> kConstraintScatter{"vd_constraint_scatter"};
// One item per sorted constraint.
inline constexpr Kernel<void(const Buffer<VdCorrespondence>& cons,
                             Buffer<float>& targets)> kConstraintTargets{"vd_constraint_targets"};
// One item per sorted constraint.
inline constexpr Kernel<void(const Buffer<VdCorrespondence>& cons, const Buffer<int32_t>& compact, VdVolume vol,
                             const Buffer<vd_float4>& d,
                             Buffer<float>& r)> kConstraintResiduals{"vd_constraint_residuals"};
inline constexpr Kernel<void(const Buffer<int32_t>& list, const Buffer<int32_t>& compact, VdVolume vol,
                             const Buffer<int32_t>& neighbours, const Buffer<VdCorrespondence>& cons,
                             const Buffer<uint32_t>& cell_start, const Buffer<float>& targets, VdSolverWeights w,
                             Buffer<vd_float4>& data_rhs,
                             Buffer<VdMat3>& diag_inv)> kSystemDataDiag{"vd_system_data_diag_kernel"};
inline constexpr Kernel<void(const Buffer<int32_t>& list, VdVolume vol, const Buffer<int32_t>& neighbours,
                             const Buffer<vd_float4>& rot, const Buffer<vd_float4>& data_rhs,
                             const Buffer<vd_float4>& x_prev, VdSolverWeights w,
                             Buffer<vd_float4>& b)> kSystemRhs{"vd_system_rhs_kernel"};
inline constexpr Kernel<void(const Buffer<int32_t>& list, const Buffer<int32_t>& compact, VdVolume vol,
                             const Buffer<int32_t>& neighbours, const Buffer<VdCorrespondence>& cons,
                             const Buffer<uint32_t>& cell_start, const Buffer<float>& r, const Buffer<vd_float4>& d,
                             VdSolverWeights w, Buffer<vd_float4>& q)> kSystemApply{"vd_system_apply_kernel"};
inline constexpr Kernel<void(const Buffer<int32_t>& list, const Buffer<int32_t>& compact, VdVolume vol,
                             const Buffer<VdCorrespondence>& cons, const Buffer<uint32_t>& cell_start,
                             VdSolverWeights w, Buffer<float>& blocks,
                             Buffer<int32_t>& nbr)> kBtbBuild{"vd_btb_build_kernel"};
inline constexpr Kernel<void(const Buffer<int32_t>& neighbours, const Buffer<float>& blocks, const Buffer<int32_t>& nbr,
                             const Buffer<vd_float4>& d, VdSolverWeights w,
                             Buffer<vd_float4>& q)> kSystemApplyCached{"vd_system_apply_cached_kernel"};
inline constexpr Kernel<void(const Buffer<VdMat3>& diag_inv, const Buffer<vd_float4>& r,
                             Buffer<vd_float4>& z)> kPcgPrecondition{"vd_pcg_precondition"};
// y = a x + y (xyz).
inline constexpr Kernel<void(float a, const Buffer<vd_float4>& x, Buffer<vd_float4>& y)> kAxpy4{"vd_axpy4"};
// y = x + a y (xyz).
inline constexpr Kernel<void(float a, const Buffer<vd_float4>& x, Buffer<vd_float4>& y)> kXpay4{"vd_xpay4"};
// y = b - y (xyz).
inline constexpr Kernel<void(const Buffer<vd_float4>& b, Buffer<vd_float4>& y)> kSubFrom4{"vd_sub_from4"};
// One item per chunk of `chunk` points.
inline constexpr Kernel<void(const Buffer<vd_float4>& a, const Buffer<vd_float4>& b, int n, int chunk,
                             Buffer<float>& partials)> kDot4Partial{"vd_dot4_partial"};
// One item per chunk of `chunk` constraints.
inline constexpr Kernel<void(const Buffer<VdCorrespondence>& cons, int n, int chunk, const Buffer<int32_t>& compact,
                             VdVolume vol, const Buffer<vd_float4>& x,
                             Buffer<float>& partials)> kEnergyDensePartial{"vd_energy_dense_partial"};
// One item per chunk of `chunk` points.
inline constexpr Kernel<void(const Buffer<int32_t>& list, const Buffer<int32_t>& neighbours, VdVolume vol,
                             const Buffer<vd_float4>& x, const Buffer<vd_float4>& rot, int n, int chunk,
                             Buffer<float>& partials)> kEnergyArapPartial{"vd_energy_arap_partial"};
inline constexpr Kernel<void(const Buffer<int32_t>& list, VdVolume vol,
                             Buffer<vd_float4>& t_hat)> kSolverRest{"vd_solver_rest"};

}  // namespace vd::ocl
