/* Projective dense correspondences (VolumeDeform section 5.1). The deformed mesh P is rasterised
 * at the current camera (so a model sample and its observation share a pixel); each sample p_c
 * is paired with the observed point p_a at that pixel and weighted with the kernels
 * Phi_r(x) = 1 - x / eps_r for distance |p_c - p_a|, normal deviation 1 - n_c.n_a and view
 * 1 - n_c.v (v towards the camera). A pair is pruned when any Phi < 0, else
 * w_c = ((Phi_d + Phi_n + Phi_v) / 3)^2. The constraint is expressed in the field's frame (world):
 * target T p_a and normal R n_a, and keeps the sample's canonical position in grid units (its cell
 * and trilinear weights), the barycentric combination of its triangle's canonical vertices. */
#ifndef VD_CORRESPONDENCE_H
#define VD_CORRESPONDENCE_H

#include "preprocess.h"
#include "vd_types.h"

typedef struct {
  /* Canonical position of the model sample in grid units; w = confidence w_c (0 = pruned). */
  vd_float4 canonical;
  /* Observed point in world (field) coordinates; w: a brick slot near the sample on the bricks
   * (its triangle's first vertex's owner, vd_sparse_constraint_cell), so that its cell is found
   * without probing the brick table; -1 (or anything not a slot next to the cell) for none. */
  vd_float4 target;
  /* The observed normal in world coordinates; w: VD_CORR_COARSE_ONLY for a row only the coarse
   * levels solve (vd_fine_row), else 0. */
  vd_float4 normal;
} VdCorrespondence;

/* normal.w of a row that enters only the hierarchy's coarse levels: the dense colour term's. Its
 * evidence is the slide along the surface that depth cannot see, which accumulates as a smooth,
 * low-frequency error (the bend's strain, docs/BENCHMARKS.md "Session 28"); on the fine level the
 * same rows also pulled on each point by the image's fine grain and noise (the rigid scene's
 * non-rigid displacement 0.66 -> 0.85 mm over 150 frames, "Session 29"). */
#define VD_CORR_COARSE_ONLY 1.0f

/* Whether the fine level solves row c (every row but the coarse-only ones). */
VD_INLINE int vd_fine_row(VdCorrespondence c) { return c.normal.w != VD_CORR_COARSE_ONLY; }

typedef struct {
  /* Thresholds of the kernels: distance (metres), normal deviation and view (1 - cos). */
  float eps_d, eps_n, eps_v;
  float pad0;
  /* The current camera, camera to world. */
  VdPose cam_to_world;
} VdCorrParams;

VD_INLINE float vd_corr_weight(float dist, float n_dot, float view_dot, VdCorrParams prm) {
  float pd = 1.0f - dist / prm.eps_d;
  float pn = 1.0f - (1.0f - n_dot) / prm.eps_n;
  float pv = 1.0f - (1.0f - view_dot) / prm.eps_v;
  if (pd < 0.0f || pn < 0.0f || pv < 0.0f) return 0.0f;
  float m = (pd + pn + pv) / 3.0f;
  return m * m;
}

/* The hint a constraint on a sample of triangle t carries (target.w): its first vertex's owning
 * brick slot (owners: DeviceMesh::brick_slots of a mesh over the bricks; null otherwise: -1). */
VD_INLINE float vd_corr_slot_hint(VD_GLOBAL const int* owners, VD_GLOBAL const int* tris, vd_uint t) {
  return owners ? (float)owners[tris[3 * t]] : -1.0f;
}

/* Pixel i: model maps (camera coordinates, from the rasteriser), triangle ids and barycentrics,
 * the observed vertex and normal maps (camera coordinates), the canonical mesh and its vertices'
 * owning brick slots (null for none). */
