/* Position step of the flip-flop solver (VolumeDeform section 7.1; SOLVER-NOTES.md): with the
 * rotations fixed, the positions x of the active set M solve
 *   (2 w_r L + w_d B^T B + lambda I) x = w_r sum_j (R_k + R_j)(t^_k - t^_j)
 *                                        + w_d sum_c alpha_ck w_c n_c (n_c . p_c) + lambda x_prev
 * with L the graph Laplacian of M's 6-neighbourhood and B the point-to-plane constraints, each a
 * trilinear combination of its cell's 8 corners. lambda is a small damping towards the current
 * positions that keeps components without constraints well posed.
 * B^T B is applied without being formed: constraints are grouped by cell (sorted by the compact
 * index of the cell's first corner, `cell_start` giving each group's range), one pass computes
 * r_c = w_c n_c . sum_l alpha_cl d_l per constraint, a second gathers sum alpha_ck n_c r_c per
 * point from the 8 cells the point is a corner of. Everything else is per point. */
#ifndef VD_SOLVER_H
#define VD_SOLVER_H

#include "correspondence.h"
#include "deformation.h"
#include "lattice.h"
#include "svd3.h"

typedef struct {
  /* Weights of the dense data term and the ARAP prior (paper eq. 1). */
  float w_dense;
  float w_reg;
  /* Damping towards the current positions. */
  float damping;
  /* 1: the ARAP edges carry their own weights (adaptive rigidity); 0: every weight is 1, and the
   * PCG product, the hot loop, skips loading them. */
  int weighted_edges;
} VdSolverWeights;

/* Grid coordinates of compact point k. */
VD_INLINE void vd_grid_coords(int gi, VdVolume vol, int* x, int* y, int* z) {
  *x = gi % vol.dim_x;
  int yz = gi / vol.dim_x;
  *y = yz % vol.dim_y;
  *z = yz / vol.dim_y;
}

/* The cell of canonical grid position g: compact indices of its 8 corners (corner o at offset
 * (o & 1, o >> 1 & 1, o >> 2 & 1)) and their trilinear weights. Returns 0 when a corner is not in
 * M (the constraint is then ignored). */
VD_INLINE int vd_cell_corners(vd_float4 g, VD_GLOBAL const int* compact, VdVolume vol, int* idx, float* alpha) {
  int cx = vd_min_i(vd_max_i((int)floor(g.x), 0), vol.dim_x - 2);
  int cy = vd_min_i(vd_max_i((int)floor(g.y), 0), vol.dim_y - 2);
  int cz = vd_min_i(vd_max_i((int)floor(g.z), 0), vol.dim_z - 2);
  float fx = g.x - (float)cx, fy = g.y - (float)cy, fz = g.z - (float)cz;
  for (int o = 0; o < 8; ++o) {
    int ox = o & 1, oy = (o >> 1) & 1, oz = (o >> 2) & 1;
    idx[o] = compact[vd_grid_index(vol, cx + ox, cy + oy, cz + oz)];
    if (idx[o] < 0) return 0;
    alpha[o] = (ox ? fx : 1.0f - fx) * (oy ? fy : 1.0f - fy) * (oz ? fz : 1.0f - fz);
  }
  return 1;
}

/* Compact index of the first corner of c's cell on a dense grid, -1 when the constraint is unusable
 * (on bricks: vd_sparse_constraint_cell). */
VD_INLINE int vd_constraint_cell(VdCorrespondence c, VD_GLOBAL const int* compact, VdVolume vol) {
  if (!(c.canonical.w > 0.0f)) return -1;
  int idx[8];
  float alpha[8];
  if (!vd_cell_corners(c.canonical, compact, vol, idx, alpha)) return -1;
  return idx[0];
}

/* Moves a[i] down the max-heap a[0..end) to where it belongs (vd_sort_indices' heapsort). */
VD_INLINE void vd_sift_down(VD_GLOBAL int* a, int i, int end) {
  int v = a[i];
  for (int c = 2 * i + 1; c < end; c = 2 * i + 1) {
    if (c + 1 < end && a[c + 1] > a[c]) ++c;
    if (a[c] <= v) break;
    a[i] = a[c];
    i = c;
  }
  a[i] = v;
}

/* Sorts a[0..n) ascending in place: insertion for the few constraints a fine cell holds, heapsort
 * (no recursion, no scratch) for a crowded one. */
VD_INLINE void vd_sort_indices(VD_GLOBAL int* a, int n) {
  if (n <= 24) {
    for (int i = 1; i < n; ++i) {
      int v = a[i], j = i - 1;
      for (; j >= 0 && a[j] > v; --j) a[j + 1] = a[j];
      a[j + 1] = v;
    }
    return;
  }
  for (int r = n / 2 - 1; r >= 0; --r) vd_sift_down(a, r, n);
  for (int end = n - 1; end > 0; --end) {
    int top = a[0];
    a[0] = a[end];
    a[end] = top;
    vd_sift_down(a, 0, end);
  }
}

/* The counting sort's last step for cell kc: order[] holds the indices of its constraints in
 * [cell_start[kc], cell_start[kc + 1]) in whatever order the scatter's atomics gave them; they are
 * put back into input order and copied into place. Every sum over a cell's constraints then adds
 * in the same order in every run, so a run repeats exactly. */
