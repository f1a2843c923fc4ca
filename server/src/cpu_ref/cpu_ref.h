#pragma once
// CPU references of every kernel: the same shared per-item functions looped on the host (with
// OpenMP). They are the test oracle for the OpenCL kernels and the native baseline of the
// benchmarks. Kernels built on prefix sums (marching cubes) get an independent reference.
#include <cstdint>
#include <vector>

#include "shared/correspondence.h"
#include "shared/icp.h"
#include "shared/solver.h"
#include "shared/tsdf.h"
#include "shared/vd_types.h"

namespace vd::cpu {

void DepthConvert(const uint16_t* raw, float* depth, int n, float inv_scale, float min_depth, float max_depth);
void Bilateral(const float* in, float* out, int width, int height, int radius, float sigma_space_px,
               float sigma_depth_m);
// out is (width / 2) x (height / 2).
void PyrDown(const float* in, float* out, int width, int height, float max_diff);
void VertexMap(const float* depth, vd_float4* vmap, VdCamera cam);
void NormalMap(const vd_float4* vmap, vd_float4* nmap, int width, int height, float max_jump);
// The dense colour term's intensity image, (width / 2) x (height / 2): smoothed luma of packed
// colour at half resolution (shared/preprocess.h).
void Intensity(const uint32_t* rgba, float* out, int width, int height);

void IntegrateTsdf(float* tsdf, float* weight, uint32_t* color, VdVolume vol, VdCamera cam, VdPose world_to_cam,
                   const float* depth, const uint32_t* rgba);

// Brick integration (shared/tsdf.h): marks the bricks the depth's truncation band may touch into
// flags (one per brick, 0/1) from 8x8 depth tiles, then integrates the marked bricks.
void IntegrateTsdfBricks(float* tsdf, float* weight, uint32_t* color, VdVolume vol, VdCamera cam, VdPose world_to_cam,
                         const float* depth, const uint32_t* rgba, std::vector<uint32_t>* flags);

// Non-rigid fusion (vd_tsdf_integrate_active) of the n listed grid points at their deformed
// positions, behind the k_min / k_min_new gates of shared/tsdf.h, with its carving.
void IntegrateActive(float* tsdf, float* weight, uint32_t* color, const int* list, int n, const vd_float4* def_pos,
                     VdFusionParams fp, VdVolume vol, VdCamera cam, VdPose world_to_cam, const float* depth,
                     const uint32_t* rgba);

// vd_volume_touched: per 8^3 brick (shared/tsdf.h vd_grid_brick), 1 when a point of it holds weight.
std::vector<uint8_t> VolumeTouched(const float* weight, VdVolume vol);

void DeformationReset(vd_float4* def_pos, vd_float4* def_rot, VdVolume vol);
// vd_field_rigid over n grid points.
void TransformField(vd_float4* def_pos, vd_float4* def_rot, int n, VdPose a, vd_float4 q_a);
void DeformVertices(const vd_float4* grid_pos, int n, const vd_float4* def_pos, VdVolume vol, vd_float4* out);
// vd_extrapolate + vd_extrapolate_commit: the n listed grid points never optimised start from their
// optimised neighbours (all computed from the field as given, then written).
void Extrapolate(const int* list, int n, vd_float4* def_pos, vd_float4* def_rot, VdVolume vol);
// The ring points of M (list, surface 0) follow their solved neighbours (vd_follow_point).
void Follow(const int* list, int n, const uint8_t* surface, vd_float4* def_pos, vd_float4* def_rot, VdVolume vol);
// The surface points (one flag per point, rows of row_len points) whose field position def_pos is
// in the view (kernel vd_active_in_view, shared/active_set.h vd_point_in_view): the solver's points
// of a solve limited to the view.
std::vector<uint8_t> ActiveInView(const std::vector<uint8_t>& surface, const vd_float4* def_pos, int row_len,
                                  VdCamera cam, VdPose world_to_cam, float margin);

struct McMesh {
  // Vertex positions in grid units (x + t, y, z): cell and trilinear weights are implicit.
  std::vector<vd_float4> positions_grid;
  std::vector<vd_float4> normals;
  std::vector<uint32_t> colors;
  std::vector<int32_t> triangles;
  // Cell codes (bit 8 valid, bits 0..7 cube index) per grid point, for the active set.
  std::vector<uint16_t> codes;
};
McMesh MarchingCubes(const float* tsdf, const float* weight, const uint32_t* color, VdVolume vol);

struct ActiveSet {
  std::vector<int32_t> list;
  std::vector<int32_t> compact;
  std::vector<int32_t> neighbours;
};
// Independent of the device's scan: a sequential compaction over the same per-point tests.
// solved: also the set of the surface points alone (the solver's unknowns).
ActiveSet BuildActiveSet(const uint16_t* codes, VdVolume vol, ActiveSet* solved = nullptr);

// A coarse level of the solver's hierarchy (shared/hierarchy.h) at spacing s, from the fine
// active list on lattice `fine` (nbr: the bricks' neighbour slots, null on a dense grid):
// sequential marking and compaction over the coarse lattice's `entries` entries, independent of
// the device's scan.
ActiveSet BuildLevel(VdLattice fine, const int32_t* nbr, const std::vector<int32_t>& fine_list, int s, VdLattice coarse,
                     size_t entries);
void LevelRestrict(VdActive coarse, int m_c, int s, VdActive fine, const vd_float4* x_f, const vd_float4* rot_f,
                   vd_float4* x0_c, vd_float4* rot_c);
// The n sorted fine constraints (cell_f: their cells) re-expressed on the coarse level.
void LevelConstraints(const VdCorrespondence* cons_f, const int32_t* cell_f, int n, VdActive fine, const vd_float4* x_f,
                      int s, VdActive coarse, const vd_float4* x0_c, VdCorrespondence* cons_c);
// Adds the prolongated coarse increment to every one of the m_f fine active points.
void LevelProlongate(VdActive fine, int m_f, int s, VdActive coarse, const vd_float4* x_c, const vd_float4* x0_c,
                     vd_float4* x_f);

struct RasterMaps {
  std::vector<uint64_t> depth_id;
  std::vector<uint32_t> ids;
  std::vector<vd_float4> vertex;
  std::vector<vd_float4> normal;
  std::vector<vd_float4> bary;
};
void Rasterize(const vd_float4* positions, const vd_float4* normals, const int32_t* triangles, int num_triangles,
               VdPose world_to_cam, VdCamera cam, RasterMaps* out);

// owners: each vertex's owning brick slot (a mesh over the bricks), carried as each constraint's
// hint; null for none.
void Correspondences(const RasterMaps& model, const vd_float4* obs_v, const vd_float4* obs_n,
                     const vd_float4* canonical_grid, const int32_t* triangles, VdCorrParams params, int n,
                     VdCorrespondence* out, const int32_t* owners = nullptr);

// The dense colour term's rows (shared/correspondence.h vd_photometric_pixel): rows[n + b] for each
// 2x2 block b of the n = width x height pixels, from its first pixel's depth row (vd_photo_pixel);
// colors per vertex of `triangles`.
void PhotometricCorrespondences(const RasterMaps& model, const vd_float4* obs_v, const uint32_t* colors,
                                const int32_t* triangles, const float* intensity, VdPhotoParams params,
                                VdCorrespondence* rows);

// Sums the ICP normal equations over all pixels in double precision.
void IcpReduce(const vd_float4* vmap, const vd_float4* nmap, const vd_float4* model_v, const vd_float4* model_n,
               int n, VdIcpParams params, double acc[VD_ICP_ACC]);

}  // namespace vd::cpu
