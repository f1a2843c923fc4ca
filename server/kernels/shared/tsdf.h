/* Projective TSDF integration of one grid point: running weighted average of the truncated
 * signed distance (normalised to [-1, 1]), weight capped at max_weight, colour averaged near the
 * surface. */
#ifndef VD_TSDF_H
#define VD_TSDF_H

#include "vd_types.h"

VD_INLINE vd_float4 vd_voxel_position(VdVolume vol, int x, int y, int z) {
  return VD_F4(vol.origin.x + vol.voxel_size * (float)x, vol.origin.y + vol.voxel_size * (float)y,
               vol.origin.z + vol.voxel_size * (float)z, 1.0f);
}

/* Fuses the observation of the grid point whose current position in camera coordinates is
 * p_cam. depth: metres, 0 invalid; color: packed RGBA (alpha 0 = no colour). */
VD_INLINE void vd_tsdf_integrate_point(VD_GLOBAL float* tsdf, VD_GLOBAL float* weight, VD_GLOBAL vd_uint* color,
                                       int index, vd_float4 p_cam, VdVolume vol, VdCamera cam,
                                       VD_GLOBAL const float* depth, VD_GLOBAL const vd_uint* rgba) {
  if (p_cam.z <= 0.0f) return;
  float u = vd_project_u(cam, p_cam);
  float v = vd_project_v(cam, p_cam);
  /* Nearest pixel: pixel centres sit at integer coordinates. */
  int px = (int)floor(u + 0.5f);
  int py = (int)floor(v + 0.5f);
  if (px < 0 || py < 0 || px >= cam.width || py >= cam.height) return;
  int pix = py * cam.width + px;
  float d = depth[pix];
  if (d <= 0.0f) return;
  float sdf = d - p_cam.z;
  if (sdf < -vol.truncation) return;
  float f = fmin(1.0f, sdf / vol.truncation);
  float w_old = weight[index];
  float w_new = w_old + 1.0f;
  tsdf[index] = (tsdf[index] * w_old + f) / w_new;
  weight[index] = fmin(w_new, vol.max_weight);
  vd_uint c_obs = rgba[pix];
  if (fabs(sdf) < vol.truncation && (c_obs >> 24) != 0u) {
    vd_float4 c_old = vd_unpack_rgba(color[index]);
    vd_float4 c_new = vd_unpack_rgba(c_obs);
    /* Colour weight counts only observations that carried colour (alpha holds up to 255). */
    float cw = c_old.w;
    float cw_new = fmin(cw + 1.0f, 255.0f);
    vd_float4 c = (c_old * cw + c_new) / (cw + 1.0f);
    color[index] = vd_pack_rgba(c.x, c.y, c.z, cw_new);
  }
}

/* Rigid integration of grid row (y, z): grid points at their regular positions, seen through
 * world_to_cam. Positions are p0 + x * step (no accumulation, so no drift along the row). */
VD_INLINE void vd_tsdf_integrate_row(VD_GLOBAL float* tsdf, VD_GLOBAL float* weight, VD_GLOBAL vd_uint* color, int y,
                                     int z, VdVolume vol, VdCamera cam, VdPose world_to_cam,
                                     VD_GLOBAL const float* depth, VD_GLOBAL const vd_uint* rgba) {
  vd_float4 p0 = vd_pose_apply(world_to_cam, vd_voxel_position(vol, 0, y, z));
  vd_float4 step = vd_pose_rotate(world_to_cam, VD_F4(vol.voxel_size, 0.0f, 0.0f, 0.0f));
  int row = vol.dim_x * (y + vol.dim_y * z);
  for (int x = 0; x < vol.dim_x; ++x) {
    vd_float4 p = p0 + step * (float)x;
    vd_tsdf_integrate_point(tsdf, weight, color, row + x, p, vol, cam, depth, rgba);
  }
}

/* Non-rigid fusion (section 8) of active grid point gi at its deformed world position t (w = the
 * number of optimisations it took part in): fused only after at least k_min optimisations, so data
 * goes only where the deformation is well defined. */
VD_INLINE void vd_tsdf_integrate_deformed(VD_GLOBAL float* tsdf, VD_GLOBAL float* weight, VD_GLOBAL vd_uint* color,
                                          int gi, vd_float4 t, float k_min, VdVolume vol, VdCamera cam,
                                          VdPose world_to_cam, VD_GLOBAL const float* depth,
                                          VD_GLOBAL const vd_uint* rgba) {
  if (t.w < k_min) return;
  t.w = 1.0f;
  vd_tsdf_integrate_point(tsdf, weight, color, gi, vd_pose_apply(world_to_cam, t), vol, cam, depth, rgba);
}

#endif /* VD_TSDF_H */
