/* The deformation field on the brick pool (issue 17; docs/SPARSE_VOLUME.md): shared/deformation.h's
 * operations with pool voxel indices (slot * 512 + local) for grid indices. Neighbours across brick
 * faces come through the per-brick neighbour table (shared/sparse_mesh.h); a canonical point's cell
 * through the hash once, for its base corner's brick. */
#ifndef VD_SPARSE_FIELD_H
#define VD_SPARSE_FIELD_H

#include "correspondence.h"
#include "deformation.h"
#include "sparse_mesh.h"

/* vd_extrapolate_gather for pool voxel v: the rigid predictions of its optimised neighbours (6 or
 * 26; with surface != 0 only surface points), a neighbour in a brick that is not allocated not
 * counting. */
VD_INLINE void vd_sparse_extrapolate_gather(int v, VD_GLOBAL const vd_uchar* surface, int faces_only,
                                            VD_GLOBAL const int* nbr, VD_GLOBAL const vd_float4* def_pos,
                                            VD_GLOBAL const vd_float4* def_rot, float voxel_size, vd_float4* disp,
                                            float* n, int* first) {
  int slot = v / VD_BRICK_VOXELS, in_brick = v % VD_BRICK_VOXELS;
  int x = in_brick % VD_BRICK, y = (in_brick / VD_BRICK) % VD_BRICK, z = in_brick / VD_BRICK_ROWS;
  *disp = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  *n = 0.0f;
  *first = -1;
  for (int k = 0; k < (faces_only ? 6 : 27); ++k) {
    int dx, dy, dz;
    if (!vd_gather_offset(faces_only, k, &dx, &dy, &dz)) continue;
    int j = faces_only ? vd_sparse_face_neighbour(nbr, slot, x, y, z, k)
                       : vd_brick_voxel_at(nbr, slot, x + dx, y + dy, z + dz);
    if (j < 0) continue;
    if (surface != 0 && !surface[j]) continue;
    vd_float4 t = def_pos[j];
    if (!(t.w > 0.0f)) continue;
    *disp = *disp + vd_extrapolate_prediction(t, def_rot[j], dx, dy, dz, voxel_size);
    *n += 1.0f;
    if (*first < 0) *first = j;
  }
}

/* vd_extrapolate_point for pool voxel v: a point never optimised starts where its optimised
 * 26-neighbours put it as rigid pieces (their mean prediction), with the first one's rotation.
 * Returns 1 when it was initialised. */
VD_INLINE int vd_sparse_extrapolate_point(int v, VD_GLOBAL const int* nbr, VD_GLOBAL const vd_float4* def_pos,
                                          VD_GLOBAL const vd_float4* def_rot, float voxel_size, vd_float4* pos_out,
                                          vd_float4* rot_out) {
  *pos_out = def_pos[v];
  *rot_out = def_rot[v];
  if (def_pos[v].w > 0.0f) return 0;
  vd_float4 disp;
  float n;
  int first;
  vd_sparse_extrapolate_gather(v, 0, 0, nbr, def_pos, def_rot, voxel_size, &disp, &n, &first);
  return vd_extrapolate_finish(disp, n, first, def_rot, pos_out, rot_out);
}

/* vd_follow_point for pool voxel v: a ring point of M follows its solved (surface) face neighbours
 * and counts the solve. Returns 1 when it moved. */
VD_INLINE int vd_sparse_follow_point(int v, VD_GLOBAL const vd_uchar* surface, VD_GLOBAL const int* nbr,
                                     VD_GLOBAL const vd_float4* def_pos, VD_GLOBAL const vd_float4* def_rot,
                                     float voxel_size, vd_float4* pos_out, vd_float4* rot_out) {
  *pos_out = def_pos[v];
  *rot_out = def_rot[v];
  if (surface[v]) return 0;
  vd_float4 disp;
  float n;
  int first;
  vd_sparse_extrapolate_gather(v, surface, 1, nbr, def_pos, def_rot, voxel_size, &disp, &n, &first);
  float w = def_pos[v].w;
  if (!vd_extrapolate_finish(disp, n, first, def_rot, pos_out, rot_out)) return 0;
  pos_out->w = w + 1.0f;
  return 1;
}

