/* The rotation half-step of the flip-flop solver (VolumeDeform section 7.1, SOLVER-NOTES.md
 * "Rotation step"): with the positions t fixed, each grid point i of the active set M gets the
 * rotation minimising its ARAP term
 *   Σ_{j∈N_i} |(t_i − t_j) − R_i (t̂_i − t̂_j)|²,
 * an orthogonal Procrustes problem solved independently per point from the cross-covariance
 *   S_i = Σ_j (t̂_i − t̂_j)(t_i − t_j)ᵀ = U Σ Vᵀ,   R_i = V Uᵀ
 * (negating the column of V of the smallest singular value when det(V Uᵀ) < 0, which turns the
 * best orthogonal matrix into the best rotation).
 *
 * Layout of the active set: compact arrays indexed by k in [0, n); neighbours[6k + d] is the
 * compact index of the d-th 6-neighbour of point k, or −1 when that grid point is not in M.
 * Every index that is not −1 must lie in [0, n): the list builder guarantees it (other negative
 * values are skipped as absent). */
#ifndef VD_PROCRUSTES_H
#define VD_PROCRUSTES_H

#include "svd3.h"
#include "vd_compat.h"

/* A neighbourhood whose second singular value is below this fraction of the first is treated as
 * collinear (rank 1): the twist about the line would be fixed by rounding, not by data. Float
 * positions of a few metres on a 4 mm grid already carry ~3e-5 relative rounding in t_i − t_j,
 * so the bound sits well above that; a real neighbourhood off a line has σ2/σ1 of order 1. */
#define VD_PROCRUSTES_RANK1_RATIO 1e-3f
/* |S| entries at or below this (m² for metric positions) count as no information at all. */
#define VD_PROCRUSTES_MIN_COVARIANCE 1e-30f

/* The shortest-arc rotation taking unit direction a onto unit direction b: the quaternion
 * (a × b, 1 + a·b), whose squared norm is 2(1 + a·b). Only when that vanishes to rounding
 * (opposite directions, any axis ⊥ a is optimal) is the axis chosen: a × e, e the coordinate
 * axis of a's smallest component, turned by π. */
VD_INLINE VdMat3 vd_rotation_between(vd_float4 a, vd_float4 b) {
  float w = 1.0f + vd_dot3(a, b);
  vd_float4 axis = vd_cross3(a, b);
  if (w <= 1e-7f) {
    float ax = fabs(a.x), ay = fabs(a.y), az = fabs(a.z);
    vd_float4 e = ax <= ay && ax <= az ? VD_F4(1.0f, 0.0f, 0.0f, 0.0f)
                                       : (ay <= az ? VD_F4(0.0f, 1.0f, 0.0f, 0.0f) : VD_F4(0.0f, 0.0f, 1.0f, 0.0f));
    axis = vd_normalize3(vd_cross3(a, e));
    w = 0.0f;
  }
  return vd_quat_to_mat3(VD_F4(axis.x, axis.y, axis.z, w));
}

/* The rotation R minimising Σ_j |q_j − R p_j|² given S = Σ_j p_j q_jᵀ. Well defined for every
 * input:
 * - S ≈ 0 (no neighbours, or every q_j = 0: nothing constrains R) or S non-finite: identity.
 * - S of rank 1 (all p_j on one line, e.g. a single neighbour or two opposite ones): any rotation
 *   taking the line of the p_j onto that of the q_j is optimal; the shortest arc is returned
 *   (no twist about the line).
 * - Rank 2 (coplanar neighbours) and rank 3: the unique optimum.
 * Always a proper rotation (det +1). */
VD_INLINE VdMat3 vd_procrustes_rotation(VdMat3 s) {
  if (!(vd_mat3_max_abs(s) > VD_PROCRUSTES_MIN_COVARIANCE) || !vd_mat3_is_finite(s)) return vd_mat3_identity();
  VdMat3 u, v;
  vd_float4 sigma;
  vd_svd3(s, &u, &sigma, &v);
  if (sigma.y <= VD_PROCRUSTES_RANK1_RATIO * sigma.x) {
    /* S ≈ σ1 u1 v1ᵀ: p_j run along u1 and q_j along v1. */
    return vd_rotation_between(VD_F4(u.m[0], u.m[3], u.m[6], 0.0f), VD_F4(v.m[0], v.m[3], v.m[6], 0.0f));
  }
  VdMat3 r = vd_mat3_mul_transpose(v, u);
  if (vd_mat3_det(r) < 0.0f) {
    v.m[2] = -v.m[2];
    v.m[5] = -v.m[5];
    v.m[8] = -v.m[8];
    r = vd_mat3_mul_transpose(v, u);
  }
  return r;
}

