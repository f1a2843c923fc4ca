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
/* Running average of a grid point's colour with an observation inside the band (one that carries
 * colour: alpha != 0). */
VD_INLINE void vd_tsdf_fuse_color(VD_GLOBAL vd_uint* color, int index, vd_uint c_obs) {
  if ((c_obs >> 24) == 0u) return;
  vd_float4 c_old = vd_unpack_rgba(color[index]);
  vd_float4 c_new = vd_unpack_rgba(c_obs);
  /* Colour weight counts only observations that carried colour (alpha holds up to 255). */
  float cw = c_old.w;
  float cw_new = fmin(cw + 1.0f, 255.0f);
  vd_float4 c = (c_old * cw + c_new) / (cw + 1.0f);
  color[index] = vd_pack_rgba(c.x, c.y, c.z, cw_new);
}

#if defined(__OPENCL_C_VERSION__) && VD_LANES > 1
/* vd_tsdf_fuse_color on VD_LANES consecutive voxels from index0 at once: the lanes where `take` is
 * set and the observation carries colour (alpha > 0) average it in, with vd_tsdf_fuse_color's
 * arithmetic in its order (so the same bits), the others keep theirs. */
VD_INLINE void vd_tsdf_fuse_color_lanes(VD_GLOBAL vd_uint* color, int index0, vd_lu c_obs, vd_li take) {
  vd_lu c_old = vd_lload(color + index0);
  take = take & (vd_li)((c_obs >> 24) != (vd_lu)0u);
  vd_lf cw = vd_lu_to_lf(c_old >> 24), inv = cw + 1.0f;
  vd_lf r = (vd_lu_to_lf(c_old & 255u) * cw + vd_lu_to_lf(c_obs & 255u)) / inv;
  vd_lf g = (vd_lu_to_lf((c_old >> 8) & 255u) * cw + vd_lu_to_lf((c_obs >> 8) & 255u)) / inv;
  vd_lf b = (vd_lu_to_lf((c_old >> 16) & 255u) * cw + vd_lu_to_lf((c_obs >> 16) & 255u)) / inv;
  vd_lf a = fmin(cw + 1.0f, 255.0f);
  vd_lu packed = vd_lf_to_lu(clamp(r + 0.5f, 0.0f, 255.0f)) | (vd_lf_to_lu(clamp(g + 0.5f, 0.0f, 255.0f)) << 8) |
                 (vd_lf_to_lu(clamp(b + 0.5f, 0.0f, 255.0f)) << 16) |
                 (vd_lf_to_lu(clamp(a + 0.5f, 0.0f, 255.0f)) << 24);
  vd_lstore(select(c_old, packed, take), color + index0);
}
#endif

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
  if (fabs(sdf) < vol.truncation) vd_tsdf_fuse_color(color, index, rgba[pix]);
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

/* Non-rigid fusion parameters (EngineParams: --k-min, --k-min-new, --carve-rate, --carve-radius). */
typedef struct {
  /* Optimisations a grid point takes part in before it is fused (section 8's K_min), and before
   * a point never fused before is (new space: its deformation started as an extrapolation). */
  float k_min;
  float k_min_new;
  /* Carving: the share of its weight a fused grid point loses each frame the depth sees it as free
   * space (0 = none), and the half-width in pixels of the window that must all agree. */
  float carve_rate;
  int carve_radius;
} VdFusionParams;

/* 1 when the depth says camera point p_cam lies in free space: every pixel of the
 * (2 radius + 1)^2 window around its projection has valid depth more than one truncation band
 * behind it. The window keeps silhouettes (a point on the object's rim that a slightly wrong
 * deformation projects onto the background) and depth holes from carving the surface. */
VD_INLINE int vd_depth_says_free(vd_float4 p_cam, int radius, VdCamera cam, VD_GLOBAL const float* depth,
                                 float truncation) {
  if (p_cam.z <= 0.0f) return 0;
  int px = (int)floor(vd_project_u(cam, p_cam) + 0.5f), py = (int)floor(vd_project_v(cam, p_cam) + 0.5f);
  if (px - radius < 0 || py - radius < 0 || px + radius >= cam.width || py + radius >= cam.height) return 0;
  for (int y = py - radius; y <= py + radius; ++y)
    for (int x = px - radius; x <= px + radius; ++x) {
      float d = depth[y * cam.width + x];
      if (!(d > 0.0f) || d - p_cam.z <= truncation) return 0;
    }
  return 1;
}

