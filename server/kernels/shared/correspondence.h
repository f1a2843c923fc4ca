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

#include "vd_types.h"

typedef struct {
  /* Canonical position of the model sample in grid units; w = confidence w_c (0 = pruned). */
  vd_float4 canonical;
  /* Observed point and its normal in world (field) coordinates; w unused. */
  vd_float4 target;
  vd_float4 normal;
} VdCorrespondence;

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

/* Pixel i: model maps (camera coordinates, from the rasteriser), triangle ids and barycentrics,
 * the observed vertex and normal maps (camera coordinates), and the canonical mesh. */
VD_INLINE VdCorrespondence vd_correspondence_pixel(int i, VD_GLOBAL const vd_float4* model_v,
                                                   VD_GLOBAL const vd_float4* model_n, VD_GLOBAL const vd_uint* ids,
                                                   VD_GLOBAL const vd_float4* bary, VD_GLOBAL const vd_float4* obs_v,
                                                   VD_GLOBAL const vd_float4* obs_n, VD_GLOBAL const vd_float4* canon,
                                                   VD_GLOBAL const int* tris, VdCorrParams prm) {
  VdCorrespondence c;
  c.canonical = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  c.target = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
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
  c.normal = vd_pose_rotate(prm.cam_to_world, na);
  return c;
}

#endif /* VD_CORRESPONDENCE_H */