/* Cross-covariance S_k = Σ_j w_kj (t̂_k − t̂_j)(t_k − t_j)ᵀ over the neighbours of active point k,
 * with the ARAP edge weights w_kj = edge_w[6k + j] (shared/solver.h vd_arap_edge_weights), or 1
 * each when edge_w is null. */
VD_INLINE VdMat3 vd_procrustes_covariance(int k, VD_GLOBAL const int* neighbours, VD_GLOBAL const float* edge_w,
                                          VD_GLOBAL const vd_float4* t, VD_GLOBAL const vd_float4* t_hat) {
  vd_float4 tk = t[k];
  vd_float4 hk = t_hat[k];
  VdMat3 s = vd_mat3_zero();
  for (int d = 0; d < 6; ++d) {
    int j = neighbours[6 * k + d];
    if (j < 0) continue;
    vd_float4 e = hk - t_hat[j];
    if (edge_w) e = e * edge_w[6 * k + d];
    vd_mat3_add_outer(&s, e, tk - t[j]);
  }
  return s;
}

/* Warm-started rotation extraction: the same optimum as vd_procrustes_rotation, maximising
 * f(R) = tr(R S), reached by `iterations` Newton steps on the rotation from the unit quaternion q
 * instead of a 3x3 SVD. With M = R S and R turned to exp([ω]) R,
 *   f ≈ tr M + gᵀω − ½ ωᵀ H ω,  g = (M₁₂ − M₂₁, M₂₀ − M₀₂, M₀₁ − M₁₀),  H = tr(M) I − (M + Mᵀ)/2,
 * so the step is ω = H⁻¹ g (a 3x3 symmetric solve by its adjugate). At the optimum M = V Σ Vᵀ and
 * H has eigenvalues σ₂+σ₃, σ₁+σ₃, σ₁+σ₂, positive wherever the optimum is unique: near it the
 * steps converge quadratically. Where H is not positive definite (a start far from the optimum),
 * the step falls back to ω = g / |tr M| (Müller et al. 2016, "A robust method to extract the
 * rotational part of deformations"), which always climbs. A step is applied as the quaternion
 * (ω/2, 1) normalised, ω first shortened to length 1: a turn by 2 atan(|ω|/2), equal to |ω| to
 * second order, and at most 53 degrees per step.
 * Written over lanes (vd_compat.h): one call refines VD_LANES points at once, every branch a
 * select. `ok` is the lane mask of points whose S carries information (vd_procrustes_informed):
 * - S ≈ 0 or non-finite (ok = 0): nothing constrains R; q is returned as it is (the previous
 *   rotation stays, where vd_procrustes_rotation answers the identity).
 * - Rank 1: every rotation turning the line of the p_j onto that of the q_j is optimal; the
 *   steps add no twist about the line (g has none), so the one nearest q is kept.
 * Otherwise the result has w >= 0. In the flip-flop, q is the point's rotation of the previous
 * half-step (or of the previous frame), within a few degrees of the optimum
 * (tests/solver/svd3_test.cpp measures the convergence from 2 to 90 degrees). */
typedef struct {
  vd_lf m[9];
} VdLMat3;
typedef struct {
  vd_lf x, y, z, w;
} VdLQuat;

