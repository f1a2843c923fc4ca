/* Sparse colour features (VolumeDeform section 5.2): descriptor matching against earlier frames,
 * the pruning rules, and the lifting of observed keypoints into the canonical pose (S^-1).
 *
 * Matching: the current frame's n_cur descriptors (128 bytes each, SIFT values 0..255) against
 * a set of earlier frames whose descriptors lie one after another in a candidate buffer (stored
 * transposed, see vd_match_distances_column). One
 * pass computes the squared L2 distance matrix D[a * n_cand + b]; the row pass finds, per current
 * feature a and candidate frame f, the nearest and second-nearest candidate of f; the column pass
 * finds, per candidate b, the nearest current feature. A pair (a, b) is a match in both directions
 * when row(a, f).best == b and col(b).best == a. The squared distances are sums of integer squares
 * below 2^24, exact in float, so kernel and CPU reference agree bit for bit.
 *
 * Lifting: an observed point f (world) is stored at the canonical point g with S(g) = f. The
 * start is the canonical point the rasterised live mesh shows at the keypoint's pixel (its
 * triangle's canonical vertices with the pixel's barycentrics); Newton steps with the exact
 * Jacobian of the trilinear S then solve S(g) = f. */
#ifndef VD_FEATURES_H
#define VD_FEATURES_H

#include "deformation.h"
#include "raster.h"
#include "sparse_field.h"
#include "svd3.h"
#include "vd_types.h"

#define VD_DESC_BYTES 128
/* No candidate / no match. */
#define VD_MATCH_NONE (-1)

/* Nearest and second-nearest of a scan; d2 values are squared distances. */
typedef struct {
  int best;
  float best_d2;
  float second_d2;
  int pad0;
} VdMatchBest;

VD_INLINE float vd_desc_dist2(VD_GLOBAL const vd_uchar* a, VD_GLOBAL const vd_uchar* b) {
  float s = 0.0f;
  for (int i = 0; i < VD_DESC_BYTES; ++i) {
    float d = (float)a[i] - (float)b[i];
    s += d * d;
  }
  return s;
}

/* Candidate b against every current descriptor: column b of D. The candidates are stored
 * transposed (byte j of candidate b at cand_t[j * n_cand + b]) so neighbouring work items read
 * neighbouring bytes; a device then loads whole vectors instead of gathering 128-byte strides. */
VD_INLINE void vd_match_distances_column(int b, VD_GLOBAL const vd_uchar* cur, int n_cur,
                                         VD_GLOBAL const vd_uchar* cand_t, int n_cand, VD_GLOBAL float* dist) {
  /* The candidate stays in private memory while every current descriptor streams past. */
  int mine[VD_DESC_BYTES];
  for (int j = 0; j < VD_DESC_BYTES; ++j) mine[j] = (int)cand_t[(size_t)j * n_cand + b];
  for (int a = 0; a < n_cur; ++a) {
    VD_GLOBAL const vd_uchar* da = cur + (size_t)a * VD_DESC_BYTES;
    /* Integer arithmetic: exact, and free to be reordered and vectorised. */
    int s = 0;
    for (int j = 0; j < VD_DESC_BYTES; ++j) {
      int d = (int)da[j] - mine[j];
      s += d * d;
    }
    dist[(size_t)a * n_cand + b] = (float)s;
  }
}

/* Transposes n descriptors (row-major, 128 bytes each) into the layout above. */
VD_INLINE void vd_desc_transpose(VD_GLOBAL const vd_uchar* rows, int n, VD_GLOBAL vd_uchar* cols) {
  for (int b = 0; b < n; ++b)
    for (int j = 0; j < VD_DESC_BYTES; ++j) cols[(size_t)j * n + b] = rows[(size_t)b * VD_DESC_BYTES + j];
}

/* Row scan of current feature a over the candidates [begin, end) of one frame. Ties keep the
 * lower index. */
