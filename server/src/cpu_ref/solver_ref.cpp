#include "cpu_ref/solver_ref.h"

#include <algorithm>
#include <vector>

namespace vd::cpu {

void SortConstraints(const VdCorrespondence* corr, const int* cell_of, int n, int m, std::vector<vd_uint>* cell_start,
                     std::vector<VdCorrespondence>* sorted, std::vector<int>* sorted_cell) {
  cell_start->assign(size_t(m) + 1, 0u);
  for (int i = 0; i < n; ++i)
    if (cell_of[i] >= 0) ++(*cell_start)[cell_of[i] + 1];
  for (int k = 0; k < m; ++k) (*cell_start)[k + 1] += (*cell_start)[k];
  const vd_uint total = (*cell_start)[m];
  std::vector<int> order(total);
  std::vector<vd_uint> cursor(cell_start->begin(), cell_start->end() - 1);
  for (int i = 0; i < n; ++i)
    if (cell_of[i] >= 0) order[cursor[cell_of[i]]++] = i;
  sorted->resize(total);
  sorted_cell->resize(total);
  for (int k = 0; k < m; ++k)
    vd_constraint_order_cell(k, corr, cell_start->data(), order.data(), sorted->data(), sorted_cell->data());
}

void CellMoments(VdActive a, const VdCorrespondence* cons, const vd_uint* cell_start, int m, float* moments) {
#pragma omp parallel for schedule(static)
  for (int k = 0; k < m; ++k) vd_cell_moments(k, a, cons, cell_start, moments);
}

void BtbAssemble(VdActive a, const int* neighbours, const float* edge_w, const float* moments, VdSolverWeights w,
                 const vd_float4* x0, int m, float* blocks, int* nbr, vd_float4* data_rhs, VdMat3* diag_inv) {
#pragma omp parallel for schedule(static)
  for (int k = 0; k < m; ++k)
    data_rhs[k] =
        vd_btb_assemble(k, a, neighbours, edge_w, moments, w, x0, x0 != nullptr ? 1 : 0, blocks, nbr, &diag_inv[k]);
}

void LevelMoments(VdActive coarse, int s, VdActive fine, const VdCorrespondence* cons, const vd_uint* cell_start,
                  const vd_float4* x_f, int n, float* moments_c) {
#pragma omp parallel for schedule(static)
  for (int k = 0; k < n; ++k) vd_level_moments(k, coarse, s, fine, cons, cell_start, x_f, moments_c);
}

void LevelMomentsUp(VdActive parent, VdActive child, const float* moments_f, int n, float* moments_c) {
#pragma omp parallel for schedule(static)
  for (int k = 0; k < n; ++k) vd_level_moments_up(k, parent, child, moments_f, moments_c);
}

void CountOptimisation(const int* list, int m, vd_float4* def_pos) {
  for (int k = 0; k < m; ++k) vd_count_optimisation(k, list, def_pos);
}

void ApplySystemCached(const float* blocks, const int* nbr, const vd_float4* d, int m, vd_float4* q) {
#pragma omp parallel for schedule(static)
  for (int k = 0; k < m; ++k) q[k] = vd_system_apply_cached(k, blocks, nbr, d);
}

namespace {
// The kernels' group sums (vd_pcg_group_sums): values[n k + i] summed per group, in item order.
void GroupSums(const std::vector<float>& values, int m, int n, float* partials) {
  const int groups = (m + VD_PCG_GROUP - 1) / VD_PCG_GROUP;
  for (int g = 0; g < groups; ++g)
    for (int i = 0; i < n; ++i) {
      float acc = 0.0f;
      for (int k = g * VD_PCG_GROUP; k < std::min(m, (g + 1) * VD_PCG_GROUP); ++k) acc += values[size_t(n) * k + i];
      partials[n * g + i] = acc;
    }
}
}  // namespace

void PcgApplyDots(const float* scal, const float* blocks, const int* nbr, const vd_float4* r, const vd_float4* u, int m,
                  vd_float4* w, float* partials) {
  if (vd_pcg_done(scal)) return;
  std::vector<float> v(3 * size_t(m));
#pragma omp parallel for schedule(static)
  for (int k = 0; k < m; ++k) {
    w[k] = vd_system_apply_cached(k, blocks, nbr, u);
    vd_pcg_dots(k, r, u, w, &v[3 * size_t(k)]);
  }
  GroupSums(v, m, 3, partials);
}

void PcgDots(const vd_float4* r, const vd_float4* u, const vd_float4* w, int m, float* partials) {
  std::vector<float> v(3 * size_t(m));
#pragma omp parallel for schedule(static)
  for (int k = 0; k < m; ++k) vd_pcg_dots(k, r, u, w, &v[3 * size_t(k)]);
  GroupSums(v, m, 3, partials);
}

void PcgCgUpdate(const float* scal, const VdMat3* diag_inv, const vd_float4* w, int m, vd_float4* p, vd_float4* s,
                 vd_float4* x, vd_float4* r, vd_float4* u, float* partials) {
  if (vd_pcg_done(scal)) return;
  std::vector<float> v(m);
#pragma omp parallel for schedule(static)
  for (int k = 0; k < m; ++k) v[k] = vd_pcg_cg_update(k, scal, diag_inv, w, p, s, x, r, u);
  GroupSums(v, m, 1, partials);
}

void PcgStart(float spacing, const int* neighbours, const float* edge_w, const vd_float4* rot,
              const vd_float4* data_rhs, VdSolverWeights w, const float* blocks, const int* nbr, const VdMat3* diag_inv,
              const vd_float4* x, int m, vd_float4* r, vd_float4* u, float* partials) {
  std::vector<float> v(m);
#pragma omp parallel for schedule(static)
  for (int k = 0; k < m; ++k)
    v[k] = vd_pcg_start(k, spacing, neighbours, edge_w, rot, data_rhs, w, blocks, nbr, diag_inv, x, r, u);
  GroupSums(v, m, 1, partials);
}

void PcgScalars(const float* partials, int groups, int mode, float tolerance, float* scal) {
  vd_pcg_scalars(partials, groups, mode, tolerance, scal);
}

void ArapEdgeWeights(const int* neighbours, const vd_float4* x, const vd_float4* rot, const vd_float4* t_hat, int m,
                     float scale2, float floor_w, float* edge_w) {
#pragma omp parallel for schedule(static)
  for (int k = 0; k < m; ++k) vd_arap_edge_weights(k, neighbours, x, rot, t_hat, scale2, floor_w, edge_w);
}

}  // namespace vd::cpu