/* The pool slot and local coordinates of the brick holding global grid point (cx, cy, cz) (through
 * the hash), -1 when it is not allocated. */
VD_INLINE int vd_brick_locate(int cx, int cy, int cz, VD_GLOBAL const vd_uint* keys, VD_GLOBAL const int* slots,
                              vd_uint capacity, int* lx, int* ly, int* lz) {
  int bx = (int)floor((float)cx / (float)VD_BRICK), by = (int)floor((float)cy / (float)VD_BRICK),
      bz = (int)floor((float)cz / (float)VD_BRICK);
  *lx = cx - VD_BRICK * bx;
  *ly = cy - VD_BRICK * by;
  *lz = cz - VD_BRICK * bz;
  return vd_brick_coords_valid(bx, by, bz) ? vd_brick_find(keys, slots, capacity, vd_brick_pack(bx, by, bz)) : -1;
}

/* The pool slot and local coordinates of the brick holding global grid point (cx, cy, cz) as a
 * cell's first corner, named relative to brick `hint` (a slot of the pool, num_slots of them)
 * when the cell's corners lie within it or the bricks next to it (local -8..14), which the
 * neighbour table reaches without probing the table; otherwise, or for a hint that is not a slot
 * holding a brick, through the hash (vd_brick_locate). Either way the cell's corners come out
 * the same: only the route to them differs. */
VD_INLINE int vd_brick_locate_near(int cx, int cy, int cz, int hint, int num_slots, VD_GLOBAL const vd_uint* slot_keys,
                                   VD_GLOBAL const vd_uint* keys, VD_GLOBAL const int* slots, vd_uint capacity, int* lx,
                                   int* ly, int* lz) {
  if (hint >= 0 && hint < num_slots) {
    vd_uint key = slot_keys[hint];
    if (key != VD_BRICK_EMPTY) {
      int bx, by, bz;
      vd_brick_unpack(key, &bx, &by, &bz);
      *lx = cx - VD_BRICK * bx;
      *ly = cy - VD_BRICK * by;
      *lz = cz - VD_BRICK * bz;
      if (*lx >= -VD_BRICK && *ly >= -VD_BRICK && *lz >= -VD_BRICK && *lx < 2 * VD_BRICK - 1 &&
          *ly < 2 * VD_BRICK - 1 && *lz < 2 * VD_BRICK - 1)
        return hint;
    }
  }
  return vd_brick_locate(cx, cy, cz, keys, slots, capacity, lx, ly, lz);
}

/* t_i of corner (cx + ox, cy + oy, cz + oz) of a cell, at pool index j (vd_brick_cell_voxels; -1:
 * its brick is not allocated): its t_i, or its rest position where there is no brick (it was never
 * deformed). */
VD_INLINE vd_float4 vd_sparse_corner(int j, int cx, int cy, int cz, int ox, int oy, int oz,
                                     VD_GLOBAL const vd_float4* def_pos, float voxel_size) {
  return j >= 0
             ? def_pos[j]
             : VD_F4(voxel_size * (float)(cx + ox), voxel_size * (float)(cy + oy), voxel_size * (float)(cz + oz), 0.0f);
}

/* The trilinear blend of the 8 corners' t_i (vd_sparse_corner) of the cell with first corner
 * (cx, cy, cz) at fractions (fx, fy, fz), that corner being local point (lx, ly, lz) of `slot`. w = 1. */
