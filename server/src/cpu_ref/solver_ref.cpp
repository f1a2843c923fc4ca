#include "cpu_ref/solver_ref.h"

namespace vd::cpu {

void CellMoments(const int* list, VdVolume vol, const VdCorrespondence* cons, const vd_uint* cell_start, int m,
                 float* moments) {
#pragma omp parallel for schedule(static)
  for (int k = 0; k < m; ++k) vd_cell_moments(k, list, vol, cons, cell_start, moments);
}

void BtbAssemble(const int* list, const int* compact, VdVolume vol, const int* neighbours, const float* edge_w,
                 const float* moments, VdSolverWeights w, const vd_float4* x0, int m, float* blocks, int* nbr,
                 vd_float4* data_rhs, VdMat3* diag_inv) {
#pragma omp parallel for schedule(static)
  for (int k = 0; k < m; ++k)
    data_rhs[k] = vd_btb_assemble(k, list, compact, vol, neighbours, edge_w, moments, w, x0, x0 != nullptr ? 1 : 0,
                                  blocks, nbr, &diag_inv[k]);
}

void LevelMoments(const int* list_c, VdVolume coarse, int s, const int* compact_f, VdVolume fine,
                  const VdCorrespondence* cons, const vd_uint* cell_start, const vd_float4* x_f, int n,
                  float* moments_c) {
#pragma omp parallel for schedule(static)
  for (int k = 0; k < n; ++k) vd_level_moments(k, list_c, coarse, s, compact_f, fine, cons, cell_start, x_f, moments_c);
}

void ApplySystemCached(const float* blocks, const int* nbr, const vd_float4* d, int m, vd_float4* q) {
#pragma omp parallel for schedule(static)
  for (int k = 0; k < m; ++k) q[k] = vd_system_apply_cached(k, blocks, nbr, d);
}

void ArapEdgeWeights(const int* neighbours, const vd_float4* x, const vd_float4* rot, const vd_float4* t_hat, int m,
                     float scale2, float floor_w, float* edge_w) {
#pragma omp parallel for schedule(static)
  for (int k = 0; k < m; ++k) vd_arap_edge_weights(k, neighbours, x, rot, t_hat, scale2, floor_w, edge_w);
}

}  // namespace vd::cpu
