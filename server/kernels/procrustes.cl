#include "shared/procrustes.h"

/* Rotation step of the flip-flop solver: one work item per active grid point k replaces R_k (a
 * unit quaternion (x, y, z, w)) by the rotation fitted to its neighbours: exact by SVD when
 * iterations = 0, else `iterations` warm-started refinement steps from the R_k it holds. */
__kernel void vd_procrustes(__global const int* neighbours, __global const float4* t, __global const float4* t_hat,
                            __global float4* rot, int iterations, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int k = get_global_id(0);
  rot[k] = vd_procrustes_point(k, neighbours, t, t_hat, rot[k], iterations);
}