VD_INLINE void vd_constraint_order_cell(int kc, VD_GLOBAL const VdCorrespondence* corr,
                                        VD_GLOBAL const vd_uint* cell_start, VD_GLOBAL int* order,
                                        VD_GLOBAL VdCorrespondence* sorted, VD_GLOBAL int* sorted_cell) {
  int s = (int)cell_start[kc], e = (int)cell_start[kc + 1];
  vd_sort_indices(order + s, e - s);
  for (int c = s; c < e; ++c) {
    sorted[c] = corr[order[c]];
    sorted_cell[c] = kc;
  }
}

/* The active set M on its lattice (shared/lattice.h), as the solver's kernels see it: built in each
 * kernel from its arguments (OpenCL 1.2 kernels cannot take buffers inside a struct). */
typedef struct {
  VdLattice lat;
  /* Bricks: the 27 neighbour slots of each slot, and each slot's brick key (never read on a dense
   * grid). */
  VD_GLOBAL const int* nbr;
  VD_GLOBAL const vd_uint* slot_keys;
  /* Active index -> entry, and entry -> active index (-1 outside M). */
  VD_GLOBAL const int* list;
  VD_GLOBAL const int* compact;
} VdActive;

VD_INLINE VdActive vd_active(VdLattice lat, VD_GLOBAL const int* nbr, VD_GLOBAL const vd_uint* slot_keys,
                             VD_GLOBAL const int* list, VD_GLOBAL const int* compact) {
  VdActive a;
  a.lat = lat;
  a.nbr = nbr;
  a.slot_keys = slot_keys;
  a.list = list;
  a.compact = compact;
  return a;
}

/* Active point k's brick slot, local and global coordinates. */
VD_INLINE void vd_active_point(VdActive a, int k, int* slot, int* x, int* y, int* z, int* gx, int* gy, int* gz) {
  vd_lattice_point(a.lat, a.list[k], slot, x, y, z);
  vd_lattice_global(a.lat, a.slot_keys, *slot, *x, *y, *z, gx, gy, gz);
}

/* Rest position of active point k. */
VD_INLINE vd_float4 vd_active_rest(VdActive a, int k) {
  int slot, x, y, z;
  vd_lattice_point(a.lat, a.list[k], &slot, &x, &y, &z);
  return vd_lattice_position(a.lat, a.slot_keys, slot, x, y, z);
}

/* The cell whose first corner is active point kc, for global position g in it: compact indices of
 * its 8 corners and their trilinear weights (the fractions g - the corner's global coordinates, as
 * vd_cell_corners forms them on a dense grid). Returns 0 when a corner is not in M. */
VD_INLINE int vd_active_cell(VdActive a, int kc, vd_float4 g, int* idx, float* alpha) {
  int slot, x, y, z, gx, gy, gz;
  vd_active_point(a, kc, &slot, &x, &y, &z, &gx, &gy, &gz);
  float fx = g.x - (float)gx, fy = g.y - (float)gy, fz = g.z - (float)gz;
  int e[8];
  vd_lattice_cell_entries(a.lat, a.nbr, slot, x, y, z, e);
  for (int o = 0; o < 8; ++o) {
    int ox = o & 1, oy = (o >> 1) & 1, oz = (o >> 2) & 1;
    idx[o] = e[o] < 0 ? -1 : a.compact[e[o]];
    if (idx[o] < 0) return 0;
    alpha[o] = (ox ? fx : 1.0f - fx) * (oy ? fy : 1.0f - fy) * (oz ? fz : 1.0f - fz);
  }
  return 1;
}

/* w_c n_c . sum_l alpha_l d_l: the row of B (times its weight) of constraint c, in the cell whose
 * first corner is active point kc (-1: unusable), applied to d. The rows of B are the fine level's:
 * a coarse-only row (vd_fine_row) is 0 here, in the targets, the gathers, the cell moments and the
 * energy; the coarse levels take it from the moments (vd_level_moments) or restricted
 * (vd_level_constraint, which clears the mark). */
VD_INLINE float vd_constraint_apply(VdCorrespondence c, int kc, VdActive a, VD_GLOBAL const vd_float4* d) {
  int idx[8];
  float alpha[8];
  if (kc < 0 || !(c.canonical.w > 0.0f) || !vd_fine_row(c) || !vd_active_cell(a, kc, c.canonical, idx, alpha))
    return 0.0f;
  vd_float4 s = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  for (int o = 0; o < 8; ++o) s = s + d[idx[o]] * alpha[o];
  return c.canonical.w * vd_dot3(c.normal, s);
}

/* w_c n_c . p_c: the constraint's right-hand side value (0 for a coarse-only row, vd_fine_row). */
VD_INLINE float vd_constraint_target(VdCorrespondence c) {
  return vd_fine_row(c) ? c.canonical.w * vd_dot3(c.normal, c.target) : 0.0f;
}

/* sum over the cells point k is a corner of, over their constraints c, of alpha_ck n_c values[c];
 * with `diag` non-null also accumulates sum w_c alpha_ck^2 n_c n_c^T (row-major 3x3). */
