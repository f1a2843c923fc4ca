#include "shared/sparse_mesh.h"

/* The brick table of the sparse volume (shared/brick_hash.h) and fusion into its pool
 * (shared/sparse_tsdf.h). slot_keys: the key of each pool slot's brick (VD_BRICK_EMPTY: none). */

/* One work item per depth tile (VD_DEPTH_TILE^2 pixels; metres, 0 = none): allocates the bricks
 * its truncation band reaches. */
__kernel void vd_brick_table_alloc_depth(__global const float* depth, VdCamera cam, VdPose cam_to_world,
                                         float truncation, float brick_size, __global uint* keys, __global int* slots,
                                         __global uint* slot_keys, uint capacity, uint pool, __global uint* counters,
                                         int vd_items) {
  int i = get_global_id(0);
  if (i >= vd_items) return;
  vd_brick_take_tile(VD_BRICK_ALLOCATE, i, depth, cam, cam_to_world, truncation, brick_size, keys, slots, slot_keys,
                     capacity, pool, 0, 0u, 0, counters);
}

/* One work item per key of `in` (packed brick coordinates). */
__kernel void vd_brick_table_insert(__global const uint* in, __global uint* keys, __global int* slots,
                                    __global uint* slot_keys, uint capacity, uint pool, __global uint* counters,
                                    int vd_items) {
  int i = get_global_id(0);
  if (i >= vd_items) return;
  vd_brick_allocate(keys, slots, slot_keys, capacity, pool, counters, in[i]);
}

/* One work item per pool slot to restore: key in[i] goes back into slot i. */
__kernel void vd_brick_table_restore(__global const uint* in, __global uint* keys, __global int* slots,
                                     __global uint* slot_keys, uint capacity, __global uint* counters, int vd_items) {
  int i = get_global_id(0);
  if (i >= vd_items) return;
  vd_brick_restore(keys, slots, slot_keys, capacity, counters, in[i], i);
}

/* One work item per key of `in`: its slot, or -1. */
__kernel void vd_brick_table_lookup(__global const uint* in, __global const uint* keys, __global const int* slots,
                                    uint capacity, __global int* out, int vd_items) {
  int i = get_global_id(0);
  if (i >= vd_items) return;
  out[i] = vd_brick_find(keys, slots, capacity, in[i]);
}

/* One work item per entry of the old table: kept bricks go into the new one, renumbered. */
__kernel void vd_brick_table_compact(__global const uint* old_keys, __global const int* old_slots,
                                     __global const uint* keep, __global const uint* offsets,
                                     __global const uint* old_stamp, __global uint* keys, __global int* slots,
                                     __global uint* slot_keys, __global uint* stamp, uint capacity,
                                     __global uint* counters, int vd_items) {
  int i = get_global_id(0);
  if (i >= vd_items) return;
  vd_brick_reinsert((uint)i, old_keys, old_slots, keep, offsets, old_stamp, keys, slots, slot_keys, stamp, capacity,
                    counters);
}

/* One work item per voxel lane (512): the kept bricks' voxels move to their compacted slots. */
__kernel void vd_brick_pool_move(__global const uint* keep, __global const uint* offsets, int used,
                                 __global float* tsdf, __global float* weight, __global uint* color, int vd_items) {
  int v = get_global_id(0);
  if (v >= vd_items) return;
  vd_brick_pool_move_lane(v, keep, offsets, used, tsdf, weight, color);
}

/* One work item per depth tile: lists the bricks its band reaches, once each per frame. */
__kernel void vd_brick_table_list(__global const float* depth, VdCamera cam, VdPose cam_to_world, float truncation,
                                  float brick_size, __global uint* keys, __global int* slots, uint capacity,
                                  __global uint* stamp, uint frame, __global int* visible, __global uint* counters,
                                  int vd_items) {
  int i = get_global_id(0);
  if (i >= vd_items) return;
  vd_brick_take_tile(VD_BRICK_LIST, i, depth, cam, cam_to_world, truncation, brick_size, keys, slots, 0, capacity, 0u,
                     stamp, frame, visible, counters);
}

/* One work item per row (8 voxels along x) of the listed bricks: rigid fusion of the depth frame. */
__kernel void vd_sparse_integrate(__global const int* visible, __global const uint* slot_keys, __global float* tsdf,
                                  __global float* weight, __global uint* color, VdVolume vol, VdCamera cam,
                                  VdPose world_to_cam, __global const float* depth, __global const uint* rgba,
                                  int vd_items) {
  int i = get_global_id(0);
  if (i >= vd_items) return;
  vd_sparse_integrate_row(visible[i / (VD_BRICK * VD_BRICK)], i % (VD_BRICK * VD_BRICK), slot_keys, tsdf, weight, color,
                          vol, cam, world_to_cam, depth, rgba);
}

/* One work item per pool slot handed out: the slots of its brick's 27 neighbours
 * (shared/sparse_mesh.h). */
__kernel void vd_brick_neighbours(__global const uint* slot_keys, __global const uint* keys, __global const int* slots,
                                  uint capacity, __global int* nbr, int vd_items) {
  int s = get_global_id(0);
  if (s >= vd_items) return;
  vd_brick_neighbours_of(s, slot_keys, keys, slots, capacity, nbr);
}