VD_INLINE VdCorrespondence vd_correspondence_pixel(int i, VD_GLOBAL const vd_float4* model_v,
                                                   VD_GLOBAL const vd_float4* model_n, VD_GLOBAL const vd_uint* ids,
                                                   VD_GLOBAL const vd_float4* bary, VD_GLOBAL const vd_float4* obs_v,
                                                   VD_GLOBAL const vd_float4* obs_n, VD_GLOBAL const vd_float4* canon,
                                                   VD_GLOBAL const int* tris, VD_GLOBAL const int* owners,
                                                   VdCorrParams prm) {
  VdCorrespondence c;
  c.canonical = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  c.target = VD_F4(0.0f, 0.0f, 0.0f, -1.0f);
  c.normal = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  vd_float4 p = model_v[i], n = model_n[i], pa = obs_v[i], na = obs_n[i];
  if (p.w == 0.0f || n.w == 0.0f || pa.w == 0.0f || na.w == 0.0f) return c;
  vd_float4 d = p - pa;
  d.w = 0.0f;
  vd_float4 view = vd_normalize3(-p);
  float w = vd_corr_weight(vd_length3(d), vd_dot3(n, na), vd_dot3(n, view), prm);
  if (w <= 0.0f) return c;
  vd_uint t = ids[i];
  vd_float4 b = bary[i];
  vd_float4 g = canon[tris[3 * t]] * b.x + canon[tris[3 * t + 1]] * b.y + canon[tris[3 * t + 2]] * b.z;
  c.canonical = VD_F4(g.x, g.y, g.z, w);
  c.target = vd_pose_apply(prm.cam_to_world, pa);
  c.target.w = vd_corr_slot_hint(owners, tris, t);
  c.normal = vd_pose_rotate(prm.cam_to_world, na);
  return c;
}

/* The dense colour term (beyond the paper, whose E_sparse pins the motion along the surface, which
 * depth cannot see, only at SIFT keypoints; docs/NONRIGID.md "Dense colour term"). Each pixel with a
 * depth row gets a second row on the same canonical sample: the observed intensity I (smoothed luma,
 * shared/preprocess.h) at the pixel the sample renders to, against the model's colour there, c.
 * Linearised at the rendered point P (camera coordinates),
 *   I(pi(P + d)) - c ~ (I - c) + g . d,   g = J_pi(P)^T grad I,
 * which is a row of the point-to-plane form n . (S - q) with n = s R g and
 * q = S0 - n s (I - c) / |n|^2 in the field's frame (R, S0: P's rotation and position there), so the
 * solver and its hierarchy take it unchanged. g is perpendicular to the viewing ray: the row sees
 * what depth does not. s converts intensity to metres; the weight is the depth row's w_c times a
 * Huber weight of I - c, so occlusions, highlights and lighting changes count only linearly. */
typedef struct {
  /* The current camera, camera to world. */
  VdPose cam_to_world;
  VdCamera cam;
  /* s: the metres of point-to-plane error one unit of intensity (black to white) weighs as. */
  float scale;
  /* Intensity residual beyond which a row weighs linearly (Huber). */
  float huber;
  /* Rows whose intensity gradient is under this per pixel carry no information: dropped. */
  float min_gradient;
  /* |n| at most: a row weighs at most this much of a depth row (|normal| = 1). */
  float max_strength;
  /* Rows within edge_radius pixels of an observed depth edge (a jump larger than max_jump of the
   * depth, or no depth) are dropped: the smoothed intensity there mixes two surfaces. */
  float max_jump;
  int edge_radius;
  int pad0, pad1;
} VdPhotoParams;

/* Whether the observed depth is continuous over the cross of edge_radius pixels around pixel (x, y). */
VD_INLINE int vd_photo_depth_smooth(VD_GLOBAL const vd_float4* obs_v, int x, int y, VdPhotoParams prm) {
  int w = prm.cam.width, r = prm.edge_radius;
  if (x < r || y < r || x >= w - r || y >= prm.cam.height - r) return 0;
  float z = obs_v[y * w + x].z, lim = prm.max_jump * z;
  if (!(obs_v[y * w + x].w > 0.0f)) return 0;
  for (int k = 1; k <= r; k *= 2) {
    vd_float4 a = obs_v[y * w + x - k], b = obs_v[y * w + x + k], c = obs_v[(y - k) * w + x],
              d = obs_v[(y + k) * w + x];
    if (a.w == 0.0f || b.w == 0.0f || c.w == 0.0f || d.w == 0.0f) return 0;
    if (fabs(a.z - z) > lim || fabs(b.z - z) > lim || fabs(c.z - z) > lim || fabs(d.z - z) > lim) return 0;
  }
  return 1;
}

/* The model's luma at pixel i: its triangle's vertex colours (packed as the frames) at the raster's
 * barycentrics. */
