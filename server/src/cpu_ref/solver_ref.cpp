#include "cpu_ref/solver_ref.h"

namespace vd::cpu {

void CellMoments(const int* list, VdVolume vol, const VdCorrespondence* cons, const vd_uint* cell_start, int m,
                 float* moments) {
#pragma omp parallel for schedule(static)
  for (int k = 0; k < m; ++k) vd_cell_moments(k, list, vol, cons, cell_start, moments);
}

void BtbAssemble(const int* list, const int* compact, VdVolume vol, const int* neighbours, const vd_uint* cell_start,
                 const float* moments, VdSolverWeights w, int m, float* blocks, int* nbr, vd_float4* data_rhs,
                 VdMat3* diag_inv) {
#pragma omp parallel for schedule(static)
  for (int k = 0; k < m; ++k)
    data_rhs[k] = vd_btb_assemble(k, list, compact, vol, neighbours, cell_start, moments, w, blocks, nbr, &diag_inv[k]);
}

void ApplySystemCached(const int* neighbours, const float* blocks, const int* nbr, const vd_float4* d,
                       VdSolverWeights w, int m, vd_float4* q) {
#pragma omp parallel for schedule(static)
  for (int k = 0; k < m; ++k) q[k] = vd_system_apply_cached(k, neighbours, blocks, nbr, d, w);
}

}  // namespace vd::cpu
