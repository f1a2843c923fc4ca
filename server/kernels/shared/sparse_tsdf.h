/* TSDF integration into the brick pool of the sparse volume (issue 17; docs/SPARSE_VOLUME.md):
 * pool voxel slot * 512 + v is voxel v (x fastest) of the brick in that slot. The bricks
 * tile space from the world origin, so a voxel's position is its global grid coordinates times the
 * voxel size, and the same per-point fusion as the dense grid's (shared/tsdf.h) runs on it. */
#ifndef VD_SPARSE_TSDF_H
#define VD_SPARSE_TSDF_H

#include "brick_hash.h"
#include "tsdf.h"

#define VD_BRICK_VOXELS (VD_BRICK * VD_BRICK * VD_BRICK)

/* Global grid coordinates of voxel v of the brick with key `key`. */
VD_INLINE void vd_brick_voxel(vd_uint key, int v, int* gx, int* gy, int* gz) {
  int bx, by, bz;
  vd_brick_unpack(key, &bx, &by, &bz);
  *gx = bx * VD_BRICK + v % VD_BRICK;
  *gy = by * VD_BRICK + (v / VD_BRICK) % VD_BRICK;
  *gz = bz * VD_BRICK + v / (VD_BRICK * VD_BRICK);
}

/* Rigid integration of row r (0..63: y = r % 8, z = r / 8) of the brick in pool slot `slot` seen
 * through world_to_cam: its 8 voxels at p0 + x * step, as the dense grid's rows (no accumulation).
 * vol: voxel_size, truncation and max_weight (its origin and dimensions are not used). A slot
 * without a brick is left alone. */
VD_INLINE void vd_sparse_integrate_row(int slot, int r, VD_GLOBAL const vd_uint* slot_keys, VD_GLOBAL float* tsdf,
                                       VD_GLOBAL float* weight, VD_GLOBAL vd_uint* color, VdVolume vol, VdCamera cam,
                                       VdPose world_to_cam, VD_GLOBAL const float* depth,
                                       VD_GLOBAL const vd_uint* rgba) {
  vd_uint key = slot_keys[slot];
  if (key == VD_BRICK_EMPTY) return;
  int gx, gy, gz;
  vd_brick_voxel(key, r * VD_BRICK, &gx, &gy, &gz);
  vd_float4 p0 = vd_pose_apply(
      world_to_cam, VD_F4(vol.voxel_size * (float)gx, vol.voxel_size * (float)gy, vol.voxel_size * (float)gz, 1.0f));
  vd_float4 step = vd_pose_rotate(world_to_cam, VD_F4(vol.voxel_size, 0.0f, 0.0f, 0.0f));
  int base = slot * VD_BRICK_VOXELS + r * VD_BRICK;
  for (int x = 0; x < VD_BRICK; ++x)
    vd_tsdf_integrate_point(tsdf, weight, color, base + x, p0 + step * (float)x, vol, cam, depth, rgba);
}

/* Moves voxel v (0..511) of every kept brick of a compaction (keep: one flag per slot, offsets:
 * their exclusive prefix sum) from its old slot s to offsets[s] <= s. Slots go in increasing order,
 * so a destination has already given up its own voxel (moved, or dropped) before it is written:
 * one work item per voxel lane may move all the bricks in place. */
VD_INLINE void vd_brick_pool_move_lane(int v, VD_GLOBAL const vd_uint* keep, VD_GLOBAL const vd_uint* offsets, int used,
                                       VD_GLOBAL float* tsdf, VD_GLOBAL float* weight, VD_GLOBAL vd_uint* color) {
  for (int s = 0; s < used; ++s) {
    int d = (int)offsets[s];
    if (!keep[s] || d == s) continue;
    int from = s * VD_BRICK_VOXELS + v, to = d * VD_BRICK_VOXELS + v;
    tsdf[to] = tsdf[from];
    weight[to] = weight[from];
    color[to] = color[from];
  }
}

/* The deformation field on the pool (shared/deformation.h's t_i and R_i, one per pool voxel; issue
 * 17, docs/SPARSE_VOLUME.md): positions in world metres, which for the bricks (tiling space from the
 * world origin) start at the voxel size times the global grid coordinates. */

/* Rest position of pool voxel `index` (w = 0: never optimised). */
VD_INLINE vd_float4 vd_pool_rest_position(VD_GLOBAL const vd_uint* slot_keys, int index, float voxel_size) {
  int gx, gy, gz;
  vd_brick_voxel(slot_keys[index / VD_BRICK_VOXELS], index % VD_BRICK_VOXELS, &gx, &gy, &gz);
  return VD_F4(voxel_size * (float)gx, voxel_size * (float)gy, voxel_size * (float)gz, 0.0f);
}

/* Puts pool voxel `index`'s deformation at rest: its rest position, the identity rotation. */
VD_INLINE void vd_pool_field_rest(VD_GLOBAL const vd_uint* slot_keys, int index, float voxel_size,
                                  VD_GLOBAL vd_float4* def_pos, VD_GLOBAL vd_float4* def_rot) {
  def_pos[index] = vd_pool_rest_position(slot_keys, index, voxel_size);
  def_rot[index] = VD_F4(0.0f, 0.0f, 0.0f, 1.0f);
}

/* vd_brick_pool_move_lane for the field: voxel v of every kept brick to its compacted slot. */
VD_INLINE void vd_brick_field_move_lane(int v, VD_GLOBAL const vd_uint* keep, VD_GLOBAL const vd_uint* offsets,
                                        int used, VD_GLOBAL vd_float4* def_pos, VD_GLOBAL vd_float4* def_rot) {
  for (int s = 0; s < used; ++s) {
    int d = (int)offsets[s];
    if (!keep[s] || d == s) continue;
    int from = s * VD_BRICK_VOXELS + v, to = d * VD_BRICK_VOXELS + v;
    def_pos[to] = def_pos[from];
    def_rot[to] = def_rot[from];
  }
}

#endif /* VD_SPARSE_TSDF_H */