VD_INLINE float vd_model_luma(int i, VD_GLOBAL const vd_uint* ids, VD_GLOBAL const vd_float4* bary,
                              VD_GLOBAL const vd_uint* colors, VD_GLOBAL const int* tris) {
  vd_uint t = ids[i];
  vd_float4 b = bary[i];
  return b.x * vd_rgba_luma(colors[tris[3 * t]]) + b.y * vd_rgba_luma(colors[tris[3 * t + 1]]) +
         b.z * vd_rgba_luma(colors[tris[3 * t + 2]]);
}

/* The dense colour term's rows: one per 2x2 block of pixels, at the block's first pixel, stored after
 * the n depth rows in block order: rows[n + b] for the block b of vd_photo_pixel(b). */
VD_INLINE int vd_photo_rows(int width, int height) { return ((width + 1) / 2) * ((height + 1) / 2); }
VD_INLINE int vd_photo_pixel(int b, int width) {
  int bw = (width + 1) / 2;
  return 2 * (b / bw) * width + 2 * (b % bw);
}

/* Pixel i's colour row, from its depth row (canonical sample and w_c; no row where that has none). */
VD_INLINE VdCorrespondence vd_photometric_pixel(int i, VdCorrespondence depth_row, VD_GLOBAL const vd_float4* model_v,
                                                VD_GLOBAL const vd_float4* obs_v, VD_GLOBAL const vd_uint* ids,
                                                VD_GLOBAL const vd_float4* bary, VD_GLOBAL const vd_uint* colors,
                                                VD_GLOBAL const int* tris, VD_GLOBAL const float* intensity,
                                                VdPhotoParams prm) {
  VdCorrespondence c;
  c.canonical = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  c.target = VD_F4(0.0f, 0.0f, 0.0f, -1.0f);
  c.normal = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  int w = prm.cam.width, x = i % w, y = i / w;
  /* One pixel of each 2x2 block, with four times the weight: neighbours see nearly the same
   * smoothed intensity, the coarse levels that solve these rows have cells of 4 and 8 pixels at a
   * metre, and each row costs the sort and the moments as much as a depth row. */
  if (((x | y) & 1) != 0 || !(depth_row.canonical.w > 0.0f) || !vd_photo_depth_smooth(obs_v, x, y, prm)) return c;
  int hw = w / 2, hh = prm.cam.height / 2;
  float fx = (float)x, fy = (float)y;
  float gx =
      0.5f * (vd_intensity_at(intensity, hw, hh, fx + 1.0f, fy) - vd_intensity_at(intensity, hw, hh, fx - 1.0f, fy));
  float gy =
      0.5f * (vd_intensity_at(intensity, hw, hh, fx, fy + 1.0f) - vd_intensity_at(intensity, hw, hh, fx, fy - 1.0f));
  if (!(gx * gx + gy * gy >= prm.min_gradient * prm.min_gradient)) return c;
  vd_float4 p = model_v[i];
  if (!(p.z > 0.0f)) return c;
  float iz = 1.0f / p.z;
  float gu = gx * prm.cam.fx * iz, gv = gy * prm.cam.fy * iz;
  vd_float4 n = vd_pose_rotate(prm.cam_to_world, VD_F4(gu, gv, -(gu * p.x + gv * p.y) * iz, 0.0f)) * prm.scale;
  float nn = vd_dot3(n, n);
  if (!(nn > 0.0f)) return c;
  float r = vd_intensity_at(intensity, hw, hh, fx, fy) - vd_model_luma(i, ids, bary, colors, tris);
  float ar = fabs(r);
  float huber = ar > prm.huber ? prm.huber / ar : 1.0f;
  vd_float4 s0 = vd_pose_apply(prm.cam_to_world, p);
  c.canonical = depth_row.canonical;
  c.canonical.w = 4.0f * depth_row.canonical.w * huber;
  c.normal = n;
  c.target = s0 - n * (prm.scale * r / nn);
  c.target.w = depth_row.target.w;
  /* A strong edge is where the linearisation holds least: its row weighs at most max_strength of a
   * depth row (the same zero, a smaller slope). */
  if (nn > prm.max_strength * prm.max_strength) c.normal = n * (prm.max_strength / sqrt(nn));
  c.normal.w = VD_CORR_COARSE_ONLY;
  return c;
}

#endif /* VD_CORRESPONDENCE_H */
