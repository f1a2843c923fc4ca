#include "shared/procrustes.h"

/* Rotation step of the flip-flop solver, exact: one work item per active grid point k replaces
 * R_k (a unit quaternion (x, y, z, w)) by the rotation fitted to its neighbours by SVD. */
__kernel void vd_procrustes(__global const int* neighbours, __global const float* edge_w, __global const float4* t,
                            __global const float4* t_hat, __global float4* rot, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int k = get_global_id(0);
  rot[k] = vd_mat3_to_quat(vd_procrustes_rotation(vd_procrustes_covariance(k, neighbours, edge_w, t, t_hat)));
}

/* Rotation step, warm-started: `iterations` refinement steps from the R_k each point holds, for
 * VD_LANES consecutive points per work item (a kLaned launch). Each lane's covariance is gathered
 * on its own (its neighbours are anywhere in the set); the steps run on all lanes at once. */
__kernel void vd_procrustes_refine_kernel(__global const int* neighbours, __global const float* edge_w,
                                          __global const float4* t, __global const float4* t_hat, __global float4* rot,
                                          int iterations, int vd_items) {
  int base = (int)get_global_id(0) * VD_LANES;
  if (base >= vd_items) return;
  float sm[9][VD_LANES], qx[VD_LANES], qy[VD_LANES], qz[VD_LANES], qw[VD_LANES];
  int informed[VD_LANES];
  VD_UNROLL
  for (int l = 0; l < VD_LANES; ++l) {
    /* Lanes past the end repeat the last point and are not stored. */
    int k = min(base + l, vd_items - 1);
    VdMat3 s = vd_procrustes_covariance(k, neighbours, edge_w, t, t_hat);
    VD_UNROLL
    for (int i = 0; i < 9; ++i) sm[i][l] = s.m[i];
    /* A lane mask is all ones where true (select tests the top bit of vector lanes). */
    informed[l] = -vd_procrustes_informed(s);
    float4 q = rot[k];
    qx[l] = q.x;
    qy[l] = q.y;
    qz[l] = q.z;
    qw[l] = q.w;
  }
  VdLMat3 s;
  VD_UNROLL
  for (int i = 0; i < 9; ++i) s.m[i] = vd_lload(sm[i]);
  VdLQuat q = {vd_lload(qx), vd_lload(qy), vd_lload(qz), vd_lload(qw)};
  q = vd_procrustes_refine_lanes(s, q, vd_lload(informed), iterations);
  vd_lstore(q.x, qx);
  vd_lstore(q.y, qy);
  vd_lstore(q.z, qz);
  vd_lstore(q.w, qw);
  VD_UNROLL
  for (int l = 0; l < VD_LANES; ++l)
    if (base + l < vd_items) rot[base + l] = (float4)(qx[l], qy[l], qz[l], qw[l]);
}