VD_INLINE vd_float4 vd_gather_constraints(int k, VdActive a, VD_GLOBAL const VdCorrespondence* cons,
                                          VD_GLOBAL const vd_uint* cell_start, VD_GLOBAL const float* values,
                                          VdMat3* diag) {
  int slot, x, y, z, gx, gy, gz;
  vd_active_point(a, k, &slot, &x, &y, &z, &gx, &gy, &gz);
  vd_float4 acc = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  for (int o = 0; o < 8; ++o) {
    int ox = o & 1, oy = (o >> 1) & 1, oz = (o >> 2) & 1;
    int kc = vd_lattice_compact(a.lat, a.nbr, a.compact, slot, x - ox, y - oy, z - oz);
    if (kc < 0) continue;
    int cx = gx - ox, cy = gy - oy, cz = gz - oz;
    for (vd_uint c = cell_start[kc]; c < cell_start[kc + 1]; ++c) {
      VdCorrespondence cc = cons[c];
      if (!vd_fine_row(cc)) continue;
      float fx = cc.canonical.x - (float)cx, fy = cc.canonical.y - (float)cy, fz = cc.canonical.z - (float)cz;
      float w = (ox ? fx : 1.0f - fx) * (oy ? fy : 1.0f - fy) * (oz ? fz : 1.0f - fz);
      if (values) acc = acc + cc.normal * (w * values[c]);
      if (diag) {
        vd_float4 nw = cc.normal * (cc.canonical.w * w * w);
        vd_mat3_add_outer(diag, nw, cc.normal);
      }
    }
  }
  acc.w = 0.0f;
  return acc;
}

/* (L d)_k of the edge-weighted graph Laplacian: sum_j w_kj (d_k - d_j) over the neighbours (the
 * factor 2 w_r is applied by the caller). edge_w[6k + j] is the ARAP weight of edge (k, j),
 * symmetric (vd_arap_edge_weights); 1 everywhere is the paper's uniform prior. */
VD_INLINE vd_float4 vd_laplacian_apply(int k, VD_GLOBAL const int* neighbours, VD_GLOBAL const float* edge_w,
                                       int weighted, VD_GLOBAL const vd_float4* d) {
  vd_float4 acc = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  vd_float4 dk = d[k];
  if (!weighted) {
    for (int j = 0; j < 6; ++j) {
      int nb = neighbours[6 * k + j];
      if (nb >= 0) acc = acc + (dk - d[nb]);
    }
    acc.w = 0.0f;
    return acc;
  }
  for (int j = 0; j < 6; ++j) {
    int nb = neighbours[6 * k + j];
    if (nb >= 0) acc = acc + (dk - d[nb]) * edge_w[6 * k + j];
  }
  acc.w = 0.0f;
  return acc;
}

/* sum_j w_kj over the neighbours of k: the Laplacian's diagonal. */
VD_INLINE float vd_weighted_degree(int k, VD_GLOBAL const int* neighbours, VD_GLOBAL const float* edge_w) {
  float deg = 0.0f;
  for (int j = 0; j < 6; ++j)
    if (neighbours[6 * k + j] >= 0) deg += edge_w[6 * k + j];
  return deg;
}

/* A d at point k, given the constraint residuals r_c = vd_constraint_apply(c, d). */
VD_INLINE vd_float4 vd_system_apply(int k, VdActive a, VD_GLOBAL const int* neighbours, VD_GLOBAL const float* edge_w,
                                    VD_GLOBAL const VdCorrespondence* cons, VD_GLOBAL const vd_uint* cell_start,
                                    VD_GLOBAL const float* r, VD_GLOBAL const vd_float4* d, VdSolverWeights w) {
  vd_float4 q = vd_laplacian_apply(k, neighbours, edge_w, w.weighted_edges, d) * (2.0f * w.w_reg) +
                vd_gather_constraints(k, a, cons, cell_start, r, 0) * w.w_dense + d[k] * w.damping;
  q.w = 0.0f;
  return q;
}

/* t^_k - t^_j for the neighbour in direction j (-x, +x, -y, +y, -z, +z) of a grid with spacing h:
 * the rest edges of the 6-neighbourhood are axis-aligned, no grid coordinates needed. */
VD_INLINE vd_float4 vd_neighbour_edge(int j, float h) {
  float v = (j & 1) ? -h : h;
  return VD_F4(j < 2 ? v : 0.0f, (j >> 1) == 1 ? v : 0.0f, j >= 4 ? v : 0.0f, 0.0f);
}

/* Cached B^T B (section 7.1: "we pre-compute and cache B^T B before the PCG iteration"): for
 * point k and each of the 27 grid offsets o in {-1,0,1}^3, the 3x3 block
 *   w_d sum_c w_c alpha_ck alpha_cj n_c n_c^T   (j = the point at offset o)
 * over the constraints c in the cells both points are corners of. Each block is symmetric and
 * stored as 6 floats (xx, xy, xz, yy, yz, zz): 162 floats per point, with the 27 compact
 * neighbour indices (-1 outside M) beside them; the ARAP Laplacian and the damping are added to
 * the same blocks. The product then costs 27 small mat-vecs per point whatever the number of
 * constraints, which matters on the coarse levels where a cell holds thousands of them.
 *
 * Built in two passes so that each constraint is visited once, not once per corner:
 * 1. Per cell, moments of its constraints. Along one axis, the product of two corners' trilinear
 *    factors is (1-f)^2 (both corners at 0), f (1-f) (one at 0, one at 1) or f^2 (both at 1): a
 *    type t = k_axis + j_axis in {0, 1, 2}. So every block of the cell's 8x8 corner pairs is one of
 *    27 moments M[tx + 3 ty + 9 tz] = sum_c w_c P_tx(fx) P_ty(fy) P_tz(fz) n_c n_c^T, and the data
 *    right-hand side of corner o is V[o] = sum_c alpha_co w_c (n_c . p_c) n_c.
 * 2. Per point, the blocks, the data right-hand side and the Jacobi preconditioner are sums of
 *    those moments over the 8 cells the point is a corner of. */
