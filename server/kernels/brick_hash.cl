#include "shared/sparse_field.h"

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

/* One work item per slot first.. of a batch whose keys were put in key order. */
__kernel void vd_brick_table_reslot(__global const uint* slot_keys, int first, __global const uint* keys,
                                    __global int* slots, uint capacity, int vd_items) {
  int i = get_global_id(0);
  if (i >= vd_items) return;
  vd_brick_reslot(first + i, slot_keys, keys, slots, capacity);
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

/* One work item per voxel of `count` slots from `first`: their deformation at rest (after the
 * table handed them out, so their keys are written). */
__kernel void vd_brick_field_rest(__global const uint* slot_keys, int first, float voxel_size, __global float4* def_pos,
                                  __global float4* def_rot, int vd_items) {
  int i = get_global_id(0);
  if (i >= vd_items) return;
  vd_pool_field_rest(slot_keys, first * VD_BRICK_VOXELS + i, voxel_size, def_pos, def_rot);
}

/* One work item per voxel lane (512): the kept bricks' deformation moves to their compacted slots. */
__kernel void vd_brick_field_move(__global const uint* keep, __global const uint* offsets, int used,
                                  __global float4* def_pos, __global float4* def_rot, int vd_items) {
  int v = get_global_id(0);
  if (v >= vd_items) return;
  vd_brick_field_move_lane(v, keep, offsets, used, def_pos, def_rot);
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

/* One work item per depth tile: allocates the bricks its band reaches and lists their table entries
 * once per frame (entry_stamp: one per table entry). */
__kernel void vd_brick_table_alloc_list(__global const float* depth, VdCamera cam, VdPose cam_to_world,
                                        float truncation, float brick_size, __global uint* keys, __global int* slots,
                                        __global uint* slot_keys, uint capacity, uint pool, __global uint* entry_stamp,
                                        uint frame, __global int* visible, __global uint* counters, int vd_items) {
  int i = get_global_id(0);
  if (i >= vd_items) return;
  vd_brick_take_tile(VD_BRICK_ALLOCATE_LIST, i, depth, cam, cam_to_world, truncation, brick_size, keys, slots,
                     slot_keys, capacity, pool, entry_stamp, frame, visible, counters);
}

/* One work item per listed entry: its slot, stamped with the frame. */
__kernel void vd_brick_entry_slots(__global int* visible, __global const int* slots, __global uint* slot_stamp,
                                   uint frame, __global uint* counters, int vd_items) {
  int i = get_global_id(0);
  if (i >= vd_items) return;
  vd_brick_entry_slot(i, visible, slots, slot_stamp, frame, counters);
}

/* Rigid fusion of the depth frame into the listed bricks, VD_LANES consecutive voxels of a brick per
 * work item (a kLaned launch; 512 is a multiple of every lane count, so the lanes share a brick).
 * With one lane (a GPU) it is vd_sparse_integrate_row's per-voxel update. With more, the same
 * arithmetic in the same order runs on all lanes at once (the rows' first voxels placed as the rows
 * are, then p0 + step * x): the projection, the depth gather, the band test and the TSDF and weight
 * update as vectors, and the colour average inside the band (the observed colours gathered per lane). */
__kernel void vd_sparse_integrate(__global const int* visible, __global const uint* slot_keys, __global float* tsdf,
                                  __global float* weight, __global uint* color, VdVolume vol, VdCamera cam,
                                  VdPose world_to_cam, __global const float* depth, __global const uint* rgba,
                                  int vd_items) {
  int base = (int)get_global_id(0) * VD_LANES;
  if (base >= vd_items) return;
  int slot = visible[base / VD_BRICK_VOXELS];
  if (slot < 0) return; /* listed, but the pool had no room */
  uint key = slot_keys[slot];
  if (key == VD_BRICK_EMPTY) return;
  int first = base % VD_BRICK_VOXELS;
  int index0 = slot * VD_BRICK_VOXELS + first;
#if VD_LANES == 1
  int gx, gy, gz;
  vd_brick_voxel(key, first - first % VD_BRICK, &gx, &gy, &gz);
  vd_float4 p0 = vd_pose_apply(
      world_to_cam, VD_F4(vol.voxel_size * (float)gx, vol.voxel_size * (float)gy, vol.voxel_size * (float)gz, 1.0f));
  vd_float4 step = vd_pose_rotate(world_to_cam, VD_F4(vol.voxel_size, 0.0f, 0.0f, 0.0f));
  vd_tsdf_integrate_point(tsdf, weight, color, index0, p0 + step * (float)(first % VD_BRICK), vol, cam, depth, rgba);
#else
  /* Each lane's row start (global grid coordinates) and its x within the row. */
  float rx[VD_LANES], ry[VD_LANES], rz[VD_LANES], xs[VD_LANES];
  for (int l = 0; l < VD_LANES; ++l) {
    int gx, gy, gz, v = first + l;
    vd_brick_voxel(key, v - v % VD_BRICK, &gx, &gy, &gz);
    rx[l] = vol.voxel_size * (float)gx;
    ry[l] = vol.voxel_size * (float)gy;
    rz[l] = vol.voxel_size * (float)gz;
    xs[l] = (float)(v % VD_BRICK);
  }
  vd_lf X = vd_lload(rx), Y = vd_lload(ry), Z = vd_lload(rz), xl = vd_lload(xs);
  VdPose P = world_to_cam;
  /* vd_pose_apply, then + step * x, component by component. */
  vd_float4 step = vd_pose_rotate(P, VD_F4(vol.voxel_size, 0.0f, 0.0f, 0.0f));
  vd_lf cx = P.r0.x * X + P.r0.y * Y + P.r0.z * Z + P.r0.w;
  vd_lf cy = P.r1.x * X + P.r1.y * Y + P.r1.z * Z + P.r1.w;
  vd_lf cz = P.r2.x * X + P.r2.y * Y + P.r2.z * Z + P.r2.w;
  cx = cx + step.x * xl;
  cy = cy + step.y * xl;
  cz = cz + step.z * xl;
  vd_li ahead = cz > 0.0f;
  vd_lf z = vd_lsel((vd_lf)1.0f, cz, ahead);
  vd_lf u = cam.fx * cx / z + cam.cx, vv = cam.fy * cy / z + cam.cy;
  vd_lf fu = floor(u + 0.5f), fv = floor(vv + 0.5f);
  vd_li inside = ahead & (fu >= 0.0f) & (fv >= 0.0f) & (fu < (float)cam.width) & (fv < (float)cam.height);
  /* Each lane's pixel (pixel 0 outside the image, then not fused), gathered without branches. */
  int pix[VD_LANES];
  vd_lstore(vd_lf_to_li(vd_lsel((vd_lf)0.0f, fv * (float)cam.width + fu, inside)), pix);
  float dd[VD_LANES];
  for (int l = 0; l < VD_LANES; ++l) dd[l] = depth[pix[l]];
  vd_lf d = vd_lsel((vd_lf)0.0f, vd_lload(dd), inside);
  vd_lf sdf = d - cz;
  vd_li fuse = inside & (d > 0.0f) & (sdf >= -vol.truncation);
  vd_lf f = fmin((vd_lf)1.0f, sdf / vol.truncation);
  vd_lf w_old = vd_lload(weight + index0), t_old = vd_lload(tsdf + index0);
  vd_lf w_new = w_old + 1.0f;
  vd_lstore(vd_lsel(t_old, (t_old * w_old + f) / w_new, fuse), tsdf + index0);
  vd_lstore(vd_lsel(w_old, fmin(w_new, (vd_lf)vol.max_weight), fuse), weight + index0);
  vd_li colour = fuse & (fabs(sdf) < vol.truncation);
  vd_uint obs[VD_LANES];
  for (int l = 0; l < VD_LANES; ++l) obs[l] = rgba[pix[l]];
  vd_tsdf_fuse_color_lanes(color, index0, vd_lload(obs), colour);
#endif
}

/* One work item per pool slot handed out: the slots of its brick's 27 neighbours
 * (shared/sparse_mesh.h). */
__kernel void vd_brick_neighbours(__global const uint* slot_keys, __global const uint* keys, __global const int* slots,
                                  uint capacity, __global int* nbr, int vd_items) {
  int s = get_global_id(0);
  if (s >= vd_items) return;
  vd_brick_neighbours_of(s, slot_keys, keys, slots, capacity, nbr);
}

/* The field on the pool: extrapolation of members never optimised (committed by
 * vd_extrapolate_commit, which takes pool indices as it takes grid indices), and the deformed
 * positions of the vertices of the mesh over the bricks. */
__kernel void vd_sparse_extrapolate(__global const int* list, __global const int* nbr, __global const float4* def_pos,
                                    __global const float4* def_rot, float voxel_size, __global float4* pos_out,
                                    __global float4* rot_out, int vd_items) {
  int k = get_global_id(0);
  if (k >= vd_items) return;
  float4 p, r;
  vd_sparse_extrapolate_point(list[k], nbr, def_pos, def_rot, voxel_size, &p, &r);
  pos_out[k] = p;
  rot_out[k] = r;
}

/* One item per member of M (pool voxel indices); only ring points write, reading surface points. */
__kernel void vd_sparse_follow(__global const int* list, __global const uchar* surface, __global const int* nbr,
                               __global float4* def_pos, __global float4* def_rot, float voxel_size, int vd_items) {
  int k = get_global_id(0);
  if (k >= vd_items) return;
  int v = list[k];
  float4 p, r;
  if (!vd_sparse_follow_point(v, surface, nbr, def_pos, def_rot, voxel_size, &p, &r)) return;
  def_pos[v] = p;
  def_rot[v] = r;
}

/* Growth: one work item per voxel of the listed slots, each slot with its planned motion. */
__kernel void vd_sparse_grow(__global const int* grow_slots, __global const VdPose* motion,
                             __global const uint* slot_keys, __global float* tsdf, __global float* weight,
                             __global uint* color, __global float4* def_pos, VdVolume vol, VdCamera cam,
                             VdPose world_to_cam, __global const float* depth, __global const uint* rgba,
                             int vd_items) {
  int i = get_global_id(0);
  if (i >= vd_items) return;
  int b = i / VD_BRICK_VOXELS, slot = grow_slots[b];
  if (slot < 0) return;
  vd_grow_point(slot * VD_BRICK_VOXELS + i % VD_BRICK_VOXELS, motion[b], slot_keys, tsdf, weight, color, def_pos, vol,
                cam, world_to_cam, depth, rgba);
}

__kernel void vd_sparse_deform_vertices(__global const float4* grid_pos, __global const uint* keys,
                                        __global const int* slots, uint capacity, __global const int* nbr,
                                        __global const float4* def_pos, float voxel_size, __global float4* out,
                                        int vd_items) {
  int i = get_global_id(0);
  if (i >= vd_items) return;
  out[i] = vd_sparse_deform_point(grid_pos[i], keys, slots, capacity, nbr, def_pos, voxel_size);
}

/* One work item per vertex of the mesh over the bricks, with its owning point's slot. */
__kernel void vd_sparse_deform_mesh_vertices(__global const float4* grid_pos, __global const int* owner,
                                             int num_slots, __global const uint* slot_keys, __global const uint* keys,
                                             __global const int* slots, uint capacity, __global const int* nbr,
                                             __global const float4* def_pos, float voxel_size, __global float4* out,
                                             int vd_items) {
  int i = get_global_id(0);
  if (i >= vd_items) return;
  out[i] = vd_sparse_deform_vertex(grid_pos[i], owner[i], num_slots, slot_keys, keys, slots, capacity, nbr, def_pos, voxel_size);
}

/* One work item per per-pixel constraint: the compact index of its cell's first corner on the
 * bricks (-1: unusable), counted per cell (vd_constraint_count's twin); num_slots: the pool's. */
__kernel void vd_sparse_constraint_count(__global const VdCorrespondence* corr, int num_slots,
                                         __global const uint* slot_keys, __global const uint* keys,
                                         __global const int* slots, uint capacity, __global const int* nbr,
                                         __global const int* compact, __global int* cell_of, __global uint* counts,
                                         int vd_items) {
  int i = get_global_id(0);
  if (i >= vd_items) return;
  int kc = vd_sparse_constraint_cell(corr[i], num_slots, slot_keys, keys, slots, capacity, nbr, compact);
  cell_of[i] = kc;
  if (kc >= 0) atomic_inc(&counts[kc]);
}
