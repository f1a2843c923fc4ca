/* Structs that cross host <-> device: 32-bit scalars and float4 only, sizes checked by a test
 * on both sides (tests/kernels/types_parity_test.cpp). */
#ifndef VD_TYPES_H
#define VD_TYPES_H

#include "vd_compat.h"

/* Pinhole camera of one image (or one pyramid level). */
typedef struct {
  float fx, fy, cx, cy;
  int width, height;
  /* Padding keeps the struct a multiple of 16 bytes on both sides. */
  int pad0, pad1;
} VdCamera;

/* Rigid transform as the top three rows of a 4x4 matrix: p' = R p + t with rows r0..r2, t in w. */
typedef struct {
  vd_float4 r0, r1, r2;
} VdPose;

/* The regular grid: voxel (x, y, z) sits at origin + voxel_size * (x, y, z), linear index
 * x + dim_x * (y + dim_y * z). */
typedef struct {
  vd_float4 origin;
  int dim_x, dim_y, dim_z;
  float voxel_size;
  /* Truncation band of the signed distance, metres. */
  float truncation;
  /* Running-average weight cap: lets the model follow slow changes. */
  float max_weight;
  int pad0, pad1;
} VdVolume;

/* Linear index of grid point (x, y, z). */
VD_INLINE int vd_grid_index(VdVolume vol, int x, int y, int z) { return x + vol.dim_x * (y + vol.dim_y * z); }

VD_INLINE vd_float4 vd_pose_apply(VdPose T, vd_float4 p) {
  return VD_F4(T.r0.x * p.x + T.r0.y * p.y + T.r0.z * p.z + T.r0.w,
               T.r1.x * p.x + T.r1.y * p.y + T.r1.z * p.z + T.r1.w,
               T.r2.x * p.x + T.r2.y * p.y + T.r2.z * p.z + T.r2.w, 1.0f);
}

VD_INLINE vd_float4 vd_pose_rotate(VdPose T, vd_float4 v) {
  return VD_F4(T.r0.x * v.x + T.r0.y * v.y + T.r0.z * v.z,
               T.r1.x * v.x + T.r1.y * v.y + T.r1.z * v.z,
               T.r2.x * v.x + T.r2.y * v.y + T.r2.z * v.z, 0.0f);
}

/* The inverse of a rigid transform: R^T and -R^T t. */
VD_INLINE VdPose vd_pose_inverse(VdPose T) {
  VdPose o;
  o.r0 = VD_F4(T.r0.x, T.r1.x, T.r2.x, -(T.r0.x * T.r0.w + T.r1.x * T.r1.w + T.r2.x * T.r2.w));
  o.r1 = VD_F4(T.r0.y, T.r1.y, T.r2.y, -(T.r0.y * T.r0.w + T.r1.y * T.r1.w + T.r2.y * T.r2.w));
  o.r2 = VD_F4(T.r0.z, T.r1.z, T.r2.z, -(T.r0.z * T.r0.w + T.r1.z * T.r1.w + T.r2.z * T.r2.w));
  return o;
}

/* Pixel coordinates of a camera-space point (z > 0 assumed by the caller). */
VD_INLINE float vd_project_u(VdCamera c, vd_float4 p) { return c.fx * p.x / p.z + c.cx; }
VD_INLINE float vd_project_v(VdCamera c, vd_float4 p) { return c.fy * p.y / p.z + c.cy; }

/* Packs / unpacks RGBA8 as r | g << 8 | b << 16 | a << 24. */
VD_INLINE vd_uint vd_pack_rgba(float r, float g, float b, float a) {
  vd_uint ri = (vd_uint)vd_clampf(r + 0.5f, 0.0f, 255.0f);
  vd_uint gi = (vd_uint)vd_clampf(g + 0.5f, 0.0f, 255.0f);
  vd_uint bi = (vd_uint)vd_clampf(b + 0.5f, 0.0f, 255.0f);
  vd_uint ai = (vd_uint)vd_clampf(a + 0.5f, 0.0f, 255.0f);
  return ri | (gi << 8) | (bi << 16) | (ai << 24);
}
VD_INLINE vd_float4 vd_unpack_rgba(vd_uint c) {
  return VD_F4((float)(c & 255u), (float)((c >> 8) & 255u), (float)((c >> 16) & 255u), (float)(c >> 24));
}

#endif /* VD_TYPES_H */
