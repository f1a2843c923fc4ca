#include "shared/deformation.h"

__kernel void vd_deformation_reset(__global float4* def_pos, __global float4* def_rot, VdVolume vol, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int yz = get_global_id(0);
  vd_deformation_reset_row(def_pos, def_rot, yz % vol.dim_y, yz / vol.dim_y, vol);
}

/* Live (deformed) positions of the marching-cubes vertices. */
__kernel void vd_deform_vertices(__global const float4* grid_pos, __global const float4* def_pos, VdVolume vol,
                                 __global float4* out, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int i = get_global_id(0);
  out[i] = vd_deform_point(grid_pos[i], def_pos, vol);
}

/* One item per grid point. */
__kernel void vd_field_rigid(__global float4* def_pos, __global float4* def_rot, VdPose a, float4 q_a, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  vd_field_rigid_point(get_global_id(0), def_pos, def_rot, a, q_a);
}

/* Two passes so no work item reads a neighbour another is writing: compute, then commit. */
__kernel void vd_extrapolate(__global const int* list, __global const float4* def_pos,
                             __global const float4* def_rot, VdVolume vol, __global float4* pos_out,
                             __global float4* rot_out, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int k = get_global_id(0);
  float4 p, r;
  vd_extrapolate_point(list[k], def_pos, def_rot, vol, &p, &r);
  pos_out[k] = p;
  rot_out[k] = r;
}

/* One item per member of M; only ring points (surface 0) write, and they read surface points only. */
__kernel void vd_follow(__global const int* list, __global const uchar* surface, __global float4* def_pos,
                        __global float4* def_rot, VdVolume vol, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int gi = list[get_global_id(0)];
  float4 p, r;
  if (!vd_follow_point(gi, surface, def_pos, def_rot, vol, &p, &r)) return;
  def_pos[gi] = p;
  def_rot[gi] = r;
}

__kernel void vd_extrapolate_commit(__global const int* list, __global const float4* pos_in,
                                    __global const float4* rot_in, __global float4* def_pos, __global float4* def_rot,
                                    int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int k = get_global_id(0);
  def_pos[list[k]] = pos_in[k];
  def_rot[list[k]] = rot_in[k];
}
