/* 3x3 matrices, a branch-light 3x3 SVD and rotation <-> quaternion conversion, shared by the
 * OpenCL kernels and the host reference.
 *
 * The SVD follows the plan of McAdams et al. 2011 ("Computing the singular value decomposition
 * of 3x3 matrices with minimal branching"): a fixed number of cyclic Jacobi sweeps diagonalise
 * the symmetric AᵀA (giving V), the columns of AV are sorted by decreasing norm, and a Givens QR
 * of AV gives U (and the singular values on the diagonal of R). Two choices differ from the
 * paper, both for accuracy in single precision:
 * - The Jacobi rotations are exact (the closed-form angle that zeroes the pair, not the
 *   approximate quaternion Givens angles), and each rotation reads the entries of AᵀA from the current columns of AV
 *   (one-sided Jacobi) instead of updating a stored AᵀA. Forming AᵀA explicitly squares the
 *   condition number: columns belonging to a small singular value would stay coupled at about
 *   eps·σ1²/σ2, and dropping that coupling would cost ~1e-4·σ1 of reconstruction error for
 *   σ2 = 1e-3·σ1. Reading it from the columns keeps it at eps·σ2.
 * - A is scaled by its largest entry first, so neither AᵀA nor the Givens norms over- or
 *   underflow for any finite A.
 *
 * Matrices are private per-item values (VdMat3 never crosses host <-> device; the grid stores
 * rotations as quaternions), so the 36-byte struct needs no padding. */
#ifndef VD_SVD3_H
#define VD_SVD3_H

#include "vd_compat.h"

/* Row-major 3x3 matrix: entry (r, c) is m[3 * r + c]. */
typedef struct {
  float m[9];
} VdMat3;

/* Cyclic sweeps over the pairs (0,1), (0,2), (1,2). One-sided Jacobi converges quadratically:
 * measured in tests/solver/svd3_test.cpp, 3 sweeps leave |U Σ Vᵀ − A| at up to 9e-6·σ1 on random
 * matrices, 4 reach float rounding (7e-7·σ1, no better with 5), as McAdams et al. found. */
#define VD_SVD3_SWEEPS 4

VD_INLINE VdMat3 vd_mat3_zero(void) {
  VdMat3 r = {{0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f}};
  return r;
}

VD_INLINE VdMat3 vd_mat3_identity(void) {
  VdMat3 r = {{1.0f, 0.0f, 0.0f, 0.0f, 1.0f, 0.0f, 0.0f, 0.0f, 1.0f}};
  return r;
}

/* a · b */
VD_INLINE VdMat3 vd_mat3_mul(VdMat3 a, VdMat3 b) {
  VdMat3 r;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      r.m[3 * i + j] = a.m[3 * i] * b.m[j] + a.m[3 * i + 1] * b.m[3 + j] + a.m[3 * i + 2] * b.m[6 + j];
    }
  }
  return r;
}

/* a · bᵀ (R = V Uᵀ without forming Uᵀ). */
VD_INLINE VdMat3 vd_mat3_mul_transpose(VdMat3 a, VdMat3 b) {
  VdMat3 r;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      r.m[3 * i + j] = a.m[3 * i] * b.m[3 * j] + a.m[3 * i + 1] * b.m[3 * j + 1] + a.m[3 * i + 2] * b.m[3 * j + 2];
    }
  }
  return r;
}

VD_INLINE VdMat3 vd_mat3_transpose(VdMat3 a) {
  VdMat3 r = {{a.m[0], a.m[3], a.m[6], a.m[1], a.m[4], a.m[7], a.m[2], a.m[5], a.m[8]}};
  return r;
}

VD_INLINE float vd_mat3_det(VdMat3 a) {
  return a.m[0] * (a.m[4] * a.m[8] - a.m[5] * a.m[7]) - a.m[1] * (a.m[3] * a.m[8] - a.m[5] * a.m[6]) +
         a.m[2] * (a.m[3] * a.m[7] - a.m[4] * a.m[6]);
}

