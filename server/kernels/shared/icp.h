/* Dense projective point-to-plane ICP, one pixel of the current frame at one pyramid level.
 * The model (rendered at the previous pose T_prev at full resolution) is looked up by projecting
 * the current point, transformed by the current estimate T_cur, into the full-resolution model
 * image. The linearisation is for a left increment exp(xi) * T_cur with xi = (omega, v):
 * r = m . (p_w - q), dr/domega = p_w x m, dr/dv = m. */
#ifndef VD_ICP_H
#define VD_ICP_H

#include "vd_types.h"

/* Accumulator layout: 21 upper-triangular entries of J^T J (row-major), 6 of J^T r, r^2, count. */
#define VD_ICP_ACC 29
#define VD_ICP_ACC_JTR 21
#define VD_ICP_ACC_R2 27
#define VD_ICP_ACC_COUNT 28

typedef struct {
  /* Current estimate, camera to world. */
  VdPose cam_to_world;
  /* Pose of the model rendering: world to its camera, and its camera to world. */
  VdPose world_to_model;
  VdPose model_to_world;
  /* Full-resolution camera of the model rendering. */
  VdCamera model_cam;
  /* Correspondences farther apart than this are rejected, metres. */
  float max_distance;
  /* Rejected when the normals' dot product is below this. */
  float min_normal_dot;
  int pad0, pad1;
} VdIcpParams;

/* Adds pixel i's contribution to acc (VD_ICP_ACC floats); returns 1 when it is an inlier. */
VD_INLINE int vd_icp_pixel(VD_GLOBAL const vd_float4* vmap, VD_GLOBAL const vd_float4* nmap,
                           VD_GLOBAL const vd_float4* model_v, VD_GLOBAL const vd_float4* model_n, int i,
                           VdIcpParams prm, float* acc) {
  vd_float4 p = vmap[i];
  vd_float4 n = nmap[i];
  if (p.w == 0.0f || n.w == 0.0f) return 0;
  vd_float4 pw = vd_pose_apply(prm.cam_to_world, p);
  vd_float4 pm = vd_pose_apply(prm.world_to_model, pw);
  if (pm.z <= 0.0f) return 0;
  int u = (int)floor(vd_project_u(prm.model_cam, pm) + 0.5f);
  int v = (int)floor(vd_project_v(prm.model_cam, pm) + 0.5f);
  if (u < 0 || v < 0 || u >= prm.model_cam.width || v >= prm.model_cam.height) return 0;
  int j = v * prm.model_cam.width + u;
  vd_float4 qc = model_v[j];
  vd_float4 mc = model_n[j];
  if (qc.w == 0.0f || mc.w == 0.0f) return 0;
  vd_float4 q = vd_pose_apply(prm.model_to_world, qc);
  vd_float4 m = vd_pose_rotate(prm.model_to_world, mc);
  vd_float4 diff = pw - q;
  diff.w = 0.0f;
  if (vd_length3(diff) > prm.max_distance) return 0;
  vd_float4 nw = vd_pose_rotate(prm.cam_to_world, n);
  if (vd_dot3(nw, m) < prm.min_normal_dot) return 0;
  float r = vd_dot3(m, diff);
  vd_float4 c = vd_cross3(pw, m);
  float J[6];
  J[0] = c.x;
  J[1] = c.y;
  J[2] = c.z;
  J[3] = m.x;
  J[4] = m.y;
  J[5] = m.z;
  int k = 0;
  for (int a = 0; a < 6; ++a) {
    for (int b = a; b < 6; ++b) acc[k++] += J[a] * J[b];
  }
  for (int a = 0; a < 6; ++a) acc[VD_ICP_ACC_JTR + a] += J[a] * r;
  acc[VD_ICP_ACC_R2] += r * r;
  acc[VD_ICP_ACC_COUNT] += 1.0f;
  return 1;
}

#endif /* VD_ICP_H */
