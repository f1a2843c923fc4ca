#include "cpu_ref/cpu_ref.h"

#include <numeric>

#include "ocl/mc_table.h"
#include "shared/active_set.h"
#include "shared/deformation.h"
#include "shared/hierarchy.h"
#include "shared/marching_cubes.h"
#include "shared/preprocess.h"
#include "shared/raster.h"
#include "shared/tsdf.h"

namespace vd::cpu {

void DepthConvert(const uint16_t* raw, float* depth, int n, float inv_scale, float min_depth, float max_depth) {
#pragma omp parallel for schedule(static)
  for (int i = 0; i < n; ++i) depth[i] = vd_depth_convert_pixel(raw[i], inv_scale, min_depth, max_depth);
}

void Bilateral(const float* in, float* out, int width, int height, int radius, float sigma_space_px,
               float sigma_depth_m) {
  const float is = 0.5f / (sigma_space_px * sigma_space_px);
  const float id = 0.5f / (sigma_depth_m * sigma_depth_m);
#pragma omp parallel for schedule(static)
  for (int i = 0; i < width * height; ++i) out[i] = vd_bilateral_pixel(in, width, height, i % width, i / width, radius, is, id);
}

void Intensity(const uint32_t* rgba, float* out, int width, int height) {
  const int w = width / 2, h = height / 2, n = w * h;
  std::vector<float> luma(static_cast<size_t>(n)), tmp(static_cast<size_t>(n));
#pragma omp parallel for schedule(static)
  for (int i = 0; i < n; ++i) luma[i] = vd_luma_half_pixel(rgba, width, i % w, i / w);
#pragma omp parallel for schedule(static)
  for (int i = 0; i < n; ++i) tmp[i] = vd_hblur_pixel(luma.data(), w, i % w, i / w);
#pragma omp parallel for schedule(static)
  for (int i = 0; i < n; ++i) out[i] = vd_vblur_pixel(tmp.data(), w, h, i % w, i / w);
}

void PyrDown(const float* in, float* out, int width, int height, float max_diff) {
  const int ow = width / 2, oh = height / 2;
#pragma omp parallel for schedule(static)
  for (int i = 0; i < ow * oh; ++i) out[i] = vd_pyr_down_pixel(in, width, i % ow, i / ow, max_diff);
}

void VertexMap(const float* depth, vd_float4* vmap, VdCamera cam) {
#pragma omp parallel for schedule(static)
  for (int i = 0; i < cam.width * cam.height; ++i) vmap[i] = vd_vertex_pixel(depth, cam, i % cam.width, i / cam.width);
}

void NormalMap(const vd_float4* vmap, vd_float4* nmap, int width, int height, float max_jump) {
#pragma omp parallel for schedule(static)
  for (int i = 0; i < width * height; ++i) nmap[i] = vd_normal_pixel(vmap, width, height, i % width, i / width, max_jump);
}

void IntegrateTsdf(float* tsdf, float* weight, uint32_t* color, VdVolume vol, VdCamera cam, VdPose world_to_cam,
                   const float* depth, const uint32_t* rgba) {
  const int rows = vol.dim_y * vol.dim_z;
#pragma omp parallel for schedule(static)
  for (int r = 0; r < rows; ++r)
    vd_tsdf_integrate_row(tsdf, weight, color, r % vol.dim_y, r / vol.dim_y, vol, cam, world_to_cam, depth, rgba);
}

void IntegrateActive(float* tsdf, float* weight, uint32_t* color, const int* list, int n, const vd_float4* def_pos,
                     VdFusionParams fp, VdVolume vol, VdCamera cam, VdPose world_to_cam, const float* depth,
                     const uint32_t* rgba) {
#pragma omp parallel for schedule(static)
  for (int k = 0; k < n; ++k)
    vd_tsdf_integrate_deformed(tsdf, weight, color, list[k], def_pos[list[k]], fp, vol, cam, world_to_cam, depth, rgba);
}

std::vector<uint8_t> VolumeTouched(const float* weight, VdVolume vol) {
  std::vector<uint8_t> touched(size_t(vd_bricks_x(vol)) * vd_bricks_y(vol) * vd_bricks_z(vol));
  for (size_t b = 0; b < touched.size(); ++b) touched[b] = vd_brick_touched_from(weight, vol, int(b));
  return touched;
}

void TransformField(vd_float4* def_pos, vd_float4* def_rot, int n, VdPose a, vd_float4 q_a) {
#pragma omp parallel for schedule(static)
  for (int i = 0; i < n; ++i) vd_field_rigid_point(i, def_pos, def_rot, a, q_a);
}

void DeformationReset(vd_float4* def_pos, vd_float4* def_rot, VdVolume vol) {
  const int rows = vol.dim_y * vol.dim_z;
#pragma omp parallel for schedule(static)
  for (int r = 0; r < rows; ++r) vd_deformation_reset_row(def_pos, def_rot, r % vol.dim_y, r / vol.dim_y, vol);
}

void DeformVertices(const vd_float4* grid_pos, int n, const vd_float4* def_pos, VdVolume vol, vd_float4* out) {
#pragma omp parallel for schedule(static)
  for (int i = 0; i < n; ++i) out[i] = vd_deform_point(grid_pos[i], def_pos, vol);
}

void Extrapolate(const int* list, int n, vd_float4* def_pos, vd_float4* def_rot, VdVolume vol) {
  std::vector<vd_float4> pos(n), rot(n);
#pragma omp parallel for schedule(static)
  for (int k = 0; k < n; ++k) vd_extrapolate_point(list[k], def_pos, def_rot, vol, &pos[k], &rot[k]);
  for (int k = 0; k < n; ++k) {
    def_pos[list[k]] = pos[k];
    def_rot[list[k]] = rot[k];
  }
}

McMesh MarchingCubes(const float* tsdf, const float* weight, const uint32_t* color, VdVolume vol) {
  const McTable& table = GetMcTable();
  const int n = vol.dim_x * vol.dim_y * vol.dim_z;
  std::vector<uint16_t> codes(n);
  std::vector<uint8_t> masks(n);
  std::vector<uint32_t> vert_count(n), tri_count(n);
#pragma omp parallel for schedule(static)
  for (int i = 0; i < n; ++i) {
    const int x = i % vol.dim_x, yz = i / vol.dim_x;
    codes[i] = static_cast<uint16_t>(vd_mc_cell_code(tsdf, weight, vol, x, yz % vol.dim_y, yz / vol.dim_y));
    tri_count[i] = (codes[i] & VD_MC_VALID) ? table.counts[codes[i] & 255] : 0;
  }
#pragma omp parallel for schedule(static)
  for (int i = 0; i < n; ++i) {
    const int x = i % vol.dim_x, yz = i / vol.dim_x;
    masks[i] = static_cast<uint8_t>(vd_mc_vertex_mask(tsdf, codes.data(), vol, x, yz % vol.dim_y, yz / vol.dim_y));
    vert_count[i] = static_cast<uint32_t>(vd_popcount3(masks[i]));
  }
  // Independent of the device's chunked scan: the standard library's.
  std::vector<uint32_t> vert_offset(n), tri_offset(n);
  std::exclusive_scan(vert_count.begin(), vert_count.end(), vert_offset.begin(), 0u);
  std::exclusive_scan(tri_count.begin(), tri_count.end(), tri_offset.begin(), 0u);
  const uint32_t nv = n ? vert_offset[n - 1] + vert_count[n - 1] : 0;
  const uint32_t nt = n ? tri_offset[n - 1] + tri_count[n - 1] : 0;
  McMesh mesh;
  mesh.positions_grid.resize(nv);
  mesh.normals.resize(nv);
  mesh.colors.resize(nv);
  mesh.triangles.resize(3 * static_cast<size_t>(nt));
#pragma omp parallel for schedule(static)
  for (int i = 0; i < n; ++i) {
    if (!masks[i]) continue;
    const int x = i % vol.dim_x, yz = i / vol.dim_x, y = yz % vol.dim_y, z = yz / vol.dim_y;
    uint32_t out = vert_offset[i];
    for (int a = 0; a < 3; ++a) {
      if (!(masks[i] & (1u << a))) continue;
      vd_mc_make_vertex(tsdf, color, vol, x, y, z, a, &mesh.positions_grid[out], &mesh.normals[out], &mesh.colors[out]);
      ++out;
    }
  }
#pragma omp parallel for schedule(static)
  for (int i = 0; i < n; ++i) {
    if (!(codes[i] & VD_MC_VALID)) continue;
    const int x = i % vol.dim_x, yz = i / vol.dim_x, y = yz % vol.dim_y, z = yz / vol.dim_y;
    const int8_t* row = &table.triangles[16 * (codes[i] & 255)];
    for (int k = 0; row[k] >= 0; ++k)
      mesh.triangles[3 * static_cast<size_t>(tri_offset[i]) + k] =
          vd_mc_edge_vertex(masks.data(), vert_offset.data(), vol, x, y, z, row[k]);
  }
  mesh.codes = std::move(codes);
  return mesh;
}

std::vector<uint8_t> ActiveInView(const std::vector<uint8_t>& surface, const vd_float4* def_pos, int row_len,
                                  VdCamera cam, VdPose world_to_cam, float margin) {
  const int rows = int(surface.size() / size_t(row_len));
  std::vector<vd_uint> row_surface(rows, 0u);
  for (int r = 0; r < rows; ++r)
    for (int x = 0; x < row_len; ++x) row_surface[r] += surface[size_t(r) * row_len + x];
  std::vector<uint8_t> solved(surface.size(), 0);
  for (int r = 0; r < rows; ++r)
    vd_active_in_view_row(r, row_len, surface.data(), row_surface.data(), def_pos, cam, world_to_cam, margin,
                          solved.data());
  return solved;
}

void Follow(const int* list, int n, const uint8_t* surface, vd_float4* def_pos, vd_float4* def_rot, VdVolume vol) {
  std::vector<vd_float4> pos(n), rot(n);
#pragma omp parallel for schedule(static)
  for (int k = 0; k < n; ++k) vd_follow_point(list[k], surface, def_pos, def_rot, vol, &pos[k], &rot[k]);
  for (int k = 0; k < n; ++k) {
    def_pos[list[k]] = pos[k];
    def_rot[list[k]] = rot[k];
  }
}

namespace {

// Sequential compaction of the flagged points of a dense grid: list, map and 6-neighbours.
ActiveSet CompactMembers(const std::vector<uint8_t>& member, VdVolume vol) {
  ActiveSet out;
  out.compact.assign(member.size(), -1);
  for (size_t i = 0; i < member.size(); ++i) {
    if (!member[i]) continue;
    out.compact[i] = int32_t(out.list.size());
    out.list.push_back(int32_t(i));
  }
  out.neighbours.resize(6 * out.list.size());
  for (size_t k = 0; k < out.list.size(); ++k) {
    const int i = out.list[k], x = i % vol.dim_x, yz = i / vol.dim_x;
    vd_active_neighbours_of(out.compact.data(), vol, x, yz % vol.dim_y, yz / vol.dim_y, &out.neighbours[6 * k]);
  }
  return out;
}

}  // namespace

ActiveSet BuildActiveSet(const uint16_t* codes, VdVolume vol, ActiveSet* solved) {
  const McTable& table = GetMcTable();
  const int n = vol.dim_x * vol.dim_y * vol.dim_z;
  std::vector<uint8_t> surface(n), member(n);
#pragma omp parallel for schedule(static)
  for (int i = 0; i < n; ++i) {
    const int x = i % vol.dim_x, yz = i / vol.dim_x;
    surface[i] = vd_active_surface_point(codes, table.counts.data(), vol, x, yz % vol.dim_y, yz / vol.dim_y);
  }
#pragma omp parallel for schedule(static)
  for (int i = 0; i < n; ++i) {
    const int x = i % vol.dim_x, yz = i / vol.dim_x;
    member[i] = vd_active_dilate_point(surface.data(), vol, x, yz % vol.dim_y, yz / vol.dim_y);
  }
  if (solved) *solved = CompactMembers(surface, vol);
  return CompactMembers(member, vol);
}

ActiveSet BuildLevel(VdLattice fine, const int32_t* nbr, const std::vector<int32_t>& fine_list, int s, VdLattice coarse,
                     size_t entries) {
  const int n = int(entries);
  std::vector<uint8_t> member(n, 0);
  for (int i : fine_list) {
    int slot, x, y, z;
    vd_lattice_point(fine, i, &slot, &x, &y, &z);
    for (int o = 0; o < 8; ++o) {
      const int e = vd_level_corner(coarse, nbr, s, slot, x, y, z, o);
      if (e >= 0) member[e] = 1;
    }
  }
  ActiveSet out;
  out.compact.assign(n, -1);
  for (int i = 0; i < n; ++i) {
    if (!member[i]) continue;
    out.compact[i] = int32_t(out.list.size());
    out.list.push_back(i);
  }
  out.neighbours.resize(6 * out.list.size());
  for (size_t k = 0; k < out.list.size(); ++k) {
    int slot, x, y, z;
    vd_lattice_point(coarse, out.list[k], &slot, &x, &y, &z);
    const int d[6][3] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};
    for (int j = 0; j < 6; ++j)
      out.neighbours[6 * k + j] =
          vd_lattice_compact(coarse, nbr, out.compact.data(), slot, x + d[j][0], y + d[j][1], z + d[j][2]);
  }
  return out;
}