/* a · v on the xyz of v; w of the result is 0. */
VD_INLINE vd_float4 vd_mat3_apply(VdMat3 a, vd_float4 v) {
  return VD_F4(a.m[0] * v.x + a.m[1] * v.y + a.m[2] * v.z, a.m[3] * v.x + a.m[4] * v.y + a.m[5] * v.z,
               a.m[6] * v.x + a.m[7] * v.y + a.m[8] * v.z, 0.0f);
}

/* *s += p qᵀ on the xyz of p and q (a cross-covariance accumulator). */
VD_INLINE void vd_mat3_add_outer(VdMat3* s, vd_float4 p, vd_float4 q) {
  s->m[0] += p.x * q.x;
  s->m[1] += p.x * q.y;
  s->m[2] += p.x * q.z;
  s->m[3] += p.y * q.x;
  s->m[4] += p.y * q.y;
  s->m[5] += p.y * q.z;
  s->m[6] += p.z * q.x;
  s->m[7] += p.z * q.y;
  s->m[8] += p.z * q.z;
}

/* Largest |entry|; NaN entries are skipped (the caller checks finiteness separately). */
VD_INLINE float vd_mat3_max_abs(VdMat3 a) {
  float r = 0.0f;
  for (int i = 0; i < 9; ++i) {
    float v = fabs(a.m[i]);
    r = v > r ? v : r;
  }
  return r;
}

/* 1 when every entry is finite. */
VD_INLINE int vd_mat3_is_finite(VdMat3 a) {
  int ok = 1;
  for (int i = 0; i < 9; ++i) ok = ok && isfinite(a.m[i]);
  return ok;
}

/* Column p of *a becomes c·a_p − s·a_q and column q becomes s·a_p + c·a_q. */
VD_INLINE void vd_mat3_rotate_columns(VdMat3* a, int p, int q, float c, float s) {
  for (int r = 0; r < 3; ++r) {
    float ap = a->m[3 * r + p];
    float aq = a->m[3 * r + q];
    a->m[3 * r + p] = c * ap - s * aq;
    a->m[3 * r + q] = s * ap + c * aq;
  }
}

/* Swaps columns p and q of *a and negates the new column q, which keeps det(*a) unchanged. */
VD_INLINE void vd_mat3_swap_columns_keep_det(VdMat3* a, int p, int q) {
  for (int r = 0; r < 3; ++r) {
    float ap = a->m[3 * r + p];
    a->m[3 * r + p] = a->m[3 * r + q];
    a->m[3 * r + q] = -ap;
  }
}

/* One Jacobi rotation on the column pair (p, q) of b = A·V: the rotation that makes the two
 * columns orthogonal (i.e. zeroes entry (p, q) of bᵀb = Vᵀ AᵀA V), applied to b and v. */
VD_INLINE void vd_svd3_jacobi_pair(VdMat3* b, VdMat3* v, int p, int q) {
  float alpha = 0.0f, beta = 0.0f, gamma = 0.0f;
  for (int r = 0; r < 3; ++r) {
    float bp = b->m[3 * r + p];
    float bq = b->m[3 * r + q];
    alpha += bp * bp;
    beta += bq * bq;
    gamma += bp * bq;
  }
  /* cot 2θ = (beta − alpha) / (2 gamma); the smaller angle (|θ| <= π/4) has, with d = beta − alpha
   * and h = sqrt(d² + 4 gamma²) = |d| / |cos 2θ|, c² = (h + |d|) / (2h) and
   * tan θ = sign(d)·2 gamma / (h + |d|). No difference cancels, gamma = 0 needs no special case,
   * and the chain is sqrt -> div -> sqrt: the sweeps are latency-bound, not flop-bound.
   * c² + s² = 1 holds as long as h² = d² + 4 gamma² is not denormal, so pairs with h <= 1e-18 are
   * left alone: A is scaled to entries <= 1 (σ1 >= 1), so both columns are then below 1e-9·σ1,
   * zero at float resolution. */
  float d = beta - alpha;
  float h = sqrt(d * d + 4.0f * gamma * gamma);
  float u = fabs(d) + h;
  int rotate = h > 1e-18f;
  float c = rotate ? sqrt(u / (2.0f * h)) : 1.0f;
  float s = rotate ? (d >= 0.0f ? 2.0f * gamma : -2.0f * gamma) / u * c : 0.0f;
  vd_mat3_rotate_columns(b, p, q, c, s);
  vd_mat3_rotate_columns(v, p, q, c, s);
}