#define VD_BTB_BLOCKS 27
#define VD_BTB_FLOATS (6 * VD_BTB_BLOCKS)
/* Per cell: the 27 symmetric moments, then the 8 corners' right-hand sides (3 floats each), then
 * the number of constraints (0: the cell has none and the rest is not read). */
#define VD_CELL_MOMENT_FLOATS (VD_BTB_FLOATS + 25)
#define VD_CELL_RHS_SLOT VD_BTB_FLOATS
#define VD_CELL_COUNT_SLOT (VD_BTB_FLOATS + 24)

/* Adds one constraint to a cell's moments (the first VD_CELL_COUNT_SLOT floats): fractions
 * (fx, fy, fz) in the cell, weight w, normal n and right-hand side value t = w n . p. */
VD_INLINE void vd_moments_add(float* acc, float fx, float fy, float fz, float w, vd_float4 n, float t) {
  float gx = 1.0f - fx, gy = 1.0f - fy, gz = 1.0f - fz;
  float px[3] = {gx * gx, fx * gx, fx * fx};
  float py[3] = {gy * gy, fy * gy, fy * fy};
  float pz[3] = {gz * gz, fz * gz, fz * fz};
  float nn[6] = {w * n.x * n.x, w * n.x * n.y, w * n.x * n.z, w * n.y * n.y, w * n.y * n.z, w * n.z * n.z};
  VD_UNROLL
  for (int m = 0; m < 27; ++m) {
    float p = px[m % 3] * py[(m / 3) % 3] * pz[m / 9];
    VD_UNROLL
    for (int e = 0; e < 6; ++e) acc[6 * m + e] += p * nn[e];
  }
  float ax[2] = {gx, fx}, ay[2] = {gy, fy}, az[2] = {gz, fz};
  VD_UNROLL
  for (int o = 0; o < 8; ++o) {
    float a = ax[o & 1] * ay[(o >> 1) & 1] * az[o >> 2] * t;
    acc[VD_CELL_RHS_SLOT + 3 * o + 0] += a * n.x;
    acc[VD_CELL_RHS_SLOT + 3 * o + 1] += a * n.y;
    acc[VD_CELL_RHS_SLOT + 3 * o + 2] += a * n.z;
  }
}

/* Moments of the constraints of the cell whose first corner is active point kc (rows
 * cell_start[kc] .. cell_start[kc + 1] of the sorted constraints); for a cell without constraints
 * only its count (0) is written (the assembly skips it). */
VD_INLINE void vd_cell_moments(int kc, VdActive a, VD_GLOBAL const VdCorrespondence* cons,
                               VD_GLOBAL const vd_uint* cell_start, VD_GLOBAL float* moments) {
  vd_uint c0 = cell_start[kc], c1 = cell_start[kc + 1];
  moments[(size_t)VD_CELL_MOMENT_FLOATS * (size_t)kc + VD_CELL_COUNT_SLOT] = (float)(c1 - c0);
  if (c0 == c1) return;
  int slot, lx, ly, lz, x, y, z;
  vd_active_point(a, kc, &slot, &lx, &ly, &lz, &x, &y, &z);
  float acc[VD_CELL_COUNT_SLOT];
  for (int i = 0; i < VD_CELL_COUNT_SLOT; ++i) acc[i] = 0.0f;
  for (vd_uint c = c0; c < c1; ++c) {
    VdCorrespondence cc = cons[c];
    if (!vd_fine_row(cc)) continue;
    vd_moments_add(acc, cc.canonical.x - (float)x, cc.canonical.y - (float)y, cc.canonical.z - (float)z, cc.canonical.w,
                   cc.normal, cc.canonical.w * vd_dot3(cc.normal, cc.target));
  }
  VD_GLOBAL float* out = moments + (size_t)VD_CELL_MOMENT_FLOATS * (size_t)kc;
  for (int i = 0; i < VD_CELL_COUNT_SLOT; ++i) out[i] = acc[i];
}

/* The inverse of a diagonal block (symmetric positive definite), by the adjugate. */
VD_INLINE VdMat3 vd_mat3_inverse_spd(VdMat3 d) {
  float det = vd_mat3_det(d);
  VdMat3 inv;
  inv.m[0] = (d.m[4] * d.m[8] - d.m[5] * d.m[7]) / det;
  inv.m[1] = (d.m[2] * d.m[7] - d.m[1] * d.m[8]) / det;
  inv.m[2] = (d.m[1] * d.m[5] - d.m[2] * d.m[4]) / det;
  inv.m[3] = (d.m[5] * d.m[6] - d.m[3] * d.m[8]) / det;
  inv.m[4] = (d.m[0] * d.m[8] - d.m[2] * d.m[6]) / det;
  inv.m[5] = (d.m[2] * d.m[3] - d.m[0] * d.m[5]) / det;
  inv.m[6] = (d.m[3] * d.m[7] - d.m[4] * d.m[6]) / det;
  inv.m[7] = (d.m[1] * d.m[6] - d.m[0] * d.m[7]) / det;
  inv.m[8] = (d.m[0] * d.m[4] - d.m[1] * d.m[3]) / det;
  return inv;
}

/* Point k's row of the position step's matrix (2 w_r L + w_d B^T B + lambda I) as 27 blocks with
 * their neighbour indices: w_d B^T B from the moments of the (up to 8) cells k is a corner of, with
 * the ARAP Laplacian and the damping folded in (on the diagonal block and the 6 face blocks), so
 * the PCG product is 27 small mat-vecs and nothing else. Returns the data right-hand side (times
 * w_d), plus (w_d B^T B x0)_k when shift (a coarse level's start, shared/hierarchy.h); the inverse
 * of the diagonal block goes to diag_inv. */
