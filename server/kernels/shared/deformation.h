/* The deformation half of the unified grid (VolumeDeform section 4). Every grid point i stores its
 * deformed position t_i (float4: xyz in metres, w = number of optimisations the point took part
 * in) and its local rotation R_i as a unit quaternion (float4 x, y, z, w; 16 bytes, renormalisable,
 * no gimbal lock; the paper stores Euler angles). t_i starts at the regular grid position, R_i at
 * the identity. A canonical point x with grid coordinates g (cell floor(g), fractions g - floor(g))
 * is deformed by S(x) = sum_k alpha_k(x) t_k over its cell's 8 corners (trilinear weights); the
 * global rigid motion is the camera pose, applied after. */
#ifndef VD_DEFORMATION_H
#define VD_DEFORMATION_H

#include "svd3.h"
#include "vd_types.h"

VD_INLINE vd_float4 vd_rest_position(VdVolume vol, int x, int y, int z) {
  return VD_F4(vol.origin.x + vol.voxel_size * (float)x, vol.origin.y + vol.voxel_size * (float)y,
               vol.origin.z + vol.voxel_size * (float)z, 0.0f);
}

/* Resets grid row (y, z): rest positions, zero optimisation counts, identity rotations. */
VD_INLINE void vd_deformation_reset_row(VD_GLOBAL vd_float4* def_pos, VD_GLOBAL vd_float4* def_rot, int y, int z,
                                        VdVolume vol) {
  int row = vol.dim_x * (y + vol.dim_y * z);
  for (int x = 0; x < vol.dim_x; ++x) {
    def_pos[row + x] = vd_rest_position(vol, x, y, z);
    def_rot[row + x] = VD_F4(0.0f, 0.0f, 0.0f, 1.0f);
  }
}

/* S(x) for a point given in grid units (as marching cubes emits vertices); w = 1. Points on the
 * last grid plane use the cell below, so all 8 corners exist. */
VD_INLINE vd_float4 vd_deform_point(vd_float4 g, VD_GLOBAL const vd_float4* def_pos, VdVolume vol) {
  int cx = vd_min_i(vd_max_i((int)floor(g.x), 0), vol.dim_x - 2);
  int cy = vd_min_i(vd_max_i((int)floor(g.y), 0), vol.dim_y - 2);
  int cz = vd_min_i(vd_max_i((int)floor(g.z), 0), vol.dim_z - 2);
  float fx = g.x - (float)cx, fy = g.y - (float)cy, fz = g.z - (float)cz;
  vd_float4 acc = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  for (int k = 0; k < 8; ++k) {
    int ox = k & 1, oy = (k >> 1) & 1, oz = (k >> 2) & 1;
    float a = (ox ? fx : 1.0f - fx) * (oy ? fy : 1.0f - fy) * (oz ? fz : 1.0f - fz);
    vd_float4 t = def_pos[cx + ox + vol.dim_x * (cy + oy + vol.dim_y * (cz + oz))];
    acc = acc + t * a;
  }
  acc.w = 1.0f;
  return acc;
}

/* Where optimised neighbour j (position t, rotation r), at offset (dx, dy, dz) voxels from a point,
 * puts that point as a rigid piece: t_j + R_j (t^_i - t^_j). */
VD_INLINE vd_float4 vd_extrapolate_prediction(vd_float4 t, vd_float4 r, int dx, int dy, int dz, float voxel_size) {
  vd_float4 edge = VD_F4(-(float)dx * voxel_size, -(float)dy * voxel_size, -(float)dz * voxel_size, 0.0f);
  return t + vd_quat_rotate(r, edge);
}

/* The end of an extrapolation: the mean of the n predictions summed in disp, with the rotation of
 * neighbour `first` (none when n == 0: returns 0 and leaves the outputs). */
VD_INLINE int vd_extrapolate_finish(vd_float4 disp, float n, int first, VD_GLOBAL const vd_float4* def_rot,
                                    vd_float4* pos_out, vd_float4* rot_out) {
  if (n == 0.0f) return 0;
  vd_float4 p = disp / n;
  p.w = 0.0f;
  *pos_out = p;
  *rot_out = def_rot[first];
  return 1;
}

/* Offset k of a gather around a point: the 6 face neighbours (-x, +x, -y, +y, -z, +z) with
 * faces_only, else the 26-neighbourhood (k in 0..26, 13 the point itself: returns 0). */
VD_INLINE int vd_gather_offset(int faces_only, int k, int* dx, int* dy, int* dz) {
  if (faces_only) {
    int axis = k >> 1, sign = (k & 1) ? 1 : -1;
    *dx = axis == 0 ? sign : 0;
    *dy = axis == 1 ? sign : 0;
    *dz = axis == 2 ? sign : 0;
    return 1;
  }
  *dx = k % 3 - 1;
  *dy = (k / 3) % 3 - 1;
  *dz = k / 9 - 1;
  return k != 13;
}

/* The sum of the rigid predictions of grid point gi's optimised neighbours j (w > 0; the 6 face
 * neighbours with faces_only, else the 26), with surface != 0 only those that are surface points of
 * M (solved this frame), into disp, their count n and the first one's index. */