VD_INLINE VdMatchBest vd_match_row(int a, int begin, int end, VD_GLOBAL const float* dist, int n_cand) {
  VdMatchBest r;
  r.best = VD_MATCH_NONE;
  r.best_d2 = 3.4e38f;
  r.second_d2 = 3.4e38f;
  r.pad0 = 0;
  VD_GLOBAL const float* row = dist + (size_t)a * n_cand;
  for (int b = begin; b < end; ++b) {
    float d = row[b];
    if (d < r.best_d2) {
      r.second_d2 = r.best_d2;
      r.best_d2 = d;
      r.best = b;
    } else if (d < r.second_d2) {
      r.second_d2 = d;
    }
  }
  return r;
}

/* Column scan of candidate b over the current features. */
VD_INLINE VdMatchBest vd_match_column(int b, int n_cur, VD_GLOBAL const float* dist, int n_cand) {
  VdMatchBest r;
  r.best = VD_MATCH_NONE;
  r.best_d2 = 3.4e38f;
  r.second_d2 = 3.4e38f;
  r.pad0 = 0;
  for (int a = 0; a < n_cur; ++a) {
    float d = dist[(size_t)a * n_cand + b];
    if (d < r.best_d2) {
      r.second_d2 = r.best_d2;
      r.best_d2 = d;
      r.best = a;
    } else if (d < r.second_d2) {
      r.second_d2 = d;
    }
  }
  return r;
}

/* Pruning thresholds (section 5.2: not close enough in feature space, screen space or 3D). */
typedef struct {
  /* Largest descriptor distance (L2 of the 0..255 SIFT values; unit-length descriptors scaled
   * by 512, so 512 is as far apart as two descriptors get). */
  float max_descriptor_distance;
  /* Lowe's ratio: nearest / second nearest distance within the candidate frame. */
  float max_ratio;
  /* Pixels between the keypoint and the earlier feature projected into the current camera. */
  float max_screen_distance;
  /* Metres between the observed point and the earlier feature moved by the current field. */
  float max_world_distance;
} VdMatchPrune;

/* Why a mutual match is dropped: 0 = kept. */
#define VD_PRUNE_KEPT 0
#define VD_PRUNE_DESCRIPTOR 1
#define VD_PRUNE_RATIO 2
#define VD_PRUNE_SCREEN 3
#define VD_PRUNE_WORLD 4
#define VD_PRUNE_NO_POSITION 5

/* `m`: the row scan of the current feature within the candidate frame; `predicted`: the earlier
 * feature moved by the current field (world, w = 1 valid); `observed`: the current keypoint's
 * point (world); `predicted_px` - `observed_px`: its screen offset (w = 1 when in front). */
VD_INLINE int vd_match_prune(VdMatchBest m, vd_float4 predicted, vd_float4 observed, float du, float dv,
                             VdMatchPrune p) {
  float d = sqrt(m.best_d2);
  if (!(d <= p.max_descriptor_distance)) return VD_PRUNE_DESCRIPTOR;
  if (m.second_d2 < 3.0e38f && !(d <= p.max_ratio * sqrt(m.second_d2))) return VD_PRUNE_RATIO;
  if (!(predicted.w > 0.0f)) return VD_PRUNE_NO_POSITION;
  if (!(du * du + dv * dv <= p.max_screen_distance * p.max_screen_distance)) return VD_PRUNE_SCREEN;
  vd_float4 e = predicted - observed;
  if (!(vd_dot3(e, e) <= p.max_world_distance * p.max_world_distance)) return VD_PRUNE_WORLD;
  return VD_PRUNE_KEPT;
}