void LevelRestrict(VdActive coarse, int m_c, int s, VdActive fine, const vd_float4* x_f, const vd_float4* rot_f,
                   vd_float4* x0_c, vd_float4* rot_c) {
#pragma omp parallel for schedule(static)
  for (int k = 0; k < m_c; ++k) x0_c[k] = vd_level_restrict(k, coarse, s, fine, x_f, rot_f, &rot_c[k]);
}

void LevelConstraints(const VdCorrespondence* cons_f, const int32_t* cell_f, int n, VdActive fine, const vd_float4* x_f,
                      int s, VdActive coarse, const vd_float4* x0_c, VdCorrespondence* cons_c) {
#pragma omp parallel for schedule(static)
  for (int c = 0; c < n; ++c) cons_c[c] = vd_level_constraint(cons_f[c], cell_f[c], fine, x_f, s, coarse, x0_c);
}

void LevelProlongate(VdActive fine, int m_f, int s, VdActive coarse, const vd_float4* x_c, const vd_float4* x0_c,
                     vd_float4* x_f) {
#pragma omp parallel for schedule(static)
  for (int k = 0; k < m_f; ++k) x_f[k] = x_f[k] + vd_level_prolongate(k, fine, s, coarse, x_c, x0_c);
}

void Rasterize(const vd_float4* positions, const vd_float4* normals, const int32_t* triangles, int num_triangles,
               VdPose world_to_cam, VdCamera cam, RasterMaps* out) {
  const int n = cam.width * cam.height;
  out->depth_id.assign(n, VD_RASTER_EMPTY64);
  out->ids.resize(n);
  out->vertex.resize(n);
  out->normal.resize(n);
  out->bary.resize(n);
  std::vector<VdRasterSetup> setups(std::max(num_triangles, 1));
#pragma omp parallel for schedule(dynamic, 256)
  for (int t = 0; t < num_triangles; ++t)
    vd_raster_triangle(positions, triangles, t, world_to_cam, cam, out->depth_id.data(), setups.data());
#pragma omp parallel for schedule(static)
  for (int i = 0; i < n; ++i) {
    out->ids[i] = vd_raster_id(out->depth_id[i]);
    vd_raster_resolve_pixel(positions, normals, triangles, setups.data(), world_to_cam, cam, i, out->ids[i],
                            &out->vertex[i], &out->normal[i], &out->bary[i]);
  }
}

