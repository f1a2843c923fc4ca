#pragma once
// The kernels of kernels/solver.cl, per-item math in shared/solver.h. One typed handle
// each (ocl/kernel.h), its parameters those of the __kernel in order; kFoo(ctx, items, args...)
// runs it over `items` work items (what one item is, above each).
#include <cstdint>

#include "ocl/device_ops.h"
#include "ocl/kernel.h"
#include "shared/solver.h"

namespace vd::ocl {

// The active set on its lattice, the kernels' VD_ACTIVE_ARGS (kernels/solver.cl) in order.
#define VD_ACTIVE_PARAMS                                                                                      \
  VdLattice lat, const Buffer<int32_t>&lat_nbr, const Buffer<uint32_t>&slot_keys, const Buffer<int32_t>&list, \
      const Buffer<int32_t>&compact

// One item per active point, as for every solver kernel unless said otherwise.
inline constexpr Kernel<void(const Buffer<int32_t>& list, const Buffer<vd_float4>& def_pos,
                             const Buffer<vd_float4>& def_rot, Buffer<vd_float4>& x,
                             Buffer<vd_float4>& rot)> kSolverGatherState{"vd_solver_gather_state"};
inline constexpr Kernel<void(const Buffer<int32_t>& list, const Buffer<vd_float4>& x, const Buffer<vd_float4>& rot,
                             Buffer<vd_float4>& def_pos,
                             Buffer<vd_float4>& def_rot)> kSolverScatterState{"vd_solver_scatter_state"};
inline constexpr Kernel<void(const Buffer<int32_t>& list, Buffer<vd_float4>& def_pos)> kSolverCountState{
    "vd_solver_count_state"};
// One item per per-pixel constraint.
inline constexpr Kernel<void(const Buffer<VdCorrespondence>& corr, const Buffer<int32_t>& compact, VdVolume vol,
                             Buffer<int32_t>& cell_of,
                             Buffer<uint32_t>& counts)> kConstraintCount{"vd_constraint_count"};
// One item per per-pixel constraint.
inline constexpr Kernel<void(const Buffer<int32_t>& cell_of, const Buffer<uint32_t>& cell_start,
                             Buffer<uint32_t>& cursor, Buffer<int32_t>& order)>
    kConstraintScatter{"vd_constraint_scatter"};
// One item per cell.
inline constexpr Kernel<void(const Buffer<VdCorrespondence>& corr, const Buffer<uint32_t>& cell_start,
                             Buffer<int32_t>& order, Buffer<VdCorrespondence>& sorted, Buffer<int32_t>& sorted_cell)>
    kConstraintOrder{"vd_constraint_order"};
// One item per sorted constraint.
inline constexpr Kernel<void(const Buffer<VdCorrespondence>& cons,
                             Buffer<float>& targets)> kConstraintTargets{"vd_constraint_targets"};
// One item per sorted constraint.
inline constexpr Kernel<void(const Buffer<VdCorrespondence>& cons, const Buffer<int32_t>& sorted_cell, VD_ACTIVE_PARAMS,
                             const Buffer<vd_float4>& d, Buffer<float>& r)>
    kConstraintResiduals{"vd_constraint_residuals"};
inline constexpr Kernel<void(VD_ACTIVE_PARAMS, const Buffer<int32_t>& neighbours, const Buffer<float>& edge_w,
                             const Buffer<VdCorrespondence>& cons, const Buffer<uint32_t>& cell_start,
                             const Buffer<float>& targets, VdSolverWeights w, Buffer<vd_float4>& data_rhs,
                             Buffer<VdMat3>& diag_inv)>
    kSystemDataDiag{"vd_system_data_diag_kernel"};
inline constexpr Kernel<void(float spacing, const Buffer<int32_t>& neighbours, const Buffer<float>& edge_w,
                             const Buffer<vd_float4>& rot, const Buffer<vd_float4>& data_rhs,
                             const Buffer<vd_float4>& x_prev, VdSolverWeights w, Buffer<vd_float4>& b)>
    kSystemRhs{"vd_system_rhs_kernel"};
inline constexpr Kernel<void(VD_ACTIVE_PARAMS, const Buffer<int32_t>& neighbours, const Buffer<float>& edge_w,
                             const Buffer<VdCorrespondence>& cons, const Buffer<uint32_t>& cell_start,
                             const Buffer<float>& r, const Buffer<vd_float4>& d, VdSolverWeights w,
                             Buffer<vd_float4>& q)>
    kSystemApply{"vd_system_apply_kernel"};
// One item per active point, the first corner of its cell.
inline constexpr Kernel<void(VD_ACTIVE_PARAMS, const Buffer<VdCorrespondence>& cons, const Buffer<uint32_t>& cell_start,
                             Buffer<float>& moments)>
    kCellMoments{"vd_cell_moments_kernel"};
// x0 is read only when shift is 1.
inline constexpr Kernel<void(VD_ACTIVE_PARAMS, const Buffer<int32_t>& neighbours, const Buffer<float>& edge_w,
                             const Buffer<float>& moments, VdSolverWeights w, const Buffer<vd_float4>& x0, int shift,
                             Buffer<float>& blocks, Buffer<int32_t>& nbr, Buffer<vd_float4>& data_rhs,
                             Buffer<VdMat3>& diag_inv)>
    kBtbAssemble{"vd_btb_assemble_kernel"};
inline constexpr Kernel<void(const Buffer<float>& blocks, const Buffer<int32_t>& nbr, const Buffer<vd_float4>& d,
                             Buffer<vd_float4>& q)>
    kSystemApplyCached{"vd_system_apply_cached_kernel"};
inline constexpr Kernel<void(const Buffer<VdMat3>& diag_inv, const Buffer<vd_float4>& r,
                             Buffer<vd_float4>& z)> kPcgPrecondition{"vd_pcg_precondition"};
// y = a x + y (xyz).
inline constexpr Kernel<void(float a, const Buffer<vd_float4>& x, Buffer<vd_float4>& y)> kAxpy4{"vd_axpy4"};
// y = b - y (xyz).
inline constexpr Kernel<void(const Buffer<vd_float4>& b, Buffer<vd_float4>& y)> kSubFrom4{"vd_sub_from4"};
// One item per chunk of `chunk` points.
inline constexpr Kernel<void(const Buffer<vd_float4>& a, const Buffer<vd_float4>& b, int n, int chunk,
                             Buffer<float>& partials)>
    kDot4Partial{"vd_dot4_partial"};
// One item.
inline constexpr Kernel<void(const Buffer<float>& partials, int groups, int mode, float tolerance,
                             Buffer<float>& scal)> kPcgScalars{"vd_pcg_scalars_kernel"};
// Work-groups of VD_PCG_GROUP points, one triple of partial sums (r.u, w.u, r.r) each.
inline constexpr Kernel<void(const Buffer<float>& scal, const Buffer<float>& blocks, const Buffer<int32_t>& nbr,
                             const Buffer<vd_float4>& r, const Buffer<vd_float4>& u, Buffer<vd_float4>& w,
                             Buffer<float>& partials)>
    kPcgApplyDots{"vd_pcg_apply_dots_kernel"};
inline constexpr Kernel<void(const Buffer<vd_float4>& r, const Buffer<vd_float4>& u, const Buffer<vd_float4>& w,
                             Buffer<float>& partials)>
    kPcgDots{"vd_pcg_dots_kernel"};
// Work-groups of VD_PCG_GROUP points, one partial sum of b.b each.
inline constexpr Kernel<void(float spacing, const Buffer<int32_t>& neighbours, const Buffer<float>& edge_w,
                             const Buffer<vd_float4>& rot, const Buffer<vd_float4>& data_rhs, VdSolverWeights w,
                             const Buffer<float>& blocks, const Buffer<int32_t>& nbr, const Buffer<VdMat3>& diag_inv,
                             const Buffer<vd_float4>& x, Buffer<vd_float4>& r, Buffer<vd_float4>& u,
                             Buffer<float>& partials)>
    kPcgStart{"vd_pcg_start_kernel"};
// Work-groups of VD_PCG_GROUP points, one partial sum of the new r.r each.
inline constexpr Kernel<void(const Buffer<float>& scal, const Buffer<VdMat3>& diag_inv, const Buffer<vd_float4>& w,
                             Buffer<vd_float4>& p, Buffer<vd_float4>& s, Buffer<vd_float4>& x, Buffer<vd_float4>& r,
                             Buffer<vd_float4>& u, Buffer<float>& partials)>
    kPcgCgUpdate{"vd_pcg_cg_update_kernel"};
// One item per chunk of `chunk` constraints.
inline constexpr Kernel<void(const Buffer<VdCorrespondence>& cons, const Buffer<int32_t>& sorted_cell, int n, int chunk,
                             VD_ACTIVE_PARAMS, const Buffer<vd_float4>& x, Buffer<float>& partials)>
    kEnergyDensePartial{"vd_energy_dense_partial"};
// One item per chunk of `chunk` points.
inline constexpr Kernel<void(const Buffer<int32_t>& neighbours, const Buffer<float>& edge_w, float spacing,
                             const Buffer<vd_float4>& x, const Buffer<vd_float4>& rot, int n, int chunk,
                             Buffer<float>& partials)>
    kEnergyArapPartial{"vd_energy_arap_partial"};
inline constexpr Kernel<void(VD_ACTIVE_PARAMS, Buffer<vd_float4>& t_hat)> kSolverRest{"vd_solver_rest"};
// One item per active point: its six ARAP edge weights.
inline constexpr Kernel<void(const Buffer<int32_t>& neighbours, const Buffer<vd_float4>& x,
                             const Buffer<vd_float4>& rot, const Buffer<vd_float4>& t_hat, float scale2, float floor_w,
                             Buffer<float>& edge_w)>
    kArapEdgeWeights{"vd_arap_edge_weights_kernel"};

// Launchers of DeviceSolver (core/solver.cpp), one per step it takes on the device; `m` active
// points (the items of the per-point kernels above), `n` constraints or elements where said.

// The compact state (x, rot) of the active points from the grid's field: the solve starts there.
Status GatherState(Context& ctx, size_t m, const Buffer<int32_t>& list, const Buffer<vd_float4>& def_pos,
                   const Buffer<vd_float4>& def_rot, Buffer<vd_float4>& x, Buffer<vd_float4>& rot);
// The solved state back into the grid's field (counting the optimisation).
Status ScatterState(Context& ctx, size_t m, const Buffer<int32_t>& list, const Buffer<vd_float4>& x,
                    const Buffer<vd_float4>& rot, Buffer<vd_float4>& def_pos, Buffer<vd_float4>& def_rot);
// An unsolved frame of a static field counted as an optimisation of the m listed points (shared/
// solver.h vd_count_optimisation): their state stays, their count grows by one.
Status CountOptimisation(Context& ctx, size_t m, const Buffer<int32_t>& list, Buffer<vd_float4>& def_pos);
// The rest positions t_hat of the ARAP prior: the active points' lattice positions.
Status RestPositions(Context& ctx, const DeviceLattice& L, const DeviceActiveSet& a, Buffer<vd_float4>& t_hat);
// First half of the counting sort of the n per-pixel constraints by cell (so that A applies
// per point without atomics): each constraint's cell and the per-cell counts (on bricks through
// the table's hash, BrickTable's CountConstraints).
Status CountConstraints(Context& ctx, size_t n, const Buffer<VdCorrespondence>& corr, const DeviceLattice& L,
                        const DeviceActiveSet& a, Buffer<int32_t>& cell_of, Buffer<uint32_t>& counts);
// Second half, after the counts' scan of the m cells into cell_start (m + 1 entries, the last the
// total): the constraints in cell order, and each one's cell (the compact index of its first
// corner). Within a cell they keep their input order, as a sequential counting sort would (and
// cpu::SortConstraints does), so runs repeat exactly. cursor: m zeros; order: scratch, one per
// sorted constraint.
Status SortConstraints(Context& ctx, size_t n, size_t m, const Buffer<VdCorrespondence>& corr,
                       const Buffer<int32_t>& cell_of, const Buffer<uint32_t>& cell_start, Buffer<uint32_t>& cursor,
                       Buffer<int32_t>& order, Buffer<VdCorrespondence>& sorted, Buffer<int32_t>& sorted_cell);
// Each sorted constraint's target term, fixed per solve.
Status ConstraintTargets(Context& ctx, size_t n, const Buffer<VdCorrespondence>& cons, Buffer<float>& targets);
// The constraint-only part of b and the Jacobi preconditioner, fixed per solve.
Status DataRhsAndDiagonal(Context& ctx, const DeviceLattice& L, const DeviceActiveSet& a, const Buffer<float>& edge_w,
                          const Buffer<VdCorrespondence>& cons, const Buffer<uint32_t>& cell_start,
                          const Buffer<float>& targets, VdSolverWeights w, Buffer<vd_float4>& data_rhs,
                          Buffer<VdMat3>& diag_inv);
// b of the position step from the current rotations and the previous positions (m points of a
// lattice with that spacing).
Status SystemRhs(Context& ctx, size_t m, float spacing, const Buffer<int32_t>& neighbours, const Buffer<float>& edge_w,
                 const Buffer<vd_float4>& rot, const Buffer<vd_float4>& data_rhs, const Buffer<vd_float4>& x_prev,
                 VdSolverWeights w, Buffer<vd_float4>& b);
// B d for the n sorted constraints: the first half of A d when B^T B is not cached.
Status ConstraintResiduals(Context& ctx, size_t n, const Buffer<VdCorrespondence>& cons,
                           const Buffer<int32_t>& sorted_cell, const DeviceLattice& L, const DeviceActiveSet& a,
                           const Buffer<vd_float4>& d, Buffer<float>& r);
// q = A d from those residuals, summed per point over its cell's constraints.
Status ApplySystem(Context& ctx, const DeviceLattice& L, const DeviceActiveSet& a, const Buffer<float>& edge_w,
                   const Buffer<VdCorrespondence>& cons, const Buffer<uint32_t>& cell_start, const Buffer<float>& r,
                   const Buffer<vd_float4>& d, VdSolverWeights w, Buffer<vd_float4>& q);
// The system matrix as 27 3x3 blocks per point (w_d B^T B with the ARAP Laplacian and the
// damping folded in), built once per solve so each PCG iteration skips the constraints, with the
// data part of b and the Jacobi preconditioner (DataRhsAndDiagonal's outputs): the cells' moments
// (VD_CELL_MOMENT_FLOATS per active point, scratch), then the points.
Status BuildBtb(Context& ctx, const DeviceLattice& L, const DeviceActiveSet& a, const Buffer<float>& edge_w,
                const Buffer<VdCorrespondence>& cons, const Buffer<uint32_t>& cell_start, VdSolverWeights w,
                Buffer<float>& moments, Buffer<float>& blocks, Buffer<int32_t>& nbr, Buffer<vd_float4>& data_rhs,
                Buffer<VdMat3>& diag_inv);
// The same from moments already in place (a coarse level's, vd_level_moments), its right-hand
// side shifted by (w_d B^T B x0)_k for the level's start x0.
Status AssembleBtb(Context& ctx, const DeviceLattice& L, const DeviceActiveSet& a, const Buffer<float>& edge_w,
                   const Buffer<float>& moments, VdSolverWeights w, const Buffer<vd_float4>& x0, Buffer<float>& blocks,
                   Buffer<int32_t>& nbr, Buffer<vd_float4>& data_rhs, Buffer<VdMat3>& diag_inv);
// q = A d from the blocks of BuildBtb (the whole matrix: ARAP and damping are in the blocks).
Status ApplySystemCached(Context& ctx, size_t m, const Buffer<float>& blocks, const Buffer<int32_t>& nbr,
                         const Buffer<vd_float4>& d, Buffer<vd_float4>& q);
// The PCG steps over n points; z = M^-1 r with the Jacobi blocks of DataRhsAndDiagonal.
Status Precondition(Context& ctx, size_t n, const Buffer<VdMat3>& diag_inv, const Buffer<vd_float4>& r,
                    Buffer<vd_float4>& z);
// y = a x + y.
Status Axpy(Context& ctx, size_t n, float a, const Buffer<vd_float4>& x, Buffer<vd_float4>& y);
// y = b - y (the initial residual from A x).
Status SubFrom(Context& ctx, size_t n, const Buffer<vd_float4>& b, Buffer<vd_float4>& y);
// a . b over n points as partial sums over `groups` chunks of `chunk` (summed on the host, in double).
Status DotPartials(Context& ctx, size_t groups, const Buffer<vd_float4>& a, const Buffer<vd_float4>& b, int n,
                   int chunk, Buffer<float>& partials);
// The PCG scalars (shared/solver.h VD_PCG_*) from `groups` partial sums (triples for START and
// NEXT), on the device: mode is one of VD_PCG_SET_*.
Status PcgScalars(Context& ctx, const Buffer<float>& partials, int groups, int mode, float tolerance,
                  Buffer<float>& scal);
// w = A u over m points from the cached blocks, with the triples (r.u, w.u, r.r) of each
// work-group of VD_PCG_GROUP points in partials (PcgGroups(m) of them); nothing once scal says
// the PCG converged (vd_pcg_done).
Status PcgApplyDots(Context& ctx, size_t m, const Buffer<float>& scal, const Buffer<float>& blocks,
                    const Buffer<int32_t>& nbr, const Buffer<vd_float4>& r, const Buffer<vd_float4>& u,
                    Buffer<vd_float4>& w, Buffer<float>& partials);
// The same triples for a w = A u computed before.
Status PcgDots(Context& ctx, size_t m, const Buffer<vd_float4>& r, const Buffer<vd_float4>& u,
               const Buffer<vd_float4>& w, Buffer<float>& partials);
// r = b - A x and u = M^-1 r over m points from the cached blocks, b as SystemRhs with x as the
// damping's anchor, with the partial sums of b.b per work-group (PcgGroups(m) of them).
Status PcgStart(Context& ctx, size_t m, float spacing, const Buffer<int32_t>& neighbours, const Buffer<float>& edge_w,
                const Buffer<vd_float4>& rot, const Buffer<vd_float4>& data_rhs, VdSolverWeights w,
                const Buffer<float>& blocks, const Buffer<int32_t>& nbr, const Buffer<VdMat3>& diag_inv,
                const Buffer<vd_float4>& x, Buffer<vd_float4>& r, Buffer<vd_float4>& u, Buffer<float>& partials);
// Partial-sum triples of PcgApplyDots and PcgDots for m points.
inline size_t PcgGroups(size_t m) { return (m + VD_PCG_GROUP - 1) / VD_PCG_GROUP; }
// p = u + beta p, s = w + beta s, x += alpha p, r -= alpha s, u = M^-1 r over m points, alpha and
// beta from scal, with the partial sums of the new r.r per work-group (PcgGroups(m) of them);
// nothing once scal says the PCG converged.
Status PcgCgUpdate(Context& ctx, size_t m, const Buffer<float>& scal, const Buffer<VdMat3>& diag_inv,
                   const Buffer<vd_float4>& w, Buffer<vd_float4>& p, Buffer<vd_float4>& s, Buffer<vd_float4>& x,
                   Buffer<vd_float4>& r, Buffer<vd_float4>& u, Buffer<float>& partials);
// E_dense over n sorted constraints, partial sums as for DotPartials.
Status DenseEnergyPartials(Context& ctx, size_t groups, const Buffer<VdCorrespondence>& cons,
                           const Buffer<int32_t>& sorted_cell, int n, int chunk, const DeviceLattice& L,
                           const DeviceActiveSet& a, const Buffer<vd_float4>& x, Buffer<float>& partials);
// Adaptive rigidity: the ARAP weights of the m points' edges from the field (x, rot) against the
// rest positions t_hat (shared/solver.h vd_arap_edge_weights).
Status ArapEdgeWeights(Context& ctx, size_t m, const Buffer<int32_t>& neighbours, const Buffer<vd_float4>& x,
                       const Buffer<vd_float4>& rot, const Buffer<vd_float4>& t_hat, float scale2, float floor_w,
                       Buffer<float>& edge_w);
// E_reg over n active points, partial sums as for DotPartials.
Status ArapEnergyPartials(Context& ctx, size_t groups, const Buffer<int32_t>& neighbours, const Buffer<float>& edge_w,
                          float spacing, const Buffer<vd_float4>& x, const Buffer<vd_float4>& rot, int n, int chunk,
                          Buffer<float>& partials);

}  // namespace vd::ocl
