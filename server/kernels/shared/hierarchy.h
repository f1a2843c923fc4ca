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

/* Entry (in the coarse lattice) of corner o of the coarse cell holding fine point (slot, x, y, z),
 * -1 where the coarse point's brick is not allocated. */
VD_INLINE int vd_level_corner(VdLattice coarse, VD_GLOBAL const int* nbr, int s, int slot, int x, int y, int z, int o) {
  int cx, cy, cz;
  vd_lattice_coarse_cell(coarse, s, x, y, z, &cx, &cy, &cz);
  return vd_lattice_entry(coarse, nbr, slot, cx + (o & 1), cy + ((o >> 1) & 1), cz + ((o >> 2) & 1));
}

/* x0 of coarse active point K (returned): its rest position plus the tent-weighted mean
 * displacement of the active fine points within s of it; and in *rot_c the warm start of its
 * rotation, the normalised tent-weighted mean of their rotations (identity when there are none).
 * The coarse rotation step then refines that (vd_procrustes_refine_lanes) instead of solving from
 * nothing by SVD: a coarse neighbourhood is a smoothed fine one, so its optimum is near the mean
 * fine rotation there, as a fine point's is near its last frame's. */
VD_INLINE vd_float4 vd_level_restrict(int K, VdActive coarse, int s, VdActive fine, VD_GLOBAL const vd_float4* x_f,
                                      VD_GLOBAL const vd_float4* rot_f, vd_float4* rot_c) {
  int slot, X, Y, Z, GX, GY, GZ;
  vd_active_point(coarse, K, &slot, &X, &Y, &Z, &GX, &GY, &GZ);
  vd_float4 acc = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  vd_float4 qsum = VD_F4(0.0f, 0.0f, 0.0f, 0.0f), qref = VD_F4(0.0f, 0.0f, 0.0f, 1.0f);
  int found = 0;
  float wsum = 0.0f;
  float inv = 1.0f / (float)(s + 1);
  for (int dz = -s; dz <= s; ++dz) {
    for (int dy = -s; dy <= s; ++dy) {
      /* The row dx = -s..s in runs of consecutive entries (one table lookup a run). */
      for (int run = -s; run <= s;) {
        int run_end = vd_lattice_run_end(fine.lat, s * X + run, s * X + s) - s * X;
        int e0 = vd_lattice_entry(fine.lat, fine.nbr, slot, s * X + run, s * Y + dy, s * Z + dz);
        int dx0 = run;
        run = run_end + 1;
        if (e0 < 0) continue;
        for (int dx = dx0; dx <= run_end; ++dx) {
          int kf = fine.compact[e0 + dx - dx0];
          if (kf < 0) continue;
          float w = (1.0f - (float)(dx < 0 ? -dx : dx) * inv) * (1.0f - (float)(dy < 0 ? -dy : dy) * inv) *
                    (1.0f - (float)(dz < 0 ? -dz : dz) * inv);
          vd_float4 rest = VD_F4(fine.lat.origin.x + fine.lat.spacing * (float)(s * GX + dx),
                                 fine.lat.origin.y + fine.lat.spacing * (float)(s * GY + dy),
                                 fine.lat.origin.z + fine.lat.spacing * (float)(s * GZ + dz), 0.0f);
          acc = acc + (x_f[kf] - rest) * w;
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
  }
  vd_float4 p = vd_lattice_position(coarse.lat, coarse.slot_keys, slot, X, Y, Z);
  if (wsum > 0.0f) p = p + acc * (1.0f / wsum);
  p.w = 0.0f;
  float qn = sqrt(vd_dot3(qsum, qsum) + qsum.w * qsum.w);
  *rot_c = qn > 0.0f ? qsum * (1.0f / qn) : VD_F4(0.0f, 0.0f, 0.0f, 1.0f);
  return p;
}

/* The coarse cell (spacing s) holding the fine cell whose first corner is fine active point kf:
 * its 8 corners' coarse compact indices, and the trilinear weights there of fine global position
 * g (coarse coordinates g / s). Returns 0 when a corner is not in the coarse M. */
VD_INLINE int vd_level_cell(VdActive fine, int kf, vd_float4 g, int s, VdActive coarse, int* idx, float* alpha) {
  int slot, x, y, z;
  vd_lattice_point(fine.lat, fine.list[kf], &slot, &x, &y, &z);
  int cx, cy, cz, gx, gy, gz;
  vd_lattice_coarse_cell(coarse.lat, s, x, y, z, &cx, &cy, &cz);
  vd_lattice_global(coarse.lat, coarse.slot_keys, slot, cx, cy, cz, &gx, &gy, &gz);
  vd_float4 gc = vd_level_coords(g.x, g.y, g.z, s);
  float fx = gc.x - (float)gx, fy = gc.y - (float)gy, fz = gc.z - (float)gz;
  int e[8];
  vd_lattice_cell_entries(coarse.lat, coarse.nbr, slot, cx, cy, cz, e);
  for (int o = 0; o < 8; ++o) {
    int ox = o & 1, oy = (o >> 1) & 1, oz = (o >> 2) & 1;
    idx[o] = e[o] < 0 ? -1 : coarse.compact[e[o]];
    if (idx[o] < 0) return 0;
    alpha[o] = (ox ? fx : 1.0f - fx) * (oy ? fy : 1.0f - fy) * (oz ? fz : 1.0f - fz);
  }
  return 1;
}

/* Fine constraint c, in the cell whose first corner is fine active point kf (-1: unusable),
 * re-expressed on the coarse level (w = 0 when a corner is missing). */
VD_INLINE VdCorrespondence vd_level_constraint(VdCorrespondence c, int kf, VdActive fine,
                                               VD_GLOBAL const vd_float4* x_f, int s, VdActive coarse,
                                               VD_GLOBAL const vd_float4* x0_c) {
  VdCorrespondence out = c;
  out.normal.w = 0.0f; /* a coarse level solves every row (vd_fine_row) */
  int idx[8];
  float alpha[8];
  vd_float4 gc = vd_level_coords(c.canonical.x, c.canonical.y, c.canonical.z, s);
  gc.w = c.canonical.w;
  out.canonical = gc;
  if (kf < 0 || !(c.canonical.w > 0.0f) || !vd_active_cell(fine, kf, c.canonical, idx, alpha)) {
    out.canonical.w = 0.0f;
    return out;
  }
  vd_float4 p_cur = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  for (int o = 0; o < 8; ++o) p_cur = p_cur + x_f[idx[o]] * alpha[o];
  if (!vd_level_cell(fine, kf, c.canonical, s, coarse, idx, alpha)) {
    out.canonical.w = 0.0f;
    return out;
  }
  vd_float4 p0 = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  for (int o = 0; o < 8; ++o) p0 = p0 + x0_c[idx[o]] * alpha[o];
  out.target = c.target - (p_cur - p0);
  out.target.w = 0.0f;
  return out;
}

/* Increment of fine active point k from the coarse solution (0 when a corner it weighs is
 * missing). A corner of weight 0 may be missing: a point of a finer coarse level on the face of
 * the coarse cell holding it (the fine points marked the cell on the face's other side). */
VD_INLINE vd_float4 vd_level_prolongate(int k, VdActive fine, int s, VdActive coarse, VD_GLOBAL const vd_float4* x_c,
                                        VD_GLOBAL const vd_float4* x0_c) {
  int slot, x, y, z, gx, gy, gz;
  vd_active_point(fine, k, &slot, &x, &y, &z, &gx, &gy, &gz);
  int idx[8];
  float alpha[8];
  vd_float4 u = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  int cx, cy, cz, cgx, cgy, cgz;
  vd_lattice_coarse_cell(coarse.lat, s, x, y, z, &cx, &cy, &cz);
  vd_lattice_global(coarse.lat, coarse.slot_keys, slot, cx, cy, cz, &cgx, &cgy, &cgz);
  vd_float4 g = vd_level_coords((float)gx, (float)gy, (float)gz, s);
  float fx = g.x - (float)cgx, fy = g.y - (float)cgy, fz = g.z - (float)cgz;
  int e[8];
  vd_lattice_cell_entries(coarse.lat, coarse.nbr, slot, cx, cy, cz, e);
  for (int o = 0; o < 8; ++o) {
    int ox = o & 1, oy = (o >> 1) & 1, oz = (o >> 2) & 1;
    idx[o] = e[o] < 0 ? -1 : coarse.compact[e[o]];
    alpha[o] = (ox ? fx : 1.0f - fx) * (oy ? fy : 1.0f - fy) * (oz ? fz : 1.0f - fz);
    if (idx[o] < 0 && alpha[o] != 0.0f) return u;
  }
  for (int o = 0; o < 8; ++o)
    if (idx[o] >= 0) u = u + (x_c[idx[o]] - x0_c[idx[o]]) * alpha[o];
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
VD_INLINE void vd_level_moments(int K, VdActive coarse, int s, VdActive fine, VD_GLOBAL const VdCorrespondence* cons,
                                VD_GLOBAL const vd_uint* cell_start, VD_GLOBAL const vd_float4* x_f,
                                VD_GLOBAL float* moments_c) {
  int slot, X, Y, Z, GX, GY, GZ;
  vd_active_point(coarse, K, &slot, &X, &Y, &Z, &GX, &GY, &GZ);
  float acc[VD_CELL_COUNT_SLOT];
  for (int i = 0; i < VD_CELL_COUNT_SLOT; ++i) acc[i] = 0.0f;
  vd_uint count = 0u;
  float inv = 1.0f / (float)s;
  for (int d = 0; d < s * s * s; ++d) {
    int dx = d % s, dy = (d / s) % s, dz = d / (s * s);
    int x = s * X + dx, y = s * Y + dy, z = s * Z + dz;
    int kc = vd_lattice_compact(fine.lat, fine.nbr, fine.compact, slot, x, y, z);
    if (kc < 0) continue;
    vd_uint c0 = cell_start[kc], c1 = cell_start[kc + 1];
    if (c0 == c1) continue;
    count += c1 - c0;
    /* A fine cell holds constraints only when all 8 corners are active (vd_cell_corners). */
    vd_float4 xc[8];
    for (int o = 0; o < 8; ++o)
      xc[o] = x_f[vd_lattice_compact(fine.lat, fine.nbr, fine.compact, slot, x + (o & 1), y + ((o >> 1) & 1),
                                     z + (o >> 2))];
    /* The fine cell's global coordinates. */
    float fgx = (float)(s * GX + dx), fgy = (float)(s * GY + dy), fgz = (float)(s * GZ + dz);
    for (vd_uint c = c0; c < c1; ++c) {
      VdCorrespondence cc = cons[c];
      float fx = cc.canonical.x - fgx, fy = cc.canonical.y - fgy, fz = cc.canonical.z - fgz;
      vd_float4 p = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
      for (int o = 0; o < 8; ++o)
        p = p + xc[o] * ((o & 1 ? fx : 1.0f - fx) * (o & 2 ? fy : 1.0f - fy) * (o & 4 ? fz : 1.0f - fz));
      /* The coarse fractions as vd_level_constraint and vd_level_cell form them. */
      float gx = cc.canonical.x * inv - (float)GX, gy = cc.canonical.y * inv - (float)GY,
            gz = cc.canonical.z * inv - (float)GZ;
      vd_moments_add(acc, gx, gy, gz, cc.canonical.w, cc.normal, cc.canonical.w * vd_dot3(cc.normal, cc.target - p));
    }
  }
  VD_GLOBAL float* out = moments_c + (size_t)VD_CELL_MOMENT_FLOATS * (size_t)K;
  for (int i = 0; i < VD_CELL_COUNT_SLOT; ++i) out[i] = acc[i];
  out[VD_CELL_COUNT_SLOT] = (float)count;
}

/* A level's moments from the level below it instead of from the fine constraints (the two are the
 * same sums): a cell of level l + 1 is 8 cells of level l, and a constraint's weights there are
 * polynomials of its weights in the child cell. Along one axis the child at offset c (0 or 1) has
 * fraction f (g = 1 - f) and the parent F = (f + c) / 2 (G = 1 - F). At c = 0, from 1 = g + f:
 * G^2 = g^2 + fg + f^2 / 4, FG = fg / 2 + f^2 / 4, F^2 = f^2 / 4 (the quadratic weights of the
 * B^T B moments) and G = g + f / 2, F = f / 2 (the linear ones of the right-hand sides); c = 1
 * swaps f with g and F with G. The right-hand sides are the residuals at the fine state of the
 * lower level's moments (vd_level_moments), the same scalar per constraint on every level. */

/* Coefficient of the child's quadratic weight a (g^2, fg, f^2) in the parent's A (G^2, FG, F^2). */
VD_INLINE float vd_level_up2(int c, int A, int a) {
  if (c) {
    A = 2 - A;
    a = 2 - a;
  }
  if (a < A) return 0.0f;
  if (a == 2) return 0.25f;
  return A == 0 ? 1.0f : 0.5f;
}

/* Coefficient of the child's linear weight a (g, f) in the parent's A (G, F). */
VD_INLINE float vd_level_up1(int c, int A, int a) {
  if (c) {
    A = 1 - A;
    a = 1 - a;
  }
  if (a < A) return 0.0f;
  return (A == 0 && a == 0) ? 1.0f : 0.5f;
}

/* dst (27 x 6 moments) += the moments src changed along axis `axis` (0: x, 1: y, 2: z) for a child at
 * offset c there. */
VD_INLINE void vd_level_up_axis(float* dst, const float* src, int axis, int c) {
  int stride = axis == 0 ? 1 : (axis == 1 ? 3 : 9);
  VD_UNROLL
  for (int m = 0; m < 27; ++m) {
    int A = (m / stride) % 3, base = m - A * stride;
    VD_UNROLL
    for (int a = 0; a < 3; ++a) {
      float t = vd_level_up2(c, A, a);
      if (t == 0.0f) continue;
      const float* v = src + 6 * (base + a * stride);
      VD_UNROLL
      for (int e = 0; e < 6; ++e) dst[6 * m + e] += t * v[e];
    }
  }
}

/* The moments (VD_CELL_MOMENT_FLOATS at moments_c + K * that) of the cell of level `parent` whose
 * first corner is its active point K, from those of its 8 child cells on level `child` (spacing
 * ratio 2) in moments_f. The passes go axis by axis (x per child, y per pair, z per half), so each
 * child costs one axis pass rather than three. */
VD_INLINE void vd_level_moments_up(int K, VdActive parent, VdActive child, VD_GLOBAL const float* moments_f,
                                   VD_GLOBAL float* moments_c) {
  int slot, X, Y, Z;
  vd_lattice_point(parent.lat, parent.list[K], &slot, &X, &Y, &Z);
  float out[VD_BTB_FLOATS], h[VD_BTB_FLOATS], g[VD_BTB_FLOATS], mom[VD_BTB_FLOATS];
  float rhs[24];
  for (int i = 0; i < VD_BTB_FLOATS; ++i) out[i] = 0.0f;
  for (int i = 0; i < 24; ++i) rhs[i] = 0.0f;
  float count = 0.0f;
  for (int cz = 0; cz < 2; ++cz) {
    for (int i = 0; i < VD_BTB_FLOATS; ++i) h[i] = 0.0f;
    int any_z = 0;
    for (int cy = 0; cy < 2; ++cy) {
      for (int i = 0; i < VD_BTB_FLOATS; ++i) g[i] = 0.0f;
      int any_y = 0;
      for (int cx = 0; cx < 2; ++cx) {
        int kc = vd_lattice_compact(child.lat, child.nbr, child.compact, slot, 2 * X + cx, 2 * Y + cy, 2 * Z + cz);
        if (kc < 0) continue;
        VD_GLOBAL const float* src = moments_f + (size_t)VD_CELL_MOMENT_FLOATS * (size_t)kc;
        float n = src[VD_CELL_COUNT_SLOT];
        if (n == 0.0f) continue;
        count += n;
        any_y = 1;
        /* Into private memory, where vd_level_up_axis reads. */
        for (int i = 0; i < VD_BTB_FLOATS; ++i) mom[i] = src[i];
        vd_level_up_axis(g, mom, 0, cx);
        VD_UNROLL
        for (int O = 0; O < 8; ++O) VD_UNROLL
        for (int o = 0; o < 8; ++o) {
          float t = vd_level_up1(cx, O & 1, o & 1) * vd_level_up1(cy, (O >> 1) & 1, (o >> 1) & 1) *
                    vd_level_up1(cz, O >> 2, o >> 2);
          if (t == 0.0f) continue;
          for (int i = 0; i < 3; ++i) rhs[3 * O + i] += t * src[VD_CELL_RHS_SLOT + 3 * o + i];
        }
      }
      if (!any_y) continue;
      any_z = 1;
      vd_level_up_axis(h, g, 1, cy);
    }
    if (any_z) vd_level_up_axis(out, h, 2, cz);
  }
  VD_GLOBAL float* dst = moments_c + (size_t)VD_CELL_MOMENT_FLOATS * (size_t)K;
  for (int i = 0; i < VD_BTB_FLOATS; ++i) dst[i] = out[i];
  for (int i = 0; i < 24; ++i) dst[VD_CELL_RHS_SLOT + i] = rhs[i];
  dst[VD_CELL_COUNT_SLOT] = count;
}

/* Bricks for the coarse levels (the pool's bricks, docs/SPARSE_VOLUME.md "The solver on a lattice"):
 * the far corners of the coarse cell (spacing s) holding a fine point near the +x, +y or +z face of
 * its brick lie in the neighbour brick across it, which must exist for the level to hold them (a
 * dense grid always has them). For fine entry e, every such missing neighbour brick is allocated
 * (vd_brick_allocate; at rest, unobserved). The largest spacing covers the smaller ones (a point
 * reaches across only from local coordinates 8 - s up). Returns the failures. */
VD_INLINE int vd_brick_level_allocate(int e, int s, VD_GLOBAL const int* nbr, VD_GLOBAL vd_uint* keys,
                                      VD_GLOBAL int* slots, VD_GLOBAL vd_uint* slot_keys, vd_uint capacity,
                                      vd_uint pool, VD_GLOBAL vd_uint* counters) {
  int slot, x, y, z;
  vd_lattice_point(vd_lattice_bricks(1.0f, 1), e, &slot, &x, &y, &z);
  /* Steps across the + faces: 1 where the coarse cell's far corner leaves the brick. */
  int sx = x / s + 1 >= VD_BRICK / s, sy = y / s + 1 >= VD_BRICK / s, sz = z / s + 1 >= VD_BRICK / s;
  if (!(sx || sy || sz)) return 0;
  int bx, by, bz;
  vd_brick_unpack(slot_keys[slot], &bx, &by, &bz);
  int failures = 0;
  for (int o = 1; o < 8; ++o) {
    int ox = o & 1, oy = (o >> 1) & 1, oz = (o >> 2) & 1;
    if ((ox && !sx) || (oy && !sy) || (oz && !sz)) continue;
    if (nbr[27 * slot + (ox + 1) + 3 * (oy + 1) + 9 * (oz + 1)] >= 0) continue;
    failures += vd_brick_allocate_at(keys, slots, slot_keys, capacity, pool, counters, bx + ox, by + oy, bz + oz);
  }
  return failures;
}

#endif /* VD_HIERARCHY_H */