void Correspondences(const RasterMaps& model, const vd_float4* obs_v, const vd_float4* obs_n,
                     const vd_float4* canonical_grid, const int32_t* triangles, VdCorrParams params, int n,
                     VdCorrespondence* out, const int32_t* owners) {
#pragma omp parallel for schedule(static)
  for (int i = 0; i < n; ++i)
    out[i] = vd_correspondence_pixel(i, model.vertex.data(), model.normal.data(), model.ids.data(), model.bary.data(),
                                     obs_v, obs_n, canonical_grid, triangles, owners, params);
}

void PhotometricCorrespondences(const RasterMaps& model, const vd_float4* obs_v, const uint32_t* colors,
                                const int32_t* triangles, const float* intensity, VdPhotoParams params,
                                VdCorrespondence* rows) {
  const int n = params.cam.width * params.cam.height, blocks = vd_photo_rows(params.cam.width, params.cam.height);
#pragma omp parallel for schedule(static)
  for (int b = 0; b < blocks; ++b) {
    const int i = vd_photo_pixel(b, params.cam.width);
    rows[n + b] = vd_photometric_pixel(i, rows[i], model.vertex.data(), obs_v, model.ids.data(), model.bary.data(),
                                       colors, triangles, intensity, params);
  }
}

void IcpReduce(const vd_float4* vmap, const vd_float4* nmap, const vd_float4* model_v, const vd_float4* model_n,
               int n, VdIcpParams params, double acc[VD_ICP_ACC]) {
  for (int k = 0; k < VD_ICP_ACC; ++k) acc[k] = 0.0;
  // Per-row float partials summed in double, the same shape of summation as the device.
  constexpr int kChunk = 64;
  const int chunks = (n + kChunk - 1) / kChunk;
  std::vector<float> partial(static_cast<size_t>(chunks) * VD_ICP_ACC, 0.f);
#pragma omp parallel for schedule(static)
  for (int g = 0; g < chunks; ++g) {
    float* a = &partial[static_cast<size_t>(g) * VD_ICP_ACC];
    for (int i = g * kChunk; i < std::min(n, (g + 1) * kChunk); ++i) vd_icp_pixel(vmap, nmap, model_v, model_n, i, params, a);
  }
  for (int g = 0; g < chunks; ++g)
    for (int k = 0; k < VD_ICP_ACC; ++k) acc[k] += partial[static_cast<size_t>(g) * VD_ICP_ACC + k];
}

}  // namespace vd::cpu