/* Sorts columns (p, q) of b by decreasing norm, moving v's columns alongside. */
VD_INLINE void vd_svd3_order_pair(VdMat3* b, VdMat3* v, int p, int q) {
  float np = b->m[p] * b->m[p] + b->m[3 + p] * b->m[3 + p] + b->m[6 + p] * b->m[6 + p];
  float nq = b->m[q] * b->m[q] + b->m[3 + q] * b->m[3 + q] + b->m[6 + q] * b->m[6 + q];
  if (nq > np) {
    vd_mat3_swap_columns_keep_det(b, p, q);
    vd_mat3_swap_columns_keep_det(v, p, q);
  }
}

/* Givens rotation on rows (p, q) of *r that zeroes entry (q, col), accumulated into *u so that
 * u · r stays invariant (u gains the transposed rotation on its columns p, q). */
VD_INLINE void vd_svd3_givens_rows(VdMat3* r, VdMat3* u, int p, int q, int col) {
  float a = r->m[3 * p + col];
  float b = r->m[3 * q + col];
  float h = sqrt(a * a + b * b);
  float c = h > 0.0f ? a / h : 1.0f;
  float s = h > 0.0f ? b / h : 0.0f;
  for (int j = 0; j < 3; ++j) {
    float rp = r->m[3 * p + j];
    float rq = r->m[3 * q + j];
    r->m[3 * p + j] = c * rp + s * rq;
    r->m[3 * q + j] = -s * rp + c * rq;
  }
  vd_mat3_rotate_columns(u, p, q, c, -s);
}

/* A = U · diag(sigma) · Vᵀ with U and V rotations (det +1), sigma.x >= sigma.y >= |sigma.z| and
 * sigma.z carrying the sign of det(A) (the form McAdams et al. use; w of sigma is 0). Any finite A,
 * including rank-deficient and zero ones; non-finite A gives non-finite output. */
VD_INLINE void vd_svd3_rotations(VdMat3 a, VdMat3* u, vd_float4* sigma, VdMat3* v) {
  float scale = vd_mat3_max_abs(a);
  float inv = scale > 0.0f ? 1.0f / scale : 1.0f;
  VdMat3 b;
  for (int i = 0; i < 9; ++i) b.m[i] = a.m[i] * inv;
  *v = vd_mat3_identity();
  for (int sweep = 0; sweep < VD_SVD3_SWEEPS; ++sweep) {
    vd_svd3_jacobi_pair(&b, v, 0, 1);
    vd_svd3_jacobi_pair(&b, v, 0, 2);
    vd_svd3_jacobi_pair(&b, v, 1, 2);
  }
  vd_svd3_order_pair(&b, v, 0, 1);
  vd_svd3_order_pair(&b, v, 0, 2);
  vd_svd3_order_pair(&b, v, 1, 2);
  /* b = A·V has orthogonal columns of decreasing norm; its QR gives U (a product of rotations)
   * and R = diag(sigma) up to the rounding left by the sweeps. */
  *u = vd_mat3_identity();
  vd_svd3_givens_rows(&b, u, 0, 1, 0);
  vd_svd3_givens_rows(&b, u, 0, 2, 0);
  vd_svd3_givens_rows(&b, u, 1, 2, 1);
  *sigma = VD_F4(b.m[0] * scale, b.m[4] * scale, b.m[8] * scale, 0.0f);
}

/* The conventional SVD A = U · diag(sigma) · Vᵀ: U, V orthogonal, sigma.x >= sigma.y >= sigma.z
 * >= 0. V is a rotation; det(U) = sign(det A) (U is a reflection when det A < 0). */
VD_INLINE void vd_svd3(VdMat3 a, VdMat3* u, vd_float4* sigma, VdMat3* v) {
  vd_svd3_rotations(a, u, sigma, v);
  float sign = sigma->z < 0.0f ? -1.0f : 1.0f;
  sigma->z *= sign;
  u->m[2] *= sign;
  u->m[5] *= sign;
  u->m[8] *= sign;
}

