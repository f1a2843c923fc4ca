#include "cpu_ref/procrustes_ref.h"

namespace vd::cpu {

void Procrustes(const int* neighbours, const float* edge_w, const vd_float4* t, const vd_float4* t_hat, int n,
                int iterations, vd_float4* rot) {
#pragma omp parallel for schedule(static)
  for (int k = 0; k < n; ++k) rot[k] = vd_procrustes_point(k, neighbours, edge_w, t, t_hat, rot[k], iterations);
}

}  // namespace vd::cpu