VD_INLINE vd_float4 vd_sparse_blend_cell(int slot, int lx, int ly, int lz, int cx, int cy, int cz, float fx, float fy,
                                         float fz, VD_GLOBAL const int* nbr, VD_GLOBAL const vd_float4* def_pos,
                                         float voxel_size) {
  vd_float4 acc = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  int v[8];
  vd_brick_cell_voxels(nbr, slot, lx, ly, lz, v);
  for (int k = 0; k < 8; ++k) {
    int ox = k & 1, oy = (k >> 1) & 1, oz = (k >> 2) & 1;
    float a = (ox ? fx : 1.0f - fx) * (oy ? fy : 1.0f - fy) * (oz ? fz : 1.0f - fz);
    acc = acc + vd_sparse_corner(v[k], cx, cy, cz, ox, oy, oz, def_pos, voxel_size) * a;
  }
  acc.w = 1.0f;
  return acc;
}

/* S(x) for a point in global grid coordinates g (as marching cubes over the bricks emits vertices):
 * the trilinear blend of its cell's 8 corners' t_i, the cell's brick found in the table. w = 1. */
VD_INLINE vd_float4 vd_sparse_deform_point(vd_float4 g, VD_GLOBAL const vd_uint* keys, VD_GLOBAL const int* slots,
                                           vd_uint capacity, VD_GLOBAL const int* nbr,
                                           VD_GLOBAL const vd_float4* def_pos, float voxel_size) {
  int cx = (int)floor(g.x), cy = (int)floor(g.y), cz = (int)floor(g.z);
  float fx = g.x - (float)cx, fy = g.y - (float)cy, fz = g.z - (float)cz;
  int lx, ly, lz;
  int slot = vd_brick_locate(cx, cy, cz, keys, slots, capacity, &lx, &ly, &lz);
  return vd_sparse_blend_cell(slot, lx, ly, lz, cx, cy, cz, fx, fy, fz, nbr, def_pos, voxel_size);
}

/* The same for a vertex of the mesh over the bricks, whose owning point lies in the brick in slot
 * `owner` (vd_sparse_mc_vertices; num_slots slots in the pool): the vertex lies on that point's
 * edge, so its cell starts at the point or the next one along the edge, in that brick or the one
 * across its face, which the neighbour table reaches without probing the brick table
 * (vd_brick_locate_near): the same corners, so the same value. Where the slot no longer holds a
 * brick next to the cell (bricks dropped or moved since the mesh was made), the cell's brick is
 * looked up in the table. */
VD_INLINE vd_float4 vd_sparse_deform_vertex(vd_float4 g, int owner, int num_slots, VD_GLOBAL const vd_uint* slot_keys,
                                            VD_GLOBAL const vd_uint* keys, VD_GLOBAL const int* slots, vd_uint capacity,
                                            VD_GLOBAL const int* nbr, VD_GLOBAL const vd_float4* def_pos,
                                            float voxel_size) {
  int cx = (int)floor(g.x), cy = (int)floor(g.y), cz = (int)floor(g.z);
  float fx = g.x - (float)cx, fy = g.y - (float)cy, fz = g.z - (float)cz;
  int lx, ly, lz;
  int slot = vd_brick_locate_near(cx, cy, cz, owner, num_slots, slot_keys, keys, slots, capacity, &lx, &ly, &lz);
  return vd_sparse_blend_cell(slot, lx, ly, lz, cx, cy, cz, fx, fy, fz, nbr, def_pos, voxel_size);
}

/* A deformation field as the feature kernels read it: a dense grid's (keys null: t_i at grid index,
 * vol its grid) or the brick pool's (keys, slots, capacity: the table's hash; nbr: its neighbour
 * table; vol.voxel_size the voxel, points in global grid coordinates). */
#define VD_FIELD_ARGS                                                                                          \
  VD_GLOBAL const vd_float4 *def_pos, VdVolume vol, VD_GLOBAL const vd_uint *keys, VD_GLOBAL const int *slots, \
      vd_uint capacity, VD_GLOBAL const int *nbr
#define VD_FIELD_PASS def_pos, vol, keys, slots, capacity, nbr

/* S(g) and its Jacobian dS/dg (metres per grid unit) for a point in grid units: on a dense grid the
 * cell clamped to the grid as in vd_deform_point, on the bricks vd_sparse_deform_point's. */
