#pragma once
// CPU reference of the rotation step (kernel vd_procrustes): the shared per-point function of
// shared/procrustes.h looped with OpenMP. The test oracle of the kernel and its native baseline.
#include "shared/procrustes.h"

namespace vd::cpu {

// rot[k] = R_k as a unit quaternion (x, y, z, w), w >= 0, for the n active grid points: exact
// when iterations = 0, else refined from the rot[k] given. neighbours holds 6 * n entries, each
// −1 (absent) or a compact index in [0, n); t and t_hat hold n deformed and rest positions (w
// ignored); edge_w: 6 ARAP edge weights per point, or null for 1 each.
void Procrustes(const int* neighbours, const float* edge_w, const vd_float4* t, const vd_float4* t_hat, int n,
                int iterations, vd_float4* rot);

}  // namespace vd::cpu