VD_INLINE vd_float4 vd_btb_assemble(int k, VdActive a, VD_GLOBAL const int* neighbours, VD_GLOBAL const float* edge_w,
                                    VD_GLOBAL const float* moments, VdSolverWeights w, VD_GLOBAL const vd_float4* x0,
                                    int shift, VD_GLOBAL float* blocks, VD_GLOBAL int* nbr, VdMat3* diag_inv) {
  int slot, x, y, z, e = a.list[k];
  vd_lattice_point(a.lat, e, &slot, &x, &y, &z);
  if (vd_lattice_interior(a.lat, x, y, z, 1)) {
    for (int o = 0; o < VD_BTB_BLOCKS; ++o)
      nbr[VD_BTB_BLOCKS * k + o] = a.compact[e + vd_lattice_offset(a.lat, o % 3 - 1, (o / 3) % 3 - 1, o / 9 - 1)];
  } else {
    for (int o = 0; o < VD_BTB_BLOCKS; ++o)
      nbr[VD_BTB_BLOCKS * k + o] =
          vd_lattice_compact(a.lat, a.nbr, a.compact, slot, x + o % 3 - 1, y + (o / 3) % 3 - 1, z + o / 9 - 1);
  }
  float acc[VD_BTB_FLOATS];
  for (int i = 0; i < VD_BTB_FLOATS; ++i) acc[i] = 0.0f;
  vd_float4 data = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  VD_UNROLL
  for (int ok = 0; ok < 8; ++ok) {
    int kx = ok & 1, ky = (ok >> 1) & 1, kz = (ok >> 2) & 1;
    /* The cell with k at corner ok starts at offset -ok: one of the 27 just looked up. */
    int kc = nbr[VD_BTB_BLOCKS * k + (1 - kx) + 3 * (1 - ky) + 9 * (1 - kz)];
    if (kc < 0) continue;
    VD_GLOBAL const float* mom = moments + (size_t)VD_CELL_MOMENT_FLOATS * (size_t)kc;
    if (mom[VD_CELL_COUNT_SLOT] == 0.0f) continue;
    VD_UNROLL
    for (int oj = 0; oj < 8; ++oj) {
      int jx = oj & 1, jy = (oj >> 1) & 1, jz = (oj >> 2) & 1;
      int b = (jx - kx + 1) + 3 * (jy - ky + 1) + 9 * (jz - kz + 1);
      int m = (kx + jx) + 3 * (ky + jy) + 9 * (kz + jz);
      VD_UNROLL
      for (int e = 0; e < 6; ++e) acc[6 * b + e] += mom[6 * m + e];
    }
    VD_GLOBAL const float* v = mom + VD_BTB_FLOATS + 3 * ok;
    data = data + VD_F4(v[0], v[1], v[2], 0.0f);
  }
  if (shift) {
    for (int o = 0; o < VD_BTB_BLOCKS; ++o) {
      int j = nbr[VD_BTB_BLOCKS * k + o];
      if (j < 0) continue;
      vd_float4 p = x0[j];
      const float* c = acc + 6 * o;
      data = data + VD_F4(c[0] * p.x + c[1] * p.y + c[2] * p.z, c[1] * p.x + c[3] * p.y + c[4] * p.z,
                          c[2] * p.x + c[4] * p.y + c[5] * p.z, 0.0f);
    }
  }
  for (int i = 0; i < VD_BTB_FLOATS; ++i) acc[i] *= w.w_dense;
  /* The Laplacian: -2 w_r w_kj I on the block of face neighbour j (directions -x, +x, -y, +y, -z,
   * +z: offsets 12, 14, 10, 16, 4, 22), 2 w_r deg_k I + lambda I on the diagonal block (13). */
  float deg = 0.0f;
  for (int j = 0; j < 6; ++j) {
    if (neighbours[6 * k + j] < 0) continue;
    float wj = w.weighted_edges ? edge_w[6 * k + j] : 1.0f;
    int o = 13 + ((j & 1) ? 1 : -1) * ((j >> 1) == 0 ? 1 : ((j >> 1) == 1 ? 3 : 9));
    acc[6 * o + 0] -= 2.0f * w.w_reg * wj;
    acc[6 * o + 3] -= 2.0f * w.w_reg * wj;
    acc[6 * o + 5] -= 2.0f * w.w_reg * wj;
    deg += wj;
  }
  float s = 2.0f * w.w_reg * deg + w.damping;
  acc[6 * 13 + 0] += s;
  acc[6 * 13 + 3] += s;
  acc[6 * 13 + 5] += s;
  VD_GLOBAL float* out = blocks + (size_t)VD_BTB_FLOATS * (size_t)k;
  for (int i = 0; i < VD_BTB_FLOATS; ++i) out[i] = acc[i];
  const float* c = acc + 6 * 13;
  VdMat3 diag;
  diag.m[0] = c[0];
  diag.m[1] = c[1];
  diag.m[2] = c[2];
  diag.m[3] = c[1];
  diag.m[4] = c[3];
  diag.m[5] = c[4];
  diag.m[6] = c[2];
  diag.m[7] = c[4];
  diag.m[8] = c[5];
  *diag_inv = vd_mat3_inverse_spd(diag);
  data = data * w.w_dense;
  data.w = 0.0f;
  return data;
}