VD_INLINE vd_float4 vd_field_deform(vd_float4 g, VD_FIELD_ARGS, VdMat3* J) {
  int cx = (int)floor(g.x), cy = (int)floor(g.y), cz = (int)floor(g.z);
  int slot = -1, lx = 0, ly = 0, lz = 0;
  if (keys) {
    slot = vd_brick_locate(cx, cy, cz, keys, slots, capacity, &lx, &ly, &lz);
  } else {
    cx = vd_min_i(vd_max_i(cx, 0), vol.dim_x - 2);
    cy = vd_min_i(vd_max_i(cy, 0), vol.dim_y - 2);
    cz = vd_min_i(vd_max_i(cz, 0), vol.dim_z - 2);
  }
  float fx = g.x - (float)cx, fy = g.y - (float)cy, fz = g.z - (float)cz;
  vd_float4 acc = VD_F4(0.0f, 0.0f, 0.0f, 0.0f);
  *J = vd_mat3_zero();
  int v[8];
  if (keys) vd_brick_cell_voxels(nbr, slot, lx, ly, lz, v);
  for (int k = 0; k < 8; ++k) {
    int ox = k & 1, oy = (k >> 1) & 1, oz = (k >> 2) & 1;
    float wx = ox ? fx : 1.0f - fx, wy = oy ? fy : 1.0f - fy, wz = oz ? fz : 1.0f - fz;
    float sx = ox ? 1.0f : -1.0f, sy = oy ? 1.0f : -1.0f, sz = oz ? 1.0f : -1.0f;
    vd_float4 t = keys ? vd_sparse_corner(v[k], cx, cy, cz, ox, oy, oz, def_pos, vol.voxel_size)
                       : def_pos[cx + ox + vol.dim_x * (cy + oy + vol.dim_y * (cz + oz))];
    acc = acc + t * (wx * wy * wz);
    vd_float4 grad = VD_F4(sx * wy * wz, wx * sy * wz, wx * wy * sz, 0.0f);
    vd_mat3_add_outer(J, t, grad);
  }
  acc.w = 1.0f;
  return acc;
}

/* Whether S may be evaluated at g: inside a dense grid; anywhere a brick may be on the bricks. */
VD_INLINE int vd_field_contains(vd_float4 g, VdVolume vol, VD_GLOBAL const vd_uint* keys) {
  if (keys)
    return vd_brick_coords_valid((int)floor(g.x / (float)VD_BRICK), (int)floor(g.y / (float)VD_BRICK),
                                 (int)floor(g.z / (float)VD_BRICK));
  return g.x >= 0.0f && g.y >= 0.0f && g.z >= 0.0f && g.x <= (float)(vol.dim_x - 1) && g.y <= (float)(vol.dim_y - 1) &&
         g.z <= (float)(vol.dim_z - 1);
}

/* vd_cell_corners on the bricks: the compact indices (compact: pool voxel -> active index) of the 8
 * corners of the cell holding global grid position g, and their trilinear weights; 0 when a corner
 * is not in M (or its brick is not allocated). hint: vd_brick_locate_near's (-1: none). */
VD_INLINE int vd_sparse_cell_corners(vd_float4 g, int hint, int num_slots, VD_GLOBAL const vd_uint* slot_keys,
                                     VD_GLOBAL const vd_uint* keys, VD_GLOBAL const int* slots, vd_uint capacity,
                                     VD_GLOBAL const int* nbr, VD_GLOBAL const int* compact, int* idx, float* alpha) {
  int cx = (int)floor(g.x), cy = (int)floor(g.y), cz = (int)floor(g.z);
  float fx = g.x - (float)cx, fy = g.y - (float)cy, fz = g.z - (float)cz;
  int lx, ly, lz;
  int slot = vd_brick_locate_near(cx, cy, cz, hint, num_slots, slot_keys, keys, slots, capacity, &lx, &ly, &lz);
  if (slot < 0) return 0;
  int v[8];
  vd_brick_cell_voxels(nbr, slot, lx, ly, lz, v);
  for (int o = 0; o < 8; ++o) {
    int ox = o & 1, oy = (o >> 1) & 1, oz = (o >> 2) & 1;
    idx[o] = v[o] >= 0 ? compact[v[o]] : -1;
    if (idx[o] < 0) return 0;
    alpha[o] = (ox ? fx : 1.0f - fx) * (oy ? fy : 1.0f - fy) * (oz ? fz : 1.0f - fz);
  }
  return 1;
}