VD_INLINE VdLQuat vd_procrustes_refine_lanes(VdLMat3 s, VdLQuat q, vd_li ok, int iterations) {
  const VdLQuat q0 = q;
  for (int it = 0; it < iterations; ++it) {
    /* R(q) as vd_quat_to_mat3 forms it (identity where |q|² is not a positive finite number). */
    vd_lf n2 = q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w;
    vd_li valid = (n2 > 0.0f) & isfinite(n2);
    vd_lf s2 = vd_lsel((vd_lf)0.0f, 2.0f / n2, valid);
    vd_lf xx = q.x * q.x * s2, yy = q.y * q.y * s2, zz = q.z * q.z * s2;
    vd_lf xy = q.x * q.y * s2, xz = q.x * q.z * s2, yz = q.y * q.z * s2;
    vd_lf wx = q.w * q.x * s2, wy = q.w * q.y * s2, wz = q.w * q.z * s2;
    vd_lf r[9] = {1.0f - yy - zz, xy - wz, xz + wy, xy + wz, 1.0f - xx - zz, yz - wx, xz - wy, yz + wx, 1.0f - xx - yy};
    vd_lf m[9];
    VD_UNROLL
    for (int i = 0; i < 3; ++i) {
      VD_UNROLL
      for (int j = 0; j < 3; ++j)
        m[3 * i + j] = r[3 * i] * s.m[j] + r[3 * i + 1] * s.m[3 + j] + r[3 * i + 2] * s.m[6 + j];
    }
    vd_lf tr = m[0] + m[4] + m[8];
    vd_lf gx = m[5] - m[7], gy = m[6] - m[2], gz = m[1] - m[3];
    vd_lf h00 = tr - m[0], h11 = tr - m[4], h22 = tr - m[8];
    vd_lf h01 = -0.5f * (m[1] + m[3]), h02 = -0.5f * (m[2] + m[6]), h12 = -0.5f * (m[5] + m[7]);
    vd_lf c00 = h11 * h22 - h12 * h12, c01 = h02 * h12 - h01 * h22, c02 = h01 * h12 - h02 * h11;
    vd_lf c11 = h00 * h22 - h02 * h02, c12 = h01 * h02 - h00 * h12, c22 = h00 * h11 - h01 * h01;
    vd_lf det = h00 * c00 + h01 * c01 + h02 * c02;
    /* Positive definite by its leading minors, det well away from rounding (relative to tr³). */
    vd_lf scale = fabs(tr) + VD_PROCRUSTES_MIN_COVARIANCE;
    vd_li definite = (h00 > 0.0f) & (c22 > 0.0f) & (det > 1e-6f * scale * scale * scale);
    vd_lf inv_det = vd_lsel((vd_lf)0.0f, 1.0f / det, definite);
    vd_lf inv_tr = vd_lsel(1.0f / scale, (vd_lf)0.0f, definite);
    vd_lf w0 = (c00 * gx + c01 * gy + c02 * gz) * inv_det + gx * inv_tr;
    vd_lf w1 = (c01 * gx + c11 * gy + c12 * gz) * inv_det + gy * inv_tr;
    vd_lf w2 = (c02 * gx + c12 * gy + c22 * gz) * inv_det + gz * inv_tr;
    /* A turn of at most ~1 rad per step: the quadratic model holds near the optimum only. */
    vd_lf shrink = 0.5f / fmax((vd_lf)1.0f, sqrt(w0 * w0 + w1 * w1 + w2 * w2));
    vd_lf ax = shrink * w0, ay = shrink * w1, az = shrink * w2;
    /* (a, 1) ∘ q, as vd_quat_mul. */
    vd_lf nx = q.x + ax * q.w + ay * q.z - az * q.y;
    vd_lf ny = q.y - ax * q.z + ay * q.w + az * q.x;
    vd_lf nz = q.z + ax * q.y - ay * q.x + az * q.w;
    vd_lf nw = q.w - ax * q.x - ay * q.y - az * q.z;
    vd_lf inv = 1.0f / sqrt(nx * nx + ny * ny + nz * nz + nw * nw);
    q.x = nx * inv;
    q.y = ny * inv;
    q.z = nz * inv;
    q.w = nw * inv;
  }
  vd_lf sign = vd_lsel((vd_lf)1.0f, (vd_lf)-1.0f, q.w < 0.0f);
  VdLQuat out;
  out.x = vd_lsel(q0.x, sign * q.x, ok);
  out.y = vd_lsel(q0.y, sign * q.y, ok);
  out.z = vd_lsel(q0.z, sign * q.z, ok);
  out.w = vd_lsel(q0.w, sign * q.w, ok);
  return out;
}

/* Whether S carries information: finite, and some entry above VD_PROCRUSTES_MIN_COVARIANCE. */
VD_INLINE int vd_procrustes_informed(VdMat3 s) {
  return vd_mat3_max_abs(s) > VD_PROCRUSTES_MIN_COVARIANCE && vd_mat3_is_finite(s);
}

#if VD_LANES == 1
/* One point: vd_procrustes_refine_lanes with a single lane. */
VD_INLINE vd_float4 vd_procrustes_refine(VdMat3 s, vd_float4 q, int iterations) {
  VdLMat3 sl;
  for (int i = 0; i < 9; ++i) sl.m[i] = s.m[i];
  VdLQuat ql = {q.x, q.y, q.z, q.w};
  VdLQuat r = vd_procrustes_refine_lanes(sl, ql, vd_procrustes_informed(s), iterations);
  return VD_F4(r.x, r.y, r.z, r.w);
}

/* R_k of active point k as a unit quaternion (x, y, z, w), w >= 0: with iterations = 0 the exact
 * optimum by SVD (vd_procrustes_rotation), else vd_procrustes_refine from warm[k], the point's
 * current rotation. */
VD_INLINE vd_float4 vd_procrustes_point(int k, VD_GLOBAL const int* neighbours, VD_GLOBAL const float* edge_w,
                                        VD_GLOBAL const vd_float4* t, VD_GLOBAL const vd_float4* t_hat, vd_float4 warm,
                                        int iterations) {
  VdMat3 s = vd_procrustes_covariance(k, neighbours, edge_w, t, t_hat);
  if (iterations <= 0) return vd_mat3_to_quat(vd_procrustes_rotation(s));
  return vd_procrustes_refine(s, warm, iterations);
}
#endif /* VD_LANES == 1 */

#endif /* VD_PROCRUSTES_H */