/* Solves a x = b by Cramer's rule; returns 0 when a is (nearly) singular. */
VD_INLINE int vd_mat3_solve(VdMat3 a, vd_float4 b, vd_float4* x) {
  float det = vd_mat3_det(a);
  float scale = vd_mat3_max_abs(a);
  if (!(fabs(det) > 1e-9f * scale * scale * scale)) return 0;
  float inv = 1.0f / det;
  x->x = (b.x * (a.m[4] * a.m[8] - a.m[5] * a.m[7]) - a.m[1] * (b.y * a.m[8] - a.m[5] * b.z) +
          a.m[2] * (b.y * a.m[7] - a.m[4] * b.z)) * inv;
  x->y = (a.m[0] * (b.y * a.m[8] - a.m[5] * b.z) - b.x * (a.m[3] * a.m[8] - a.m[5] * a.m[6]) +
          a.m[2] * (a.m[3] * b.z - b.y * a.m[6])) * inv;
  x->z = (a.m[0] * (a.m[4] * b.z - b.y * a.m[7]) - a.m[1] * (a.m[3] * b.z - b.y * a.m[6]) +
          b.x * (a.m[3] * a.m[7] - a.m[4] * a.m[6])) * inv;
  x->w = 0.0f;
  return 1;
}

/* Lifting parameters. */
typedef struct {
  VdPose world_to_cam;
  /* The rendered surface at the keypoint must lie within this of the observed depth (metres):
   * otherwise the pixel shows an occluder or a part the model does not have yet. */
  float max_depth_gap;
  /* Newton stops when |S(g) - f| falls below this (metres); a lift that does not get there fails. */
  float tolerance;
  int iterations;
  /* 1: the grid has no surface yet (the first frame): start from the undeformed position. */
  int no_model;
} VdLiftParams;

/* Canonical grid position of the observed point `f` (world; w = 1 valid) seen at `pix`; w of the
 * result is 1 on success, 0 when the point cannot be lifted. */
VD_INLINE vd_float4 vd_feature_lift(vd_float4 f, int pix, VD_GLOBAL const vd_uint* ids, VD_GLOBAL const vd_float4* bary,
                                    VD_GLOBAL const vd_float4* raster_vertex, VD_GLOBAL const vd_float4* canon,
                                    VD_GLOBAL const int* tris, VD_FIELD_ARGS, VdLiftParams p) {
  vd_float4 fail = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  if (!(f.w > 0.0f)) return fail;
  vd_float4 g;
  if (p.no_model) {
    float inv = 1.0f / vol.voxel_size;
    g = VD_F4((f.x - vol.origin.x) * inv, (f.y - vol.origin.y) * inv, (f.z - vol.origin.z) * inv, 0.0f);
  } else {
    if (pix < 0) return fail;
    vd_uint t = ids[pix];
    if (t == VD_RASTER_EMPTY) return fail;
    vd_float4 rv = raster_vertex[pix];
    vd_float4 fc = vd_pose_apply(p.world_to_cam, f);
    if (!(fabs(rv.z - fc.z) <= p.max_depth_gap)) return fail;
    vd_float4 b = bary[pix];
    g = canon[tris[3 * t]] * b.x + canon[tris[3 * t + 1]] * b.y + canon[tris[3 * t + 2]] * b.z;
  }
  for (int it = 0; it < p.iterations; ++it) {
    if (!vd_field_contains(g, vol, keys)) return fail;
    VdMat3 J;
    vd_float4 s = vd_field_deform(g, VD_FIELD_PASS, &J);
    vd_float4 r = f - s;
    r.w = 0.0f;
    if (vd_dot3(r, r) <= p.tolerance * p.tolerance) {
      g.w = 1.0f;
      return g;
    }
    vd_float4 step;
    if (!vd_mat3_solve(J, r, &step)) return fail;
    g = g + step;
    g.w = 0.0f;
  }
  /* Converged on the last step? */
  if (!vd_field_contains(g, vol, keys)) return fail;
  VdMat3 J;
  vd_float4 s = vd_field_deform(g, VD_FIELD_PASS, &J);
  vd_float4 r = f - s;
  if (vd_dot3(r, r) <= p.tolerance * p.tolerance) {
    g.w = 1.0f;
    return g;
  }
  return fail;
}

/* A canonical feature moved by the current field (world, w = 1), or w = 0 for an invalid one. */
VD_INLINE vd_float4 vd_feature_predict(vd_float4 g, VD_FIELD_ARGS) {
  if (!(g.w > 0.0f)) return VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  VdMat3 J;
  return vd_field_deform(g, VD_FIELD_PASS, &J);
}

#endif /* VD_FEATURES_H */
