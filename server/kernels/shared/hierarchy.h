/* The coarse levels of the nested coarse-to-fine solver (VolumeDeform section 7.2;
 * docs/NONRIGID.md "Hierarchy"). Level l has spacing s = 2^l fine voxels and the fine grid's
 * origin: coarse grid point P sits at fine grid coordinates s P, and a fine point with grid
 * coordinates g lies in coarse cell floor(g / s) with trilinear weights from the fractions.
 *  - Active points of a level: the 8 corners of every coarse cell holding a fine active point, so
 *    every fine constraint and every fine active point has all its coarse corners.
 *  - Restriction: a coarse point starts at its rest position plus the tent-weighted mean
 *    displacement of the fine active points within one coarse spacing, inclusive (x0); the tent
 *    reaches zero one fine voxel beyond, so a corner marked only by fine points on the opposite
 *    face of its cell still has weight.
 *  - Constraints keep their fine deformed position p_cur = sum_fine alpha x: at level l their
 *    residual is n . (p_cur + sum_coarse alpha_l (x - x0) - p~), i.e. the fine form with canonical
 *    position g / s and target p~ - (p_cur - sum_coarse alpha_l x0). All constraints are kept.
 *  - Prolongation: the fine points move by the trilinear interpolation of the coarse increments
 *    x - x0. */
#ifndef VD_HIERARCHY_H
#define VD_HIERARCHY_H

#include "solver.h"

/* Coarse grid coordinates of fine grid coordinates (gx, gy, gz) at spacing s. */
VD_INLINE vd_float4 vd_level_coords(float gx, float gy, float gz, int s) {
  float inv = 1.0f / (float)s;
  return VD_F4(gx * inv, gy * inv, gz * inv, 0.0f);
}

/* Grid index of corner o of the coarse cell holding fine grid point (x, y, z). */
VD_INLINE int vd_level_corner_index(int x, int y, int z, int s, VdVolume coarse, int o) {
  int cx = vd_min_i(x / s, coarse.dim_x - 2), cy = vd_min_i(y / s, coarse.dim_y - 2), cz = vd_min_i(z / s, coarse.dim_z - 2);
  return vd_grid_index(coarse, cx + (o & 1), cy + ((o >> 1) & 1), cz + ((o >> 2) & 1));
}

/* x0 of coarse active point K (returned): its rest position plus the tent-weighted mean
 * displacement of the active fine points within s of it; and in *rot_c the warm start of its
 * rotation, the normalised tent-weighted mean of their rotations (identity when there are none).
 * The coarse rotation step then refines that (vd_procrustes_refine_lanes) instead of solving from
 * nothing by SVD: a coarse neighbourhood is a smoothed fine one, so its optimum is near the mean
 * fine rotation there, as a fine point's is near its last frame's. */
VD_INLINE vd_float4 vd_level_restrict(int K, VD_GLOBAL const int* list_c, VdVolume coarse, int s,
                                      VD_GLOBAL const int* compact_f, VdVolume fine, VD_GLOBAL const vd_float4* x_f,
                                      VD_GLOBAL const vd_float4* rot_f, vd_float4* rot_c) {
  int X, Y, Z;
  vd_grid_coords(list_c[K], coarse, &X, &Y, &Z);
  vd_float4 acc = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  vd_float4 qsum = VD_F4(0.0f, 0.0f, 0.0f, 0.0f), qref = VD_F4(0.0f, 0.0f, 0.0f, 1.0f);
  int found = 0;
  float wsum = 0.0f;
  float inv = 1.0f / (float)(s + 1);
  for (int dz = -s; dz <= s; ++dz) {
    int z = s * Z + dz;
    if (z < 0 || z >= fine.dim_z) continue;
    for (int dy = -s; dy <= s; ++dy) {
      int y = s * Y + dy;
      if (y < 0 || y >= fine.dim_y) continue;
      for (int dx = -s; dx <= s; ++dx) {
        int x = s * X + dx;
        if (x < 0 || x >= fine.dim_x) continue;
        int kf = compact_f[vd_grid_index(fine, x, y, z)];
        if (kf < 0) continue;
        float w = (1.0f - (float)(dx < 0 ? -dx : dx) * inv) * (1.0f - (float)(dy < 0 ? -dy : dy) * inv) *
                  (1.0f - (float)(dz < 0 ? -dz : dz) * inv);
        acc = acc + (x_f[kf] - vd_rest_position(fine, x, y, z)) * w;
        wsum += w;
        /* q and -q are one rotation: each is added on the side of the first one met. */
        vd_float4 q = rot_f[kf];
        if (!found) qref = q;
        found = 1;
        if (vd_dot3(q, qref) + q.w * qref.w < 0.0f) q = -q;
        qsum = qsum + q * w;
      }
    }
  }
  vd_float4 p = vd_rest_position(coarse, X, Y, Z);
  if (wsum > 0.0f) p = p + acc * (1.0f / wsum);
  p.w = 0.0f;
  float qn = sqrt(vd_dot3(qsum, qsum) + qsum.w * qsum.w);
  *rot_c = qn > 0.0f ? qsum * (1.0f / qn) : VD_F4(0.0f, 0.0f, 0.0f, 1.0f);
  return p;
}

