/* The active set M of VolumeDeform (section 4): grid points of the cells the isosurface crosses
 * (cells that emit marching-cubes triangles) plus their one-ring (6-neighbourhood). Built with
 * gathers only (no write races): pass 1 flags surface points, pass 2 dilates, then per-row counts
 * are scanned and each row writes its compact indices. */
#ifndef VD_ACTIVE_SET_H
#define VD_ACTIVE_SET_H

#include "marching_cubes.h"

/* 1 when grid point (x, y, z) is a corner of a cell with triangles. codes: marching-cubes cell
 * codes; tri_counts: triangles per cube index. */
VD_INLINE vd_uchar vd_active_surface_point(VD_GLOBAL const vd_ushort* codes, VD_GLOBAL const vd_uchar* tri_counts,
                                           VdVolume vol, int x, int y, int z) {
  for (int k = 0; k < 8; ++k) {
    int cx = x - (k & 1), cy = y - ((k >> 1) & 1), cz = z - ((k >> 2) & 1);
    if (cx < 0 || cy < 0 || cz < 0) continue;
    vd_uint code = vd_mc_code_at(codes, vol, cx, cy, cz);
    if ((code & VD_MC_VALID) && tri_counts[code & 255u] > 0) return 1;
  }
  return 0;
}

/* Whether a point at p (world metres) lies in front of the camera and projects into its image
 * widened by `margin` times the image's size on each side: the solver's points are limited to the
 * view (EngineParams::solve_view_margin). */
VD_INLINE int vd_point_in_view(vd_float4 p, VdCamera cam, VdPose world_to_cam, float margin) {
  vd_float4 c = vd_pose_apply(world_to_cam, p);
  if (!(c.z > 1e-3f)) return 0;
  float u = cam.fx * c.x / c.z + cam.cx, v = cam.fy * c.y / c.z + cam.cy;
  float mu = margin * (float)cam.width, mv = margin * (float)cam.height;
  return u >= -mu && u <= (float)cam.width + mu && v >= -mv && v <= (float)cam.height + mv;
}

/* Row r (row_len points from r * row_len, a dense grid row or 8 points of a brick) of the solved
 * flags: the surface points in view. Returns the row's count. */
VD_INLINE vd_uint vd_active_in_view_row(int r, int row_len, VD_GLOBAL const vd_uchar* surface,
                                        VD_GLOBAL const vd_uint* row_surface, VD_GLOBAL const vd_float4* def_pos,
                                        VdCamera cam, VdPose world_to_cam, float margin, VD_GLOBAL vd_uchar* solved) {
  vd_uint n = 0u;
  int skip = row_surface[r] == 0u;
  for (int x = 0; x < row_len; ++x) {
    int v = r * row_len + x;
    vd_uchar s = (vd_uchar)(!skip && surface[v] && vd_point_in_view(def_pos[v], cam, world_to_cam, margin));
    solved[v] = s;
    n += s;
  }
  return n;
}

/* Whether grid row (y, z) or one of its 4 neighbouring rows holds a surface point. */
VD_INLINE int vd_active_row_near_surface(VD_GLOBAL const vd_uint* row_surface, VdVolume vol, int y, int z) {
  int yz = y + vol.dim_y * z;
  if (row_surface[yz] > 0u) return 1;
  if (y > 0 && row_surface[yz - 1] > 0u) return 1;
  if (y < vol.dim_y - 1 && row_surface[yz + 1] > 0u) return 1;
  if (z > 0 && row_surface[yz - vol.dim_y] > 0u) return 1;
  if (z < vol.dim_z - 1 && row_surface[yz + vol.dim_y] > 0u) return 1;
  return 0;
}

/* 1 when grid point (x, y, z) is a surface point or a 6-neighbour of one. */
VD_INLINE vd_uchar vd_active_dilate_point(VD_GLOBAL const vd_uchar* surface, VdVolume vol, int x, int y, int z) {
  int i = vd_grid_index(vol, x, y, z);
  if (surface[i]) return 1;
  if (x > 0 && surface[i - 1]) return 1;
  if (x < vol.dim_x - 1 && surface[i + 1]) return 1;
  if (y > 0 && surface[i - vol.dim_x]) return 1;
  if (y < vol.dim_y - 1 && surface[i + vol.dim_x]) return 1;
  int plane = vol.dim_x * vol.dim_y;
  if (z > 0 && surface[i - plane]) return 1;
  if (z < vol.dim_z - 1 && surface[i + plane]) return 1;
  return 0;
}

/* Compact indices of the 6-neighbours of grid point (x, y, z) (-1 where outside M or the grid),
 * in the order -x, +x, -y, +y, -z, +z. compact: dense grid -> compact index map (-1 outside M). */
VD_INLINE void vd_active_neighbours_of(VD_GLOBAL const int* compact, VdVolume vol, int x, int y, int z,
                                    VD_GLOBAL int* out) {
  int i = vd_grid_index(vol, x, y, z);
  int plane = vol.dim_x * vol.dim_y;
  out[0] = x > 0 ? compact[i - 1] : -1;
  out[1] = x < vol.dim_x - 1 ? compact[i + 1] : -1;
  out[2] = y > 0 ? compact[i - vol.dim_x] : -1;
  out[3] = y < vol.dim_y - 1 ? compact[i + vol.dim_x] : -1;
  out[4] = z > 0 ? compact[i - plane] : -1;
  out[5] = z < vol.dim_z - 1 ? compact[i + plane] : -1;
}

#endif /* VD_ACTIVE_SET_H */