/* (A d)_k from the cached blocks of vd_btb_assemble (the whole matrix, ARAP and damping included). */
VD_INLINE vd_float4 vd_system_apply_cached(int k, VD_GLOBAL const float* blocks, VD_GLOBAL const int* nbr,
                                           VD_GLOBAL const vd_float4* d) {
  VD_GLOBAL const float* m = blocks + (size_t)VD_BTB_FLOATS * (size_t)k;
  float qx = 0.0f, qy = 0.0f, qz = 0.0f;
  for (int o = 0; o < VD_BTB_BLOCKS; ++o) {
    int j = nbr[VD_BTB_BLOCKS * k + o];
    if (j < 0) continue;
    vd_float4 v = d[j];
    VD_GLOBAL const float* b = m + 6 * o;
    qx += b[0] * v.x + b[1] * v.y + b[2] * v.z;
    qy += b[1] * v.x + b[3] * v.y + b[4] * v.z;
    qz += b[2] * v.x + b[4] * v.y + b[5] * v.z;
  }
  return VD_F4(qx, qy, qz, 0.0f);
}

/* The ARAP part of the right-hand side at point k: sum_j w_kj (R_k + R_j)(t^_k - t^_j) (times w_r
 * by the caller). It changes with the rotations, so it is recomputed every position step. R_k is
 * applied once, to the weighted sum of the edges (7 rotations instead of 12). */
VD_INLINE vd_float4 vd_system_reg_rhs(int k, float spacing, VD_GLOBAL const int* neighbours,
                                      VD_GLOBAL const float* edge_w, VD_GLOBAL const vd_float4* rot) {
  vd_float4 reg = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  vd_float4 edges = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  for (int j = 0; j < 6; ++j) {
    int nb = neighbours[6 * k + j];
    if (nb < 0) continue;
    vd_float4 e = vd_neighbour_edge(j, spacing) * edge_w[6 * k + j];
    edges = edges + e;
    reg = reg + vd_quat_rotate(rot[nb], e);
  }
  reg = reg + vd_quat_rotate(rot[k], edges);
  reg.w = 0.0f;
  return reg;
}

/* The parts of the system at point k that depend only on the constraints, computed once per
 * solve (the paper caches B^T B for the same reason): the data right-hand side
 * w_d sum_c alpha_ck n_c (w_c n_c . p_c) (returned) and the inverse of the 3x3 diagonal block
 * 2 w_r deg_k I + w_d sum_c w_c alpha_ck^2 n_c n_c^T + lambda I, the Jacobi preconditioner. */
VD_INLINE vd_float4 vd_system_data_diag(int k, VdActive a, VD_GLOBAL const int* neighbours,
                                        VD_GLOBAL const float* edge_w, VD_GLOBAL const VdCorrespondence* cons,
                                        VD_GLOBAL const vd_uint* cell_start, VD_GLOBAL const float* targets,
                                        VdSolverWeights w, VdMat3* diag_inv) {
  VdMat3 diag = vd_mat3_zero();
  vd_float4 data = vd_gather_constraints(k, a, cons, cell_start, targets, &diag);
  float s = 2.0f * w.w_reg * vd_weighted_degree(k, neighbours, edge_w) + w.damping;
  for (int a = 0; a < 9; ++a) diag.m[a] *= w.w_dense;
  diag.m[0] += s;
  diag.m[4] += s;
  diag.m[8] += s;
  /* Symmetric positive definite (s > 0). */
  *diag_inv = vd_mat3_inverse_spd(diag);
  data = data * w.w_dense;
  data.w = 0.0f;
  return data;
}

/* Right-hand side b_k = w_r reg_k + data_k + lambda x_prev_k, from the cached data part. */
VD_INLINE vd_float4 vd_system_rhs(int k, float spacing, VD_GLOBAL const int* neighbours, VD_GLOBAL const float* edge_w,
                                  VD_GLOBAL const vd_float4* rot, VD_GLOBAL const vd_float4* data_rhs,
                                  VD_GLOBAL const vd_float4* x_prev, VdSolverWeights w) {
  vd_float4 b = vd_system_reg_rhs(k, spacing, neighbours, edge_w, rot) * w.w_reg + data_rhs[k] + x_prev[k] * w.damping;
  b.w = 0.0f;
  return b;
}

/* PCG with its scalars on the device: the Chronopoulos/Gear form of preconditioned CG (Ghysels and
 * Vanroose, "Hiding global synchronization latency in the preconditioned Conjugate Gradient
 * algorithm", 2014, algorithm 2). With u = M^-1 r and w = A u,
 *   p = u + beta p,  s = w + beta s,  x += alpha p,  r -= alpha s,  u = M^-1 r,  r.r  (vd_pcg_cg_update)
 *   w = A u,  gamma' = r.u,  delta = w.u                                            (vd_pcg_dots)
 *   beta = gamma' / gamma,  alpha = gamma' / (delta - beta gamma' / alpha)           (vd_pcg_scalars)
 * the same iterates as the textbook form in exact arithmetic (s = A p), but both dots of the step
 * sizes come from the pass of the product, so an iteration is four launches (update with r.r,
 * convergence test, product with dots, step sizes) instead of seven, and no pass only re-reads
 * vectors for a dot. The scalars live in a small buffer of VD_PCG_SCALARS floats that single-item
 * kernels update from partial sums and the vector kernels read. Once converged (r.r <= stop, or
 * a non-positive curvature), alpha and beta are 0 and further updates leave x unchanged; the host
 * reads the buffer once per iteration, after the convergence test and before the product, so
 * that the last product is never wasted. */