namespace vd::cpu {

void IntegrateTsdfBricks(float* tsdf, float* weight, uint32_t* color, VdVolume vol, VdCamera cam, VdPose world_to_cam,
                         const float* depth, const uint32_t* rgba, std::vector<uint32_t>* flags) {
  const int bricks = vd_bricks_x(vol) * vd_bricks_y(vol) * vd_bricks_z(vol);
  flags->assign(size_t(bricks), 0u);
  std::vector<vd_float4> tiles(size_t(vd_depth_tiles_x(cam)) * vd_depth_tiles_y(cam));
  for (size_t t = 0; t < tiles.size(); ++t) tiles[t] = vd_depth_tile(int(t), depth, cam);
  std::vector<uint32_t> masks(size_t(bricks), 0u);
  for (int b = 0; b < bricks; ++b) {
    masks[b] = vd_brick_octants(b, tiles.data(), cam, world_to_cam, vol);
    (*flags)[b] = masks[b] != 0u ? 1u : 0u;
  }
  std::vector<uint32_t> list;
  for (int b = 0; b < bricks; ++b)
    if ((*flags)[b]) list.push_back(uint32_t(b));
  const int items = int(list.size()) * VD_BRICK_ITEMS;
#pragma omp parallel for schedule(static)
  for (int i = 0; i < items; ++i)
    vd_tsdf_integrate_brick_row(i, list.data(), masks.data(), tsdf, weight, color, vol, cam, world_to_cam, depth, rgba);
}

}  // namespace vd::cpu