/* Non-rigid fusion (section 8) of active grid point gi at its deformed world position t (w = the
 * number of optimisations it took part in): fused only after at least k_min optimisations, so data
 * goes only where the deformation is well defined. A point never fused before (weight 0: space
 * first seen now, such as the far side of a part that turned towards the camera) waits for
 * k_min_new: its deformation started as an extrapolation, and data fused before it settles is
 * geometry at the wrong canonical place that later frames cannot remove (docs/BENCHMARKS.md
 * "Long takes"). Carving: a fused point that holds surface (tsdf < 1) where the depth sees free
 * space first loses carve_rate of its weight, so geometry the scene no longer has (fused with a
 * since-corrected deformation, or a part that moved) is unlearnt in a few frames rather than in
 * max_weight / 2 of them. */
VD_INLINE void vd_tsdf_integrate_deformed(VD_GLOBAL float* tsdf, VD_GLOBAL float* weight, VD_GLOBAL vd_uint* color,
                                          int gi, vd_float4 t, VdFusionParams fp, VdVolume vol, VdCamera cam,
                                          VdPose world_to_cam, VD_GLOBAL const float* depth,
                                          VD_GLOBAL const vd_uint* rgba) {
  float w = weight[gi];
  if (t.w < (w > 0.0f ? fp.k_min : fp.k_min_new)) return;
  t.w = 1.0f;
  vd_float4 p_cam = vd_pose_apply(world_to_cam, t);
  if (fp.carve_rate > 0.0f && w > 0.0f && tsdf[gi] < 1.0f &&
      vd_depth_says_free(p_cam, fp.carve_radius, cam, depth, vol.truncation))
    weight[gi] = w * (1.0f - fp.carve_rate);
  vd_tsdf_integrate_point(tsdf, weight, color, gi, p_cam, vol, cam, depth, rgba);
}

/* Bricks: 8^3 blocks of grid points, numbered x-fastest like the grid. Integration may run over
 * the bricks the truncation band of some frame has touched ("allocated" bricks, kept across frames)
 * instead of the whole grid, as hashed-block systems do: voxels outside them are only free space
 * (sdf beyond the band) and unobserved space, which marching cubes never meshes. */
#define VD_BRICK 8
VD_INLINE int vd_bricks_x(VdVolume vol) { return (vol.dim_x + VD_BRICK - 1) / VD_BRICK; }
VD_INLINE int vd_bricks_y(VdVolume vol) { return (vol.dim_y + VD_BRICK - 1) / VD_BRICK; }
VD_INLINE int vd_bricks_z(VdVolume vol) { return (vol.dim_z + VD_BRICK - 1) / VD_BRICK; }

/* Touched bricks: touched[b] == 0 promises that no grid point of brick b holds weight, so the
 * passes that look for observed cells (marching cubes' classification) skip the brick without
 * reading it. Fusion keeps the promise by flagging every brick it gives weight to (a flag may stay
 * set after carving empties a brick: that costs time, not correctness); vd_brick_touched_from
 * rebuilds a flag from the weights after the host wrote them. */
VD_INLINE int vd_grid_brick(VdVolume vol, int x, int y, int z) {
  return x / VD_BRICK + vd_bricks_x(vol) * (y / VD_BRICK + vd_bricks_y(vol) * (z / VD_BRICK));
}

VD_INLINE int vd_grid_brick_of_index(VdVolume vol, int gi) {
  int x = gi % vol.dim_x, yz = gi / vol.dim_x;
  return vd_grid_brick(vol, x, yz % vol.dim_y, yz / vol.dim_y);
}

VD_INLINE vd_uchar vd_brick_touched_from(VD_GLOBAL const float* weight, VdVolume vol, int b) {
  int nbx = vd_bricks_x(vol), nby = vd_bricks_y(vol);
  int x0 = (b % nbx) * VD_BRICK, y0 = ((b / nbx) % nby) * VD_BRICK, z0 = (b / (nbx * nby)) * VD_BRICK;
  int x1 = vd_min_i(x0 + VD_BRICK, vol.dim_x), y1 = vd_min_i(y0 + VD_BRICK, vol.dim_y);
  int z1 = vd_min_i(z0 + VD_BRICK, vol.dim_z);
  for (int z = z0; z < z1; ++z)
    for (int y = y0; y < y1; ++y) {
      int row = vol.dim_x * (y + vol.dim_y * z);
      for (int x = x0; x < x1; ++x)
        if (weight[row + x] > 0.0f) return (vd_uchar)1;
    }
  return (vd_uchar)0;
}

/* Depth tiles: the minimum and maximum valid depth of each VD_DEPTH_TILE^2 pixel tile (x = min,
 * y = max; min > max when the tile has no valid depth), the coarse image the brick test reads. */