#define VD_PCG_GAMMA 0
#define VD_PCG_RR 1
#define VD_PCG_ALPHA 2
#define VD_PCG_BETA 3
#define VD_PCG_STOP 4
#define VD_PCG_CONVERGED 5
#define VD_PCG_SCALARS 8
/* What vd_pcg_scalars does with its partial sums. */
#define VD_PCG_SET_STOP 0  /* partials of b.b: stop = tol^2 max(b.b, 1e-30), not converged */
#define VD_PCG_SET_START 1 /* triples (r.u, w.u, r.r) of the start: alpha = gamma / delta, beta = 0 */
#define VD_PCG_SET_RR 2    /* partials of r.r after an update: the convergence test */
#define VD_PCG_SET_NEXT 3  /* triples after the product: beta and alpha of the next update */
/* Work items per work-group of the kernels that reduce within a group (ocl::Context::kGroupSize),
 * so the number of partial sums of m points is ceil(m / VD_PCG_GROUP). */
#define VD_PCG_GROUP 64

/* Compensated sum of n floats at stride `stride` from `first`. */
VD_INLINE float vd_sum_partials(VD_GLOBAL const float* partials, int n, int first, int stride) {
  float s = 0.0f, c = 0.0f;
  for (int i = 0; i < n; ++i) {
    float y = partials[first + i * stride] - c;
    float t = s + y;
    c = (t - s) - y;
    s = t;
  }
  return s;
}

/* The single item of vd_pcg_scalars: `groups` partial sums (triples for START and NEXT). */
VD_INLINE void vd_pcg_scalars(VD_GLOBAL const float* partials, int groups, int mode, float tolerance,
                              VD_GLOBAL float* scal) {
  if (mode == VD_PCG_SET_STOP) {
    float bb = vd_sum_partials(partials, groups, 0, 1);
    scal[VD_PCG_STOP] = tolerance * tolerance * fmax(bb, 1e-30f);
    scal[VD_PCG_CONVERGED] = 0.0f;
    scal[VD_PCG_ALPHA] = 0.0f;
    scal[VD_PCG_BETA] = 0.0f;
    return;
  }
  int go = scal[VD_PCG_CONVERGED] == 0.0f;
  if (mode == VD_PCG_SET_RR) {
    float rr = vd_sum_partials(partials, groups, 0, 1);
    if (go) scal[VD_PCG_RR] = rr;
    if (go && !(rr > scal[VD_PCG_STOP])) {
      scal[VD_PCG_CONVERGED] = 1.0f;
      scal[VD_PCG_ALPHA] = 0.0f;
      scal[VD_PCG_BETA] = 0.0f;
    }
    return;
  }
  float ru = vd_sum_partials(partials, groups, 0, 3);
  float wu = vd_sum_partials(partials, groups, 1, 3);
  float beta = 0.0f, denom = wu;
  if (mode == VD_PCG_SET_START) {
    float rr = vd_sum_partials(partials, groups, 2, 3);
    if (go) scal[VD_PCG_RR] = rr;
    go = go && rr > scal[VD_PCG_STOP];
  } else {
    float gamma = scal[VD_PCG_GAMMA], alpha = scal[VD_PCG_ALPHA];
    go = go && gamma > 0.0f && alpha > 0.0f;
    beta = go ? ru / gamma : 0.0f;
    denom = go ? wu - beta * ru / alpha : 0.0f;
  }
  /* M and A are positive definite: r.u > 0 and a positive curvature, unless converged or broken. */
  go = go && ru > 0.0f && denom > 0.0f;
  scal[VD_PCG_ALPHA] = go ? ru / denom : 0.0f;
  scal[VD_PCG_BETA] = go ? beta : 0.0f;
  if (go) scal[VD_PCG_GAMMA] = ru;
  if (!go) scal[VD_PCG_CONVERGED] = 1.0f;
}

/* An unsolved frame of a static field (EngineParams::static_solve_every) counts for the point the
 * solve would have written back (list entry k) as an optimisation that left it where it was: the
 * count in w grows by one, as vd_solver_scatter_state's does, so fusion (k_min, k_min_new) starts
 * as early as when every frame is solved. */
VD_INLINE void vd_count_optimisation(int k, VD_GLOBAL const int* list, VD_GLOBAL vd_float4* def_pos) {
  def_pos[list[k]].w += 1.0f;
}

/* Whether the PCG has converged (or broken down): the host learns it one iteration late (it queues
 * the next product and update before it reads the test), so those are skipped on the device: the
 * product and the update return at once, leaving x, r, w and the partial sums as they were. */
VD_INLINE int vd_pcg_done(VD_GLOBAL const float* scal) { return scal[VD_PCG_CONVERGED] != 0.0f; }

/* One update at point k (xyz; alpha and beta from scal): p = u + beta p, s = w + beta s,
 * x += alpha p, r -= alpha s, u = M^-1 r; returns the new r.r term. At the start (beta 0) p and s
 * are not read. */