/* Fine constraint c re-expressed on the coarse level (w = 0 when a corner is missing). */
VD_INLINE VdCorrespondence vd_level_constraint(VdCorrespondence c, VD_GLOBAL const int* compact_f, VdVolume fine,
                                               VD_GLOBAL const vd_float4* x_f, int s, VD_GLOBAL const int* compact_c,
                                               VdVolume coarse, VD_GLOBAL const vd_float4* x0_c) {
  VdCorrespondence out = c;
  int idx[8];
  float alpha[8];
  vd_float4 gc = vd_level_coords(c.canonical.x, c.canonical.y, c.canonical.z, s);
  gc.w = c.canonical.w;
  out.canonical = gc;
  if (!(c.canonical.w > 0.0f) || !vd_cell_corners(c.canonical, compact_f, fine, idx, alpha)) {
    out.canonical.w = 0.0f;
    return out;
  }
  vd_float4 p_cur = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  for (int o = 0; o < 8; ++o) p_cur = p_cur + x_f[idx[o]] * alpha[o];
  if (!vd_cell_corners(gc, compact_c, coarse, idx, alpha)) {
    out.canonical.w = 0.0f;
    return out;
  }
  vd_float4 p0 = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  for (int o = 0; o < 8; ++o) p0 = p0 + x0_c[idx[o]] * alpha[o];
  out.target = c.target - (p_cur - p0);
  out.target.w = 0.0f;
  return out;
}

/* Increment of fine active point k from the coarse solution (0 when a corner is missing). */
VD_INLINE vd_float4 vd_level_prolongate(int k, VD_GLOBAL const int* list_f, VdVolume fine, int s,
                                        VD_GLOBAL const int* compact_c, VdVolume coarse,
                                        VD_GLOBAL const vd_float4* x_c, VD_GLOBAL const vd_float4* x0_c) {
  int x, y, z;
  vd_grid_coords(list_f[k], fine, &x, &y, &z);
  int idx[8];
  float alpha[8];
  vd_float4 u = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  if (!vd_cell_corners(vd_level_coords((float)x, (float)y, (float)z, s), compact_c, coarse, idx, alpha)) return u;
  for (int o = 0; o < 8; ++o) u = u + (x_c[idx[o]] - x0_c[idx[o]]) * alpha[o];
  u.w = 0.0f;
  return u;
}

/* A coarse system from the fine level's sorted constraints (docs/NONRIGID.md "Hierarchy"),
 * without re-expressing, re-sorting or storing them per level: a coarse cell's constraints are
 * those of the s^3 fine cells inside it, each a contiguous range of the fine order. On a coarse
 * level a constraint's right-hand side is w n . (p~ - p_cur + sum alpha x0) (vd_level_constraint):
 * its first part, the residual at the fine state x_f, is accumulated here; the x0 part is
 * (B^T B x0)_k, added by the assembly (vd_btb_assemble with shift). */

/* The moments of the coarse cell whose first corner is active point K (VD_CELL_MOMENT_FLOATS at
 * moments_c + K * that): the 27 B^T B moments, the residuals' right-hand sides and the count. */
VD_INLINE void vd_level_moments(int K, VD_GLOBAL const int* list_c, VdVolume coarse, int s,
                                VD_GLOBAL const int* compact_f, VdVolume fine, VD_GLOBAL const VdCorrespondence* cons,
                                VD_GLOBAL const vd_uint* cell_start, VD_GLOBAL const vd_float4* x_f,
                                VD_GLOBAL float* moments_c) {
  int X, Y, Z;
  vd_grid_coords(list_c[K], coarse, &X, &Y, &Z);
  float acc[VD_CELL_COUNT_SLOT];
  for (int i = 0; i < VD_CELL_COUNT_SLOT; ++i) acc[i] = 0.0f;
  vd_uint count = 0u;
  float inv = 1.0f / (float)s;
  for (int d = 0; d < s * s * s; ++d) {
    int x = s * X + d % s, y = s * Y + (d / s) % s, z = s * Z + d / (s * s);
    if (x >= fine.dim_x - 1 || y >= fine.dim_y - 1 || z >= fine.dim_z - 1) continue;
    int kc = compact_f[vd_grid_index(fine, x, y, z)];
    if (kc < 0) continue;
    vd_uint c0 = cell_start[kc], c1 = cell_start[kc + 1];
    if (c0 == c1) continue;
    count += c1 - c0;
    /* A fine cell holds constraints only when all 8 corners are active (vd_cell_corners). */
    vd_float4 xc[8];
    for (int o = 0; o < 8; ++o)
      xc[o] = x_f[compact_f[vd_grid_index(fine, x + (o & 1), y + ((o >> 1) & 1), z + (o >> 2))]];
    for (vd_uint c = c0; c < c1; ++c) {
      VdCorrespondence cc = cons[c];
      float fx = cc.canonical.x - (float)x, fy = cc.canonical.y - (float)y, fz = cc.canonical.z - (float)z;
      vd_float4 p = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
      for (int o = 0; o < 8; ++o)
        p = p + xc[o] * ((o & 1 ? fx : 1.0f - fx) * (o & 2 ? fy : 1.0f - fy) * (o & 4 ? fz : 1.0f - fz));
      /* The coarse fractions as vd_level_constraint and vd_cell_corners form them. */
      float gx = cc.canonical.x * inv - (float)X, gy = cc.canonical.y * inv - (float)Y,
            gz = cc.canonical.z * inv - (float)Z;
      vd_moments_add(acc, gx, gy, gz, cc.canonical.w, cc.normal, cc.canonical.w * vd_dot3(cc.normal, cc.target - p));
    }
  }
  VD_GLOBAL float* out = moments_c + (size_t)VD_CELL_MOMENT_FLOATS * (size_t)K;
  for (int i = 0; i < VD_CELL_COUNT_SLOT; ++i) out[i] = acc[i];
  out[VD_CELL_COUNT_SLOT] = (float)count;
}

#endif /* VD_HIERARCHY_H */
