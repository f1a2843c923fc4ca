// The launchers of kernels/solver.cl that DeviceSolver (core/solver.cpp) calls.
#include "ocl/solver_ocl.h"

#include "ocl/brick_hash_ocl.h"

namespace vd::ocl {

Status GatherState(Context& ctx, size_t m, const Buffer<int32_t>& list, const Buffer<vd_float4>& def_pos,
                   const Buffer<vd_float4>& def_rot, Buffer<vd_float4>& x, Buffer<vd_float4>& rot) {
  return kSolverGatherState(ctx, m, list, def_pos, def_rot, x, rot);
}

Status ScatterState(Context& ctx, size_t m, const Buffer<int32_t>& list, const Buffer<vd_float4>& x,
                    const Buffer<vd_float4>& rot, Buffer<vd_float4>& def_pos, Buffer<vd_float4>& def_rot) {
  return kSolverScatterState(ctx, m, list, x, rot, def_pos, def_rot);
}

Status CountOptimisation(Context& ctx, size_t m, const Buffer<int32_t>& list, Buffer<vd_float4>& def_pos) {
  return kSolverCountState(ctx, m, list, def_pos);
}

// The five VD_ACTIVE_PARAMS of lattice L and active set a.
#define VD_ACTIVE_OF(L, a) (L).lat, *(L).nbr, *(L).slot_keys, (a).list, (a).compact

Status RestPositions(Context& ctx, const DeviceLattice& L, const DeviceActiveSet& a, Buffer<vd_float4>& t_hat) {
  return kSolverRest(ctx, a.count, VD_ACTIVE_OF(L, a), t_hat);
}

Status CountConstraints(Context& ctx, size_t n, const Buffer<VdCorrespondence>& corr, const DeviceLattice& L,
                        const DeviceActiveSet& a, Buffer<int32_t>& cell_of, Buffer<uint32_t>& counts) {
  if (!L.lat.bricks) {
    VdVolume vol{};
    vol.origin = L.lat.origin;
    vol.dim_x = L.lat.dim_x;
    vol.dim_y = L.lat.dim_y;
    vol.dim_z = L.lat.dim_z;
    vol.voxel_size = L.lat.spacing;
    return kConstraintCount(ctx, n, corr, a.compact, vol, cell_of, counts);
  }
  // The hash names bricks of VD_BRICK points a side: the fine level's. Coarse levels on bricks take
  // their systems from the fine constraints (SolverParams::cache_btb_coarse), never their own.
  if (L.lat.dim_x != VD_BRICK || !L.table)
    return Unimplemented("constraints of a coarse level on bricks (use the cached coarse systems)");
  return CountConstraints(ctx, n, corr, *L.table, a.compact, cell_of, counts);
}

Status SortConstraints(Context& ctx, size_t n, size_t m, const Buffer<VdCorrespondence>& corr,
                       const Buffer<int32_t>& cell_of, const Buffer<uint32_t>& cell_start, Buffer<uint32_t>& cursor,
                       Buffer<int32_t>& order, Buffer<VdCorrespondence>& sorted, Buffer<int32_t>& sorted_cell) {
  if (m == 0) return Status::Ok();
  VD_RETURN_IF_ERROR(kConstraintScatter(ctx, n, cell_of, cell_start, cursor, order));
  return kConstraintOrder(ctx, m, corr, cell_start, order, sorted, sorted_cell);
}

Status ConstraintTargets(Context& ctx, size_t n, const Buffer<VdCorrespondence>& cons, Buffer<float>& targets) {
  return kConstraintTargets(ctx, n, cons, targets);
}

Status DataRhsAndDiagonal(Context& ctx, const DeviceLattice& L, const DeviceActiveSet& a, const Buffer<float>& edge_w,
                          const Buffer<VdCorrespondence>& cons, const Buffer<uint32_t>& cell_start,
                          const Buffer<float>& targets, VdSolverWeights w, Buffer<vd_float4>& data_rhs,
                          Buffer<VdMat3>& diag_inv) {
  return kSystemDataDiag(ctx, a.count, VD_ACTIVE_OF(L, a), a.neighbours, edge_w, cons, cell_start, targets, w, data_rhs,
                         diag_inv);
}

Status SystemRhs(Context& ctx, size_t m, float spacing, const Buffer<int32_t>& neighbours, const Buffer<float>& edge_w,
                 const Buffer<vd_float4>& rot, const Buffer<vd_float4>& data_rhs, const Buffer<vd_float4>& x_prev,
                 VdSolverWeights w, Buffer<vd_float4>& b) {
  return kSystemRhs(ctx, m, spacing, neighbours, edge_w, rot, data_rhs, x_prev, w, b);
}

Status ConstraintResiduals(Context& ctx, size_t n, const Buffer<VdCorrespondence>& cons,
                           const Buffer<int32_t>& sorted_cell, const DeviceLattice& L, const DeviceActiveSet& a,
                           const Buffer<vd_float4>& d, Buffer<float>& r) {
  return kConstraintResiduals(ctx, n, cons, sorted_cell, VD_ACTIVE_OF(L, a), d, r);
}

Status ApplySystem(Context& ctx, const DeviceLattice& L, const DeviceActiveSet& a, const Buffer<float>& edge_w,
                   const Buffer<VdCorrespondence>& cons, const Buffer<uint32_t>& cell_start, const Buffer<float>& r,
                   const Buffer<vd_float4>& d, VdSolverWeights w, Buffer<vd_float4>& q) {
  return kSystemApply(ctx, a.count, VD_ACTIVE_OF(L, a), a.neighbours, edge_w, cons, cell_start, r, d, w, q);
}

Status BuildBtb(Context& ctx, const DeviceLattice& L, const DeviceActiveSet& a, const Buffer<float>& edge_w,
                const Buffer<VdCorrespondence>& cons, const Buffer<uint32_t>& cell_start, VdSolverWeights w,
                Buffer<float>& moments, Buffer<float>& blocks, Buffer<int32_t>& nbr, Buffer<vd_float4>& data_rhs,
                Buffer<VdMat3>& diag_inv) {
  VD_RETURN_IF_ERROR(kCellMoments(ctx, a.count, VD_ACTIVE_OF(L, a), cons, cell_start, moments));
  // No shift: x0 is not read (any buffer serves).
  return kBtbAssemble(ctx, a.count, VD_ACTIVE_OF(L, a), a.neighbours, edge_w, moments, w, data_rhs, 0, blocks, nbr,
                      data_rhs, diag_inv);
}

Status AssembleBtb(Context& ctx, const DeviceLattice& L, const DeviceActiveSet& a, const Buffer<float>& edge_w,
                   const Buffer<float>& moments, VdSolverWeights w, const Buffer<vd_float4>& x0, Buffer<float>& blocks,
                   Buffer<int32_t>& nbr, Buffer<vd_float4>& data_rhs, Buffer<VdMat3>& diag_inv) {
  return kBtbAssemble(ctx, a.count, VD_ACTIVE_OF(L, a), a.neighbours, edge_w, moments, w, x0, 1, blocks, nbr, data_rhs,
                      diag_inv);
}

Status ApplySystemCached(Context& ctx, size_t m, const Buffer<float>& blocks, const Buffer<int32_t>& nbr,
                         const Buffer<vd_float4>& d, Buffer<vd_float4>& q) {
  return kSystemApplyCached(ctx, m, blocks, nbr, d, q);
}

Status Precondition(Context& ctx, size_t n, const Buffer<VdMat3>& diag_inv, const Buffer<vd_float4>& r,
                    Buffer<vd_float4>& z) {
  return kPcgPrecondition(ctx, n, diag_inv, r, z);
}

Status Axpy(Context& ctx, size_t n, float a, const Buffer<vd_float4>& x, Buffer<vd_float4>& y) {
  return kAxpy4(ctx, n, a, x, y);
}


Status SubFrom(Context& ctx, size_t n, const Buffer<vd_float4>& b, Buffer<vd_float4>& y) {
  return kSubFrom4(ctx, n, b, y);
}

Status DotPartials(Context& ctx, size_t groups, const Buffer<vd_float4>& a, const Buffer<vd_float4>& b, int n,
                   int chunk, Buffer<float>& partials) {
  return kDot4Partial(ctx, groups, a, b, n, chunk, partials);
}

Status DenseEnergyPartials(Context& ctx, size_t groups, const Buffer<VdCorrespondence>& cons,
                           const Buffer<int32_t>& sorted_cell, int n, int chunk, const DeviceLattice& L,
                           const DeviceActiveSet& a, const Buffer<vd_float4>& x, Buffer<float>& partials) {
  return kEnergyDensePartial(ctx, groups, cons, sorted_cell, n, chunk, VD_ACTIVE_OF(L, a), x, partials);
}

Status ArapEnergyPartials(Context& ctx, size_t groups, const Buffer<int32_t>& neighbours, const Buffer<float>& edge_w,
                          float spacing, const Buffer<vd_float4>& x, const Buffer<vd_float4>& rot, int n, int chunk,
                          Buffer<float>& partials) {
  return kEnergyArapPartial(ctx, groups, neighbours, edge_w, spacing, x, rot, n, chunk, partials);
}

Status ArapEdgeWeights(Context& ctx, size_t m, const Buffer<int32_t>& neighbours, const Buffer<vd_float4>& x,
                       const Buffer<vd_float4>& rot, const Buffer<vd_float4>& t_hat, float scale2, float floor_w,
                       Buffer<float>& edge_w) {
  return kArapEdgeWeights(ctx, m, neighbours, x, rot, t_hat, scale2, floor_w, edge_w);
}

Status PcgScalars(Context& ctx, const Buffer<float>& partials, int groups, int mode, float tolerance,
                  Buffer<float>& scal) {
  return kPcgScalars(ctx, 1, partials, groups, mode, tolerance, scal);
}

// The group reductions assume the launch's work-groups are VD_PCG_GROUP items (reqd_work_group_size).
static_assert(Context::kGroupSize == VD_PCG_GROUP);

Status PcgApplyDots(Context& ctx, size_t m, const Buffer<float>& scal, const Buffer<float>& blocks,
                    const Buffer<int32_t>& nbr, const Buffer<vd_float4>& r, const Buffer<vd_float4>& u,
                    Buffer<vd_float4>& w, Buffer<float>& partials) {
  return kPcgApplyDots(ctx, m, scal, blocks, nbr, r, u, w, partials);
}

Status PcgStart(Context& ctx, size_t m, float spacing, const Buffer<int32_t>& neighbours, const Buffer<float>& edge_w,
                const Buffer<vd_float4>& rot, const Buffer<vd_float4>& data_rhs, VdSolverWeights w,
                const Buffer<float>& blocks, const Buffer<int32_t>& nbr, const Buffer<VdMat3>& diag_inv,
                const Buffer<vd_float4>& x, Buffer<vd_float4>& r, Buffer<vd_float4>& u, Buffer<float>& partials) {
  return kPcgStart(ctx, m, spacing, neighbours, edge_w, rot, data_rhs, w, blocks, nbr, diag_inv, x, r, u, partials);
}

Status PcgDots(Context& ctx, size_t m, const Buffer<vd_float4>& r, const Buffer<vd_float4>& u,
               const Buffer<vd_float4>& w, Buffer<float>& partials) {
  return kPcgDots(ctx, m, r, u, w, partials);
}

Status PcgCgUpdate(Context& ctx, size_t m, const Buffer<float>& scal, const Buffer<VdMat3>& diag_inv,
                   const Buffer<vd_float4>& w, Buffer<vd_float4>& p, Buffer<vd_float4>& s, Buffer<vd_float4>& x,
                   Buffer<vd_float4>& r, Buffer<vd_float4>& u, Buffer<float>& partials) {
  return kPcgCgUpdate(ctx, m, scal, diag_inv, w, p, s, x, r, u, partials);
}

}  // namespace vd::ocl