/* Rotations are stored as unit quaternions (x, y, z, w) = (axis · sin(θ/2), cos(θ/2)) in a
 * float4: 16 bytes (one aligned load, a 3x3 matrix would take 36), renormalisable after
 * interpolation or accumulated rounding, and free of the gimbal lock and wrap-around of the
 * Euler angles the paper stores. q and −q are the same rotation; conversions return w >= 0. */

/* The rotation matrix of q (acting on column vectors). q need not be unit length: it is
 * normalised on the fly; a zero (or non-finite-norm) q gives the identity. */
VD_INLINE VdMat3 vd_quat_to_mat3(vd_float4 q) {
  float n2 = q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w;
  if (!(n2 > 0.0f) || !isfinite(n2)) return vd_mat3_identity();
  float s = 2.0f / n2;
  float xx = q.x * q.x * s, yy = q.y * q.y * s, zz = q.z * q.z * s;
  float xy = q.x * q.y * s, xz = q.x * q.z * s, yz = q.y * q.z * s;
  float wx = q.w * q.x * s, wy = q.w * q.y * s, wz = q.w * q.z * s;
  VdMat3 r = {{1.0f - yy - zz, xy - wz, xz + wy, xy + wz, 1.0f - xx - zz, yz - wx, xz - wy, yz + wx, 1.0f - xx - yy}};
  return r;
}

/* The unit quaternion (w >= 0) of a rotation matrix (Shepperd's method: the square root is taken
 * of the largest of 4w², 4x², 4y², 4z², so no division loses precision). */
VD_INLINE vd_float4 vd_mat3_to_quat(VdMat3 r) {
  float m00 = r.m[0], m11 = r.m[4], m22 = r.m[8];
  float tr = m00 + m11 + m22;
  vd_float4 q;
  if (tr > 0.0f) {
    float s = 2.0f * sqrt(1.0f + tr);
    q = VD_F4((r.m[7] - r.m[5]) / s, (r.m[2] - r.m[6]) / s, (r.m[3] - r.m[1]) / s, 0.25f * s);
  } else if (m00 >= m11 && m00 >= m22) {
    float s = 2.0f * sqrt(fmax(1.0f + m00 - m11 - m22, 1e-30f));
    q = VD_F4(0.25f * s, (r.m[1] + r.m[3]) / s, (r.m[2] + r.m[6]) / s, (r.m[7] - r.m[5]) / s);
  } else if (m11 >= m22) {
    float s = 2.0f * sqrt(fmax(1.0f + m11 - m00 - m22, 1e-30f));
    q = VD_F4((r.m[1] + r.m[3]) / s, 0.25f * s, (r.m[5] + r.m[7]) / s, (r.m[2] - r.m[6]) / s);
  } else {
    float s = 2.0f * sqrt(fmax(1.0f + m22 - m00 - m11, 1e-30f));
    q = VD_F4((r.m[2] + r.m[6]) / s, (r.m[5] + r.m[7]) / s, 0.25f * s, (r.m[3] - r.m[1]) / s);
  }
  float n = sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
  float inv = (q.w < 0.0f ? -1.0f : 1.0f) / n;
  return VD_F4(q.x * inv, q.y * inv, q.z * inv, q.w * inv);
}

/* v rotated by the unit quaternion q (xyz of v; w of the result is 0):
 * v' = v + 2w (u × v) + 2 u × (u × v) with u = q.xyz. */
VD_INLINE vd_float4 vd_quat_rotate(vd_float4 q, vd_float4 v) {
  vd_float4 u = VD_F4(q.x, q.y, q.z, 0.0f);
  vd_float4 uv = vd_cross3(u, v);
  vd_float4 uuv = vd_cross3(u, uv);
  return VD_F4(v.x + 2.0f * (q.w * uv.x + uuv.x), v.y + 2.0f * (q.w * uv.y + uuv.y),
               v.z + 2.0f * (q.w * uv.z + uuv.z), 0.0f);
}

/* The Hamilton product a ⊗ b: the rotation b, then a. */
VD_INLINE vd_float4 vd_quat_mul(vd_float4 a, vd_float4 b) {
  return VD_F4(a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y, a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x,
               a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w, a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z);
}

#endif /* VD_SVD3_H */