#define VD_DEPTH_TILE 4
VD_INLINE int vd_depth_tiles_x(VdCamera cam) { return (cam.width + VD_DEPTH_TILE - 1) / VD_DEPTH_TILE; }
VD_INLINE int vd_depth_tiles_y(VdCamera cam) { return (cam.height + VD_DEPTH_TILE - 1) / VD_DEPTH_TILE; }

/* The minimum and maximum valid depth of the pixels [x0, x1) x [y0, y1) (x = min, y = max; min >
 * max when none is valid). */
VD_INLINE vd_float4 vd_depth_range(VD_GLOBAL const float* depth, VdCamera cam, int x0, int y0, int x1, int y1) {
  float lo = 3.4e38f, hi = -3.4e38f;
  for (int y = y0; y < y1; ++y)
    for (int x = x0; x < x1; ++x) {
      float d = depth[y * cam.width + x];
      if (d > 0.0f) {
        lo = fmin(lo, d);
        hi = fmax(hi, d);
      }
    }
  return VD_F4(lo, hi, 0.0f, 0.0f);
}

VD_INLINE vd_float4 vd_depth_tile(int tile, VD_GLOBAL const float* depth, VdCamera cam) {
  int tx = tile % vd_depth_tiles_x(cam), ty = tile / vd_depth_tiles_x(cam);
  return vd_depth_range(depth, cam, tx * VD_DEPTH_TILE, ty * VD_DEPTH_TILE,
                        vd_min_i((tx + 1) * VD_DEPTH_TILE, cam.width), vd_min_i((ty + 1) * VD_DEPTH_TILE, cam.height));
}

/* 1 when the box of grid points [x0, x1] x [y0, y1] x [z0, z1] (inclusive) may hold a grid point
 * that integration updates within the truncation band: some valid depth d under the box's
 * projected footprint (nearest-pixel rounding included) with d - z in [-truncation, truncation]
 * for z in the box's camera depth range. Conservative: a box it passes may still hold none (it
 * then costs time, not correctness). */
VD_INLINE vd_uint vd_box_in_band(int x0, int y0, int z0, int x1, int y1, int z1, VD_GLOBAL const vd_float4* tiles,
                                 VdCamera cam, VdPose world_to_cam, VdVolume vol) {
  float zmin = 3.4e38f, zmax = -3.4e38f, umin = 3.4e38f, umax = -3.4e38f, vmin = 3.4e38f, vmax = -3.4e38f;
  int behind = 0;
  for (int c = 0; c < 8; ++c) {
    vd_float4 p = vd_pose_apply(world_to_cam, vd_voxel_position(vol, (c & 1) ? x1 : x0, (c & 2) ? y1 : y0,
                                                                (c & 4) ? z1 : z0));
    zmin = fmin(zmin, p.z);
    zmax = fmax(zmax, p.z);
    if (p.z <= 1e-4f) {
      behind = 1;
      continue;
    }
    float u = vd_project_u(cam, p), v = vd_project_v(cam, p);
    umin = fmin(umin, u);
    umax = fmax(umax, u);
    vmin = fmin(vmin, v);
    vmax = fmax(vmax, v);
  }
  if (zmax <= 0.0f) return 0u;
  int px0 = 0, px1 = cam.width - 1, py0 = 0, py1 = cam.height - 1;
  if (!behind) {
    px0 = vd_max_i((int)floor(umin + 0.5f), 0);
    px1 = vd_min_i((int)floor(umax + 0.5f), cam.width - 1);
    py0 = vd_max_i((int)floor(vmin + 0.5f), 0);
    py1 = vd_min_i((int)floor(vmax + 0.5f), cam.height - 1);
    if (px0 > px1 || py0 > py1) return 0u;
  }
  float lo = zmin - vol.truncation, hi = zmax + vol.truncation;
  int ntx = vd_depth_tiles_x(cam);
  for (int ty = py0 / VD_DEPTH_TILE; ty <= py1 / VD_DEPTH_TILE; ++ty)
    for (int tx = px0 / VD_DEPTH_TILE; tx <= px1 / VD_DEPTH_TILE; ++tx) {
      vd_float4 t = tiles[ty * ntx + tx];
      if (t.x <= hi && t.y >= lo) return 1u;
    }
  return 0u;
}

/* 1 when brick b may hold a grid point in the band (vd_box_in_band over the whole brick). */
VD_INLINE vd_uint vd_brick_in_band(int b, VD_GLOBAL const vd_float4* tiles, VdCamera cam, VdPose world_to_cam,
                                   VdVolume vol) {
  int nbx = vd_bricks_x(vol), nby = vd_bricks_y(vol);
  int bx = b % nbx, by = (b / nbx) % nby, bz = b / (nbx * nby);
  int x0 = bx * VD_BRICK, y0 = by * VD_BRICK, z0 = bz * VD_BRICK;
  return vd_box_in_band(x0, y0, z0, vd_min_i(x0 + VD_BRICK - 1, vol.dim_x - 1), vd_min_i(y0 + VD_BRICK - 1, vol.dim_y - 1),
                        vd_min_i(z0 + VD_BRICK - 1, vol.dim_z - 1), tiles, cam, world_to_cam, vol);
}

