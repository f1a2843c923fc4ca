#include "shared/tsdf.h"

/* One work item per grid row (fixed y, z): the inner loop walks contiguous memory, which a CPU
 * device runs like a plain loop and a GPU still spreads over dim_y * dim_z items. */
__kernel void vd_tsdf_integrate(__global float* tsdf, __global float* weight, __global uint* color, VdVolume vol,
                                VdCamera cam, VdPose world_to_cam, __global const float* depth,
                                __global const uint* rgba, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int yz = get_global_id(0);
  vd_tsdf_integrate_row(tsdf, weight, color, yz % vol.dim_y, yz / vol.dim_y, vol, cam, world_to_cam, depth, rgba);
}

/* Non-rigid fusion: one work item per active point (a dense grid's index, or a pool voxel's on the
 * bricks, whose allocation already says where surface is: mark_touched 0 and touched not read). */
__kernel void vd_tsdf_integrate_active(__global float* tsdf, __global float* weight, __global uint* color,
                                       __global uchar* touched, int mark_touched, __global const int* list,
                                       __global const float4* def_pos, VdFusionParams fp, VdVolume vol, VdCamera cam,
                                       VdPose world_to_cam, __global const float* depth, __global const uint* rgba,
                                       int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int gi = list[get_global_id(0)];
  vd_tsdf_integrate_deformed(tsdf, weight, color, gi, def_pos[gi], fp, vol, cam, world_to_cam, depth, rgba);
  if (mark_touched && weight[gi] > 0.0f) touched[vd_grid_brick_of_index(vol, gi)] = (uchar)1;
}

/* touched[b] from brick b's weights (shared/tsdf.h), one work item per brick. */
__kernel void vd_volume_touched(__global const float* weight, VdVolume vol, __global uchar* touched, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int b = get_global_id(0);
  touched[b] = vd_brick_touched_from(weight, vol, b);
}

/* Minimum and maximum depth per 8x8 pixel tile. */
__kernel void vd_depth_tiles(__global const float* depth, VdCamera cam, __global float4* tiles, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int t = get_global_id(0);
  tiles[t] = vd_depth_tile(t, depth, cam);
}

/* Bricks (flag 0/1) and their octants (mask) the current depth's truncation band may touch, one
 * work item per brick; the flagged ones are fused, so they become touched. */
__kernel void vd_brick_mark(__global const float4* tiles, VdCamera cam, VdPose world_to_cam, VdVolume vol,
                            __global uint* flags, __global uint* masks, __global uchar* touched, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int b = get_global_id(0);
  uint m = vd_brick_octants(b, tiles, cam, world_to_cam, vol);
  masks[b] = m;
  flags[b] = m != 0u ? 1u : 0u;
  if (m != 0u) touched[b] = (uchar)1;
}

/* list[offsets[b]] = b for every flagged brick. */
__kernel void vd_brick_compact(__global const uint* flags, __global const uint* offsets, __global uint* list,
                               int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int b = get_global_id(0);
  if (flags[b]) list[offsets[b]] = (uint)b;
}

/* Integration over the listed bricks: VD_BRICK_ITEMS work items (z-slices) per brick. */
__kernel void vd_tsdf_integrate_bricks(__global const uint* list, __global const uint* masks, __global float* tsdf,
                                       __global float* weight, __global uint* color, VdVolume vol, VdCamera cam,
                                       VdPose world_to_cam, __global const float* depth, __global const uint* rgba,
                                       int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  vd_tsdf_integrate_brick_row(get_global_id(0), list, masks, tsdf, weight, color, vol, cam, world_to_cam, depth,
                              rgba);
}