/* vd_constraint_cell on the bricks: the compact index of the first corner of c's cell, -1 when the
 * constraint is unusable. The cell's brick is found from c's slot hint (target.w) where it can be. */
VD_INLINE int vd_sparse_constraint_cell(VdCorrespondence c, int num_slots, VD_GLOBAL const vd_uint* slot_keys,
                                        VD_GLOBAL const vd_uint* keys, VD_GLOBAL const int* slots, vd_uint capacity,
                                        VD_GLOBAL const int* nbr, VD_GLOBAL const int* compact) {
  if (!(c.canonical.w > 0.0f)) return -1;
  int idx[8];
  float alpha[8];
  /* A hint is a slot number held exactly in a float; anything else is no hint. */
  int hint = c.target.w >= 0.0f && c.target.w < (float)num_slots ? (int)c.target.w : -1;
  if (!vd_sparse_cell_corners(c.canonical, hint, num_slots, slot_keys, keys, slots, capacity, nbr, compact, idx, alpha))
    return -1;
  return idx[0];
}

/* Growth (core/growth.h): pool voxel v of a brick that depth the live model does not explain falls
 * in. A voxel never fused (weight 0) whose deformed position lies within the depth's truncation
 * band is fused once, ungated: at its own t_i where the solver has optimised it, otherwise at its
 * rest position moved by the brick's planned rigid motion (written back as its t_i, still w = 0:
 * never optimised, so extrapolation from optimised neighbours refines it). A fused voxel is left to
 * the solve and the gated fusion. */
VD_INLINE void vd_grow_point(int v, VdPose motion, VD_GLOBAL const vd_uint* slot_keys, VD_GLOBAL float* tsdf,
                             VD_GLOBAL float* weight, VD_GLOBAL vd_uint* color, VD_GLOBAL vd_float4* def_pos,
                             VdVolume vol, VdCamera cam, VdPose world_to_cam, VD_GLOBAL const float* depth,
                             VD_GLOBAL const vd_uint* rgba) {
  if (weight[v] > 0.0f) return;
  vd_float4 t = def_pos[v];
  int planned = !(t.w > 0.0f);
  if (planned) t = vd_pose_apply(motion, vd_pool_rest_position(slot_keys, v, vol.voxel_size));
  /* Only within the truncation band of the depth: free space in front is left to the gated fusion
   * (fused here, it would give the surface's unobserved edges cells to mesh). */
  vd_float4 p = t;
  p.w = 1.0f;
  vd_float4 pc = vd_pose_apply(world_to_cam, p);
  if (!(pc.z > 0.0f)) return;
  int px = (int)floor(vd_project_u(cam, pc) + 0.5f), py = (int)floor(vd_project_v(cam, pc) + 0.5f);
  if (px < 0 || py < 0 || px >= cam.width || py >= cam.height) return;
  float d = depth[py * cam.width + px];
  if (!(d > 0.0f) || fabs(d - pc.z) > vol.truncation) return;
  if (planned) {
    t.w = 0.0f;
    def_pos[v] = t;
  }
  VdFusionParams ungated;
  ungated.k_min = 0.0f;
  ungated.k_min_new = 0.0f;
  ungated.carve_rate = 0.0f;
  ungated.carve_radius = 0;
  vd_tsdf_integrate_deformed(tsdf, weight, color, v, t, ungated, vol, cam, world_to_cam, depth, rgba);
}

#endif /* VD_SPARSE_FIELD_H */