/* The octants of brick b (its (VD_BRICK/2)^3 corners; bit ox + 2 oy + 4 oz) that may hold a grid
 * point in the band; 0 when the brick holds none. Integration skips the other octants: the band
 * crosses a brick as a slab, so a passing brick typically has octants wholly in front of or
 * behind it. */
VD_INLINE vd_uint vd_brick_octants(int b, VD_GLOBAL const vd_float4* tiles, VdCamera cam, VdPose world_to_cam,
                                   VdVolume vol) {
  if (!vd_brick_in_band(b, tiles, cam, world_to_cam, vol)) return 0u;
  int nbx = vd_bricks_x(vol), nby = vd_bricks_y(vol);
  int bx = b % nbx, by = (b / nbx) % nby, bz = b / (nbx * nby);
  const int h = VD_BRICK / 2;
  vd_uint mask = 0u;
  for (int o = 0; o < 8; ++o) {
    int x0 = bx * VD_BRICK + (o & 1) * h, y0 = by * VD_BRICK + ((o >> 1) & 1) * h, z0 = bz * VD_BRICK + (o >> 2) * h;
    if (x0 >= vol.dim_x || y0 >= vol.dim_y || z0 >= vol.dim_z) continue;
    if (vd_box_in_band(x0, y0, z0, vd_min_i(x0 + h - 1, vol.dim_x - 1), vd_min_i(y0 + h - 1, vol.dim_y - 1),
                       vd_min_i(z0 + h - 1, vol.dim_z - 1), tiles, cam, world_to_cam, vol))
      mask |= 1u << o;
  }
  return mask;
}

/* Work items per brick of the brick integration: one per z-slice of VD_BRICK^2 grid points, so
 * the per-item set-up is shared by 64 points and the inner loop walks contiguous x. */
#define VD_BRICK_ITEMS VD_BRICK

/* Work item `item` of the brick integration: slice (item % VD_BRICK) of brick list[item / VD_BRICK],
 * only in the octants masks[brick] names (vd_brick_octants). */
VD_INLINE void vd_tsdf_integrate_brick_row(int item, VD_GLOBAL const vd_uint* list, VD_GLOBAL const vd_uint* masks,
                                           VD_GLOBAL float* tsdf, VD_GLOBAL float* weight, VD_GLOBAL vd_uint* color,
                                           VdVolume vol, VdCamera cam, VdPose world_to_cam,
                                           VD_GLOBAL const float* depth, VD_GLOBAL const vd_uint* rgba) {
  int b = (int)list[item / VD_BRICK_ITEMS], r = item % VD_BRICK_ITEMS;
  int nbx = vd_bricks_x(vol), nby = vd_bricks_y(vol);
  int bx = b % nbx, by = (b / nbx) % nby, bz = b / (nbx * nby);
  int z = bz * VD_BRICK + r;
  if (z >= vol.dim_z) return;
  const int h = VD_BRICK / 2;
  /* The octant bits of this slice's half in z: bit ox + 2 oy. */
  vd_uint mask = (masks[b] >> (r >= h ? 4 : 0)) & 15u;
  if (mask == 0u) return;
  vd_float4 step = vd_pose_rotate(world_to_cam, VD_F4(vol.voxel_size, 0.0f, 0.0f, 0.0f));
  for (int oy = 0; oy < 2; ++oy) {
    if ((mask & (3u << (2 * oy))) == 0u) continue;
    int y0 = by * VD_BRICK + oy * h, y1 = vd_min_i(y0 + h, vol.dim_y);
    for (int ox = 0; ox < 2; ++ox) {
      if ((mask & (1u << (2 * oy + ox))) == 0u) continue;
      int x0 = bx * VD_BRICK + ox * h, x1 = vd_min_i(x0 + h, vol.dim_x);
      for (int y = y0; y < y1; ++y) {
        vd_float4 p0 = vd_pose_apply(world_to_cam, vd_voxel_position(vol, x0, y, z));
        int row = vol.dim_x * (y + vol.dim_y * z);
        for (int x = x0; x < x1; ++x) {
          vd_float4 p = p0 + step * (float)(x - x0);
          vd_tsdf_integrate_point(tsdf, weight, color, row + x, p, vol, cam, depth, rgba);
        }
      }
    }
  }
}

#endif /* VD_TSDF_H */
