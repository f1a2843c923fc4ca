#pragma once
// CPU reference of the cached B^T B build and product (kernels vd_cell_moments_kernel,
// vd_btb_assemble_kernel and vd_system_apply_cached_kernel): the shared per-item functions of
// shared/solver.h looped with OpenMP.
// The test oracle of the kernels.
#include <vector>

#include "shared/hierarchy.h"
#include "shared/solver.h"

namespace vd::cpu {

// The counting sort of n constraints by cell (kernels vd_constraint_scatter, then
// vd_constraint_order): cell_of[i] is constraint i's cell of m (-1: none). Gives cell_start (m + 1
// entries, the last the total), the constraints in cell order (input order within a cell) and each
// one's cell.
void SortConstraints(const VdCorrespondence* corr, const int* cell_of, int n, int m, std::vector<vd_uint>* cell_start,
                     std::vector<VdCorrespondence>* sorted, std::vector<int>* sorted_cell);
// Moments of every cell with constraints (VD_CELL_MOMENT_FLOATS floats per active point; cells
// without constraints are left as given), for m active points and constraints sorted by cell.
void CellMoments(VdActive a, const VdCorrespondence* cons, const vd_uint* cell_start, int m, float* moments);
// Per point: 27 blocks (VD_BTB_FLOATS floats) and neighbour indices, the data
// right-hand side and the inverse diagonal block, from the moments.
// x0 (read when not null) shifts the right-hand side by (w_d B^T B x0)_k, as on a coarse level.
void BtbAssemble(VdActive a, const int* neighbours, const float* edge_w, const float* moments, VdSolverWeights w,
                 const vd_float4* x0, int m, float* blocks, int* nbr, vd_float4* data_rhs, VdMat3* diag_inv);
// q = A d from the cached blocks (edge-weighted ARAP Laplacian, w_d B^T B, damping) for m points.
// vd_count_optimisation for the m listed points.
void CountOptimisation(const int* list, int m, vd_float4* def_pos);
void ApplySystemCached(const float* blocks, const int* nbr, const vd_float4* d, int m, vd_float4* q);
// The PCG's passes (shared/solver.h, the Chronopoulos/Gear form) over m points, with partial sums
// per group of VD_PCG_GROUP points added in the kernels' order: w = A u with the triples
// (r.u, w.u, r.r); the update with the singles of the new r.r; the scalars from the partials.
// The product and the update do nothing once scal says the PCG converged (vd_pcg_done).
void PcgApplyDots(const float* scal, const float* blocks, const int* nbr, const vd_float4* r, const vd_float4* u, int m,
                  vd_float4* w, float* partials);
void PcgDots(const vd_float4* r, const vd_float4* u, const vd_float4* w, int m, float* partials);
void PcgCgUpdate(const float* scal, const VdMat3* diag_inv, const vd_float4* w, int m, vd_float4* p, vd_float4* s,
                 vd_float4* x, vd_float4* r, vd_float4* u, float* partials);
void PcgScalars(const float* partials, int groups, int mode, float tolerance, float* scal);
// The start of a position step (vd_pcg_start) over m points, with the singles of b.b.
void PcgStart(float spacing, const int* neighbours, const float* edge_w, const vd_float4* rot,
              const vd_float4* data_rhs, VdSolverWeights w, const float* blocks, const int* nbr, const VdMat3* diag_inv,
              const vd_float4* x, int m, vd_float4* r, vd_float4* u, float* partials);

// A coarse level's moments from the fine constraints (shared/hierarchy.h; kernel
// vd_level_moments_kernel), n coarse points.
void LevelMoments(VdActive coarse, int s, VdActive fine, const VdCorrespondence* cons, const vd_uint* cell_start,
                  const vd_float4* x_f, int n, float* moments_c);

// The moments of level `parent` from those of the level below it (shared/hierarchy.h; kernel
// vd_level_moments_up_kernel), n points of the parent.
void LevelMomentsUp(VdActive parent, VdActive child, const float* moments_f, int n, float* moments_c);

// Adaptive rigidity (vd_arap_edge_weights_kernel): 6 ARAP edge weights per point for m points.
void ArapEdgeWeights(const int* neighbours, const vd_float4* x, const vd_float4* rot, const vd_float4* t_hat, int m,
                     float scale2, float floor_w, float* edge_w);

}  // namespace vd::cpu