VD_INLINE float vd_pcg_cg_update(int k, VD_GLOBAL const float* scal, VD_GLOBAL const VdMat3* diag_inv,
                                 VD_GLOBAL const vd_float4* w, VD_GLOBAL vd_float4* p, VD_GLOBAL vd_float4* s,
                                 VD_GLOBAL vd_float4* x, VD_GLOBAL vd_float4* r, VD_GLOBAL vd_float4* u) {
  float a = scal[VD_PCG_ALPHA], b = scal[VD_PCG_BETA];
  vd_float4 pk = b != 0.0f ? u[k] + p[k] * b : u[k];
  vd_float4 sk = b != 0.0f ? w[k] + s[k] * b : w[k];
  pk.w = 0.0f;
  sk.w = 0.0f;
  p[k] = pk;
  s[k] = sk;
  vd_float4 xk = x[k] + pk * a;
  xk.w = x[k].w;
  x[k] = xk;
  vd_float4 rk = r[k] - sk * a;
  rk.w = 0.0f;
  r[k] = rk;
  u[k] = vd_mat3_apply(diag_inv[k], rk);
  return vd_dot3(rk, rk);
}

/* The start of a position step at point k from the current x (also the damping's anchor):
 * b_k (vd_system_rhs), r_k = b_k - (A x)_k from the cached blocks and u_k = M^-1 r_k, in one pass
 * instead of four; returns the term of b.b (the scale of the convergence test). */
VD_INLINE float vd_pcg_start(int k, float spacing, VD_GLOBAL const int* neighbours, VD_GLOBAL const float* edge_w,
                             VD_GLOBAL const vd_float4* rot, VD_GLOBAL const vd_float4* data_rhs, VdSolverWeights w,
                             VD_GLOBAL const float* blocks, VD_GLOBAL const int* nbr, VD_GLOBAL const VdMat3* diag_inv,
                             VD_GLOBAL const vd_float4* x, VD_GLOBAL vd_float4* r, VD_GLOBAL vd_float4* u) {
  vd_float4 b = vd_system_rhs(k, spacing, neighbours, edge_w, rot, data_rhs, x, w);
  vd_float4 rk = b - vd_system_apply_cached(k, blocks, nbr, x);
  rk.w = 0.0f;
  r[k] = rk;
  u[k] = vd_mat3_apply(diag_inv[k], rk);
  return vd_dot3(b, b);
}

/* Point k's terms of the three dots after a product: (r.u, w.u, r.r). */
VD_INLINE void vd_pcg_dots(int k, VD_GLOBAL const vd_float4* r, VD_GLOBAL const vd_float4* u,
                           VD_GLOBAL const vd_float4* w, float* out) {
  out[0] = vd_dot3(r[k], u[k]);
  out[1] = vd_dot3(w[k], u[k]);
  out[2] = vd_dot3(r[k], r[k]);
}

/* Energy terms (paper eqs. 2 and 4) for tests and the status: one constraint's weighted squared
 * point-to-plane residual, and one point's ARAP sum over its neighbours. */
VD_INLINE float vd_constraint_energy(VdCorrespondence c, int kc, VdActive a, VD_GLOBAL const vd_float4* x) {
  int idx[8];
  float alpha[8];
  if (kc < 0 || !(c.canonical.w > 0.0f) || !vd_fine_row(c) || !vd_active_cell(a, kc, c.canonical, idx, alpha))
    return 0.0f;
  vd_float4 s = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  for (int o = 0; o < 8; ++o) s = s + x[idx[o]] * alpha[o];
  float r = vd_dot3(c.normal, s - c.target);
  return c.canonical.w * r * r;
}

VD_INLINE float vd_arap_energy(int k, VD_GLOBAL const int* neighbours, VD_GLOBAL const float* edge_w, float spacing,
                               VD_GLOBAL const vd_float4* x, VD_GLOBAL const vd_float4* rot) {
  float e = 0.0f;
  for (int j = 0; j < 6; ++j) {
    int nb = neighbours[6 * k + j];
    if (nb < 0) continue;
    vd_float4 d = (x[k] - x[nb]) - vd_quat_rotate(rot[k], vd_neighbour_edge(j, spacing));
    d.w = 0.0f;
    e += edge_w[6 * k + j] * vd_dot3(d, d);
  }
  return e;
}

/* Adaptive rigidity (beyond the paper, whose section 10 names the uniform ARAP weight a
 * limitation): the weights of point k's six edges from the strain of the current field,
 * w_kj = max(floor, 1 / (1 + e_kj / scale^2)) with e_kj = (|r_kj|^2 + |r_jk|^2) / 2 and
 * r_kj = (x_k - x_j) - R_k (t^_k - t^_j): the same formula from either end, so the weights are
 * symmetric. Where the field bends sharply (the rotations change fast between neighbours), the
 * prior gives way instead of smoothing the bend; a rigid part keeps weight 1. */
VD_INLINE void vd_arap_edge_weights(int k, VD_GLOBAL const int* neighbours, VD_GLOBAL const vd_float4* x,
                                    VD_GLOBAL const vd_float4* rot, VD_GLOBAL const vd_float4* t_hat, float scale2,
                                    float floor_w, VD_GLOBAL float* edge_w) {
  vd_float4 xk = x[k], hk = t_hat[k], qk = rot[k];
  for (int j = 0; j < 6; ++j) {
    int nb = neighbours[6 * k + j];
    float w = 0.0f;
    if (nb >= 0) {
      vd_float4 dx = xk - x[nb], dh = hk - t_hat[nb];
      vd_float4 r_kj = dx - vd_quat_rotate(qk, dh);
      vd_float4 r_jk = vd_quat_rotate(rot[nb], dh) - dx;
      float e = 0.5f * (vd_dot3(r_kj, r_kj) + vd_dot3(r_jk, r_jk));
      w = fmax(floor_w, 1.0f / (1.0f + e / scale2));
    }
    edge_w[6 * k + j] = w;
  }
}

#endif /* VD_SOLVER_H */