VD_INLINE void vd_extrapolate_gather(int gi, VD_GLOBAL const vd_uchar* surface, int faces_only,
                                     VD_GLOBAL const vd_float4* def_pos, VD_GLOBAL const vd_float4* def_rot,
                                     VdVolume vol, vd_float4* disp, float* n, int* first) {
  int x = gi % vol.dim_x, yz = gi / vol.dim_x;
  int y = yz % vol.dim_y, z = yz / vol.dim_y;
  *disp = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  *n = 0.0f;
  *first = -1;
  for (int k = 0; k < (faces_only ? 6 : 27); ++k) {
    int dx, dy, dz;
    if (!vd_gather_offset(faces_only, k, &dx, &dy, &dz)) continue;
    int nx = x + dx, ny = y + dy, nz = z + dz;
    if (k == 13 || nx < 0 || ny < 0 || nz < 0 || nx >= vol.dim_x || ny >= vol.dim_y || nz >= vol.dim_z) continue;
    int j = nx + vol.dim_x * (ny + vol.dim_y * nz);
    if (surface != 0 && !surface[j]) continue;
    vd_float4 t = def_pos[j];
    if (!(t.w > 0.0f)) continue;
    *disp = *disp + vd_extrapolate_prediction(t, def_rot[j], dx, dy, dz, vol.voxel_size);
    *n += 1.0f;
    if (*first < 0) *first = j;
  }
}

/* A grid point entering the active set for the first time (never optimised: w == 0) starts where
 * its optimised 26-neighbours j put it as rigid pieces, the mean of t_j + R_j (t^_i - t^_j) (the
 * ARAP prior's own prediction), with the rotation of the first such neighbour. Moving it by their
 * mean displacement alone ignored their rotation: an error of 2 sin(a/2) per voxel for a local
 * rotation a (~5 mm per 4 mm voxel at 75 degrees), so new surface near strongly rotated parts was
 * fused at the wrong canonical place (docs/BENCHMARKS.md "Long takes"). Without optimised
 * neighbours it keeps its state. Returns 1 when the point was initialised. */
VD_INLINE int vd_extrapolate_point(int gi, VD_GLOBAL const vd_float4* def_pos, VD_GLOBAL const vd_float4* def_rot,
                                   VdVolume vol, vd_float4* pos_out, vd_float4* rot_out) {
  *pos_out = def_pos[gi];
  *rot_out = def_rot[gi];
  if (def_pos[gi].w > 0.0f) return 0;
  vd_float4 disp;
  float n;
  int first;
  vd_extrapolate_gather(gi, 0, 0, def_pos, def_rot, vol, &disp, &n, &first);
  return vd_extrapolate_finish(disp, n, first, def_rot, pos_out, rot_out);
}

/* A ring point of M (a 6-neighbour of the surface that is no corner of a surface cell) is no
 * unknown of the solve: no data term reaches it, and its ARAP edges only carry its solved
 * neighbours' motion on. After each solve it follows them instead: to the mean of the rigid
 * predictions t_j + R_j (t^_i - t^_j) of its solved face neighbours j (its ARAP edges; it has at
 * least one by construction) with the first one's rotation, the ARAP prior's own answer for a
 * point without data, and counts the solve (w + 1), so fusion's K_min wait runs as for a solved
 * point. The face neighbours alone cost a third of the 26 (vd_follow 119 -> 41 ms over 60 tube
 * frames) and give the same drift. surface: 1 at the surface points (the solved ones). Returns 1
 * when it moved (a surface point, or a ring point without a solved neighbour, keeps its state). */
VD_INLINE int vd_follow_point(int gi, VD_GLOBAL const vd_uchar* surface, VD_GLOBAL const vd_float4* def_pos,
                              VD_GLOBAL const vd_float4* def_rot, VdVolume vol, vd_float4* pos_out,
                              vd_float4* rot_out) {
  *pos_out = def_pos[gi];
  *rot_out = def_rot[gi];
  if (surface[gi]) return 0;
  vd_float4 disp;
  float n;
  int first;
  vd_extrapolate_gather(gi, surface, 1, def_pos, def_rot, vol, &disp, &n, &first);
  float w = def_pos[gi].w;
  if (!vd_extrapolate_finish(disp, n, first, def_rot, pos_out, rot_out)) return 0;
  pos_out->w = w + 1.0f;
  return 1;
}

/* Moves a rigid motion out of the field: grid point i (optimised: w > 0) takes t_i' = A t_i and
 * R_i' = q_A R_i for the rigid A = (rotation q_A, rows of `a`), so that the camera pose taking
 * A^-1 in leaves every deformed point where the camera sees it (Engine's rigid factoring). Points
 * never optimised hold their rest positions and are left alone (extrapolation sets them). */
VD_INLINE void vd_field_rigid_point(int gi, VD_GLOBAL vd_float4* def_pos, VD_GLOBAL vd_float4* def_rot, VdPose a,
                                    vd_float4 q_a) {
  vd_float4 t = def_pos[gi];
  if (!(t.w > 0.0f)) return;
  vd_float4 p = vd_pose_apply(a, t);
  p.w = t.w;
  def_pos[gi] = p;
  def_rot[gi] = vd_quat_mul(q_a, def_rot[gi]);
}

#endif /* VD_DEFORMATION_H */
