#include "core/device_ops.h"

#include <algorithm>

#include "core/mc_table.h"
#include "ocl/active_set_ocl.h"
#include "ocl/correspondence_ocl.h"
#include "ocl/deformation_ocl.h"
#include "ocl/icp_ocl.h"
#include "ocl/marching_cubes_ocl.h"
#include "ocl/preprocess_ocl.h"
#include "ocl/raster_ocl.h"
#include "ocl/scan_ocl.h"
#include "ocl/tsdf_ocl.h"

namespace vd {
namespace {
// Elements per work item in the chunked scan and the ICP reduction.
constexpr uint32_t kScanChunk = 256;
constexpr int kIcpChunk = 64;
}  // namespace

Status DeviceOps::Init() {
  const McTable& t = GetMcTable();
  VD_ASSIGN_OR_RETURN(mc_tri_table_, ctx_->Alloc<int8_t>(t.triangles.size()));
  VD_ASSIGN_OR_RETURN(mc_tri_counts_, ctx_->Alloc<uint8_t>(t.counts.size()));
  VD_RETURN_IF_ERROR(ctx_->Upload(mc_tri_table_, t.triangles.data(), t.triangles.size()));
  VD_RETURN_IF_ERROR(ctx_->Upload(mc_tri_counts_, t.counts.data(), t.counts.size()));
  return Status::Ok();
}

Status DeviceOps::DepthConvert(const ocl::Buffer<uint16_t>& raw, ocl::Buffer<float>& depth, int n, float inv_scale,
                               float min_depth, float max_depth) {
  return ocl::kDepthConvert(*ctx_, n, raw, depth, inv_scale, min_depth, max_depth);
}

Status DeviceOps::Bilateral(const ocl::Buffer<float>& in, ocl::Buffer<float>& out, int width, int height, int radius,
                            float sigma_space_px, float sigma_depth_m) {
  const float is = 0.5f / (sigma_space_px * sigma_space_px);
  const float id = 0.5f / (sigma_depth_m * sigma_depth_m);
  return ocl::kBilateral(*ctx_, static_cast<size_t>(width) * height, in, out, width, height, radius, is, id);
}

Status DeviceOps::PyrDown(const ocl::Buffer<float>& in, ocl::Buffer<float>& out, int width, int height,
                          float max_diff) {
  const int ow = width / 2;
  return ocl::kPyrDown(*ctx_, static_cast<size_t>(ow) * (height / 2), in, out, width, ow, max_diff);
}

Status DeviceOps::VertexMap(const ocl::Buffer<float>& depth, ocl::Buffer<vd_float4>& vmap, VdCamera cam) {
  return ocl::kVertexMap(*ctx_, static_cast<size_t>(cam.width) * cam.height, depth, vmap, cam);
}

Status DeviceOps::NormalMap(const ocl::Buffer<vd_float4>& vmap, ocl::Buffer<vd_float4>& nmap, int width, int height,
                            float max_jump) {
  return ocl::kNormalMap(*ctx_, static_cast<size_t>(width) * height, vmap, nmap, width, height, max_jump);
}

Status DeviceOps::AllocVolume(const VdVolume& vol, bool with_deformation, DeviceVolume* out) {
  out->vol = vol;
  const size_t n = out->num_voxels();
  VD_ASSIGN_OR_RETURN(out->tsdf, ctx_->Alloc<float>(n));
  VD_ASSIGN_OR_RETURN(out->weight, ctx_->Alloc<float>(n));
  VD_ASSIGN_OR_RETURN(out->color, ctx_->Alloc<uint32_t>(n));
  if (with_deformation) {
    VD_ASSIGN_OR_RETURN(out->def_pos, ctx_->Alloc<vd_float4>(n));
    VD_ASSIGN_OR_RETURN(out->def_rot, ctx_->Alloc<vd_float4>(n));
  } else {
    out->def_pos = ocl::Buffer<vd_float4>();
    out->def_rot = ocl::Buffer<vd_float4>();
  }
  return ResetVolume(*out);
}

Status DeviceOps::ResetVolume(DeviceVolume& v) {
  const size_t n = v.num_voxels();
  VD_RETURN_IF_ERROR(ctx_->Fill(v.tsdf, 1.0f, n));
  VD_RETURN_IF_ERROR(ctx_->Fill(v.weight, 0.0f, n));
  VD_RETURN_IF_ERROR(ctx_->Fill(v.color, 0u, n));
  if (!v.has_deformation()) return Status::Ok();
  return ocl::kDeformationReset(*ctx_, v.num_rows(), v.def_pos, v.def_rot, v.vol);
}

Status DeviceOps::IntegrateTsdf(DeviceVolume& v, VdCamera cam, VdPose world_to_cam, const ocl::Buffer<float>& depth,
                                const ocl::Buffer<uint32_t>& rgba) {
  const size_t bricks = size_t(vd_bricks_x(v.vol)) * vd_bricks_y(v.vol) * vd_bricks_z(v.vol);
  VD_RETURN_IF_ERROR(ctx_->Reserve(&brick_flags_, bricks));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&brick_masks_, bricks));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&brick_offsets_, bricks + 1));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&brick_list_, bricks));
  const size_t tiles = size_t(vd_depth_tiles_x(cam)) * vd_depth_tiles_y(cam);
  VD_RETURN_IF_ERROR(ctx_->Reserve(&depth_tiles_, tiles));
  VD_RETURN_IF_ERROR(ocl::kDepthTiles(*ctx_, tiles, depth, cam, depth_tiles_));
  VD_RETURN_IF_ERROR(
      ocl::kBrickMark(*ctx_, bricks, depth_tiles_, cam, world_to_cam, v.vol, brick_flags_, brick_masks_));
  uint32_t total = 0;
  VD_RETURN_IF_ERROR(ScanExclusive(brick_flags_, bricks, brick_offsets_, &total));
  VD_RETURN_IF_ERROR(ocl::kBrickCompact(*ctx_, bricks, brick_flags_, brick_offsets_, brick_list_));
  brick_count_ = total;
  return ocl::kTsdfIntegrateBricks(*ctx_, size_t(total) * VD_BRICK_ITEMS, brick_list_, brick_masks_, v.tsdf, v.weight,
                                   v.color, v.vol, cam, world_to_cam, depth, rgba);
}

Status DeviceOps::IntegrateTsdfDense(DeviceVolume& v, VdCamera cam, VdPose world_to_cam,
                                     const ocl::Buffer<float>& depth, const ocl::Buffer<uint32_t>& rgba) {
  return ocl::kTsdfIntegrate(*ctx_, v.num_rows(), v.tsdf, v.weight, v.color, v.vol, cam, world_to_cam, depth, rgba);
}

Status DeviceOps::ScanExclusive(const ocl::Buffer<uint32_t>& in, size_t n, ocl::Buffer<uint32_t>& out,
                                uint32_t* total) {
  if (out.size() < n + 1) return OutOfRange("scan output needs n + 1 entries");
  // Level l scans the chunk sums of level l - 1; recursion as a loop over cached scratch.
  std::vector<size_t> sizes{n};
  while (sizes.back() > kScanChunk) sizes.push_back((sizes.back() + kScanChunk - 1) / kScanChunk);
  const size_t levels = sizes.size() - 1;
  if (scan_sums_.size() < levels) {
    scan_sums_.resize(levels);
    scan_offsets_.resize(levels);
  }
  for (size_t l = 0; l < levels; ++l) {
    VD_RETURN_IF_ERROR(ctx_->Reserve(&scan_sums_[l], sizes[l + 1]));
    VD_RETURN_IF_ERROR(ctx_->Reserve(&scan_offsets_[l], sizes[l + 1] + 1));
  }
  // Down: chunk sums of every level.
  for (size_t l = 0; l < levels; ++l) {
    const ocl::Buffer<uint32_t>& src = l == 0 ? in : scan_sums_[l - 1];
    VD_RETURN_IF_ERROR(
        ocl::kScanSums(*ctx_, sizes[l + 1], src, static_cast<uint32_t>(sizes[l]), kScanChunk, scan_sums_[l]));
  }
  // Up: the top level fits in one chunk; each level below adds its chunk offsets.
  for (size_t l = levels + 1; l-- > 0;) {
    const ocl::Buffer<uint32_t>& src = l == 0 ? in : scan_sums_[l - 1];
    ocl::Buffer<uint32_t>& dst = l == 0 ? out : scan_offsets_[l - 1];
    const bool top = l == levels;
    const ocl::Buffer<uint32_t>& offsets = top ? dst : scan_offsets_[l];
    const size_t items = top ? 1 : sizes[l + 1];
    VD_RETURN_IF_ERROR(ocl::kScanApply(*ctx_, items, src, static_cast<uint32_t>(sizes[l]), kScanChunk, offsets,
                                       static_cast<uint32_t>(top ? 0 : 1), dst));
  }
  if (total) VD_RETURN_IF_ERROR(ctx_->Download(out, total, 1, n));
  return Status::Ok();
}

Status DeviceOps::MarchingCubes(const DeviceVolume& v, DeviceMesh* mesh) {
  const size_t n = v.num_voxels(), rows = v.num_rows();
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mc_codes_, n));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mc_masks_, n));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mc_vert_offset_, n));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mc_row_tris_, rows));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mc_row_verts_, rows));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mc_row_tri_offset_, rows + 1));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mc_row_vert_offset_, rows + 1));
  VD_RETURN_IF_ERROR(ocl::kMcClassify(*ctx_, rows, v.tsdf, v.weight, v.vol, mc_tri_counts_, mc_codes_, mc_row_tris_));
  VD_RETURN_IF_ERROR(ocl::kMcMasks(*ctx_, rows, v.tsdf, mc_codes_, mc_row_tris_, v.vol, mc_masks_, mc_row_verts_));
  uint32_t nt = 0, nv = 0;
  VD_RETURN_IF_ERROR(ScanExclusive(mc_row_tris_, rows, mc_row_tri_offset_, &nt));
  VD_RETURN_IF_ERROR(ScanExclusive(mc_row_verts_, rows, mc_row_vert_offset_, &nv));
  mesh->num_vertices = nv;
  mesh->num_triangles = nt;
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mesh->positions_grid, nv));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mesh->positions, nv));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mesh->normals, nv));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mesh->colors, nv));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mesh->triangles, 3 * static_cast<size_t>(nt)));
  if (nv == 0 || nt == 0) return Status::Ok();
  VD_RETURN_IF_ERROR(ocl::kMcVertices(*ctx_, rows, v.tsdf, v.color, v.vol, mc_masks_, mc_row_verts_,
                                      mc_row_vert_offset_, mc_vert_offset_, mesh->positions_grid, mesh->normals,
                                      mesh->colors));
  return ocl::kMcTriangles(*ctx_, rows, mc_codes_, mc_row_tris_, mc_row_tri_offset_, mc_tri_table_, mc_masks_,
                           mc_vert_offset_, v.vol, mesh->triangles);
}

Status DeviceOps::GridToWorld(const VdVolume& vol, DeviceMesh* mesh) {
  return ocl::kGridToWorld(*ctx_, mesh->num_vertices, mesh->positions_grid, vol, mesh->positions);
}

Status DeviceOps::Correspondences(const DeviceRaster& model, const ocl::Buffer<vd_float4>& obs_v,
                                  const ocl::Buffer<vd_float4>& obs_n, const DeviceMesh& mesh,
                                  const VdCorrParams& params, ocl::Buffer<VdCorrespondence>& out) {
  const size_t n = static_cast<size_t>(model.cam.width) * model.cam.height;
  if (out.size() < n) return OutOfRange("correspondence buffer smaller than the image");
  return ocl::kCorrespondences(*ctx_, n, model.vertex, model.normal, model.ids, model.bary, obs_v, obs_n,
                               mesh.positions_grid, mesh.triangles, params, out);
}

Status DeviceOps::Extrapolate(DeviceVolume& v, const DeviceActiveSet& active) {
  if (!v.has_deformation()) return FailedPrecondition("Extrapolate needs a deformation field");
  VD_RETURN_IF_ERROR(ctx_->Reserve(&extrapolated_pos_, std::max<size_t>(active.count, 1)));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&extrapolated_rot_, std::max<size_t>(active.count, 1)));
  VD_RETURN_IF_ERROR(ocl::kExtrapolate(*ctx_, active.count, active.list, v.def_pos, v.def_rot, v.vol, extrapolated_pos_,
                                       extrapolated_rot_));
  return ocl::kExtrapolateCommit(*ctx_, active.count, active.list, extrapolated_pos_, extrapolated_rot_, v.def_pos,
                                 v.def_rot);
}

Status DeviceOps::IntegrateActive(DeviceVolume& v, const DeviceActiveSet& active, float k_min, VdCamera cam,
                                  VdPose world_to_cam, const ocl::Buffer<float>& depth,
                                  const ocl::Buffer<uint32_t>& rgba) {
  if (!v.has_deformation()) return FailedPrecondition("IntegrateActive needs a deformation field");
  return ocl::kTsdfIntegrateActive(*ctx_, active.count, v.tsdf, v.weight, v.color, active.list, v.def_pos, k_min, v.vol,
                                   cam, world_to_cam, depth, rgba);
}

Status DeviceOps::BuildActiveSet(const DeviceVolume& v, DeviceActiveSet* out) {
  const size_t n = v.num_voxels(), rows = v.num_rows();
  if (mc_codes_.size() < n) return FailedPrecondition("BuildActiveSet needs a MarchingCubes() run on this grid");
  VD_RETURN_IF_ERROR(ctx_->Reserve(&active_surface_, n));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&active_member_, n));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&active_row_count_, rows));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&active_row_offset_, rows + 1));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&out->compact, n));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&active_row_surface_, rows));
  VD_RETURN_IF_ERROR(ocl::kActiveSurface(*ctx_, rows, mc_codes_, mc_tri_counts_, mc_row_tris_, v.vol, active_surface_,
                                         active_row_surface_));
  VD_RETURN_IF_ERROR(
      ocl::kActiveDilate(*ctx_, rows, active_surface_, active_row_surface_, v.vol, active_member_, active_row_count_));
  uint32_t total = 0;
  VD_RETURN_IF_ERROR(ScanExclusive(active_row_count_, rows, active_row_offset_, &total));
  out->count = total;
  VD_RETURN_IF_ERROR(ctx_->Reserve(&out->list, std::max<size_t>(total, 1)));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&out->neighbours, 6 * std::max<size_t>(total, 1)));
  VD_RETURN_IF_ERROR(
      ocl::kActiveCompact(*ctx_, rows, active_member_, active_row_offset_, v.vol, out->list, out->compact));
  return ocl::kActiveNeighbours(*ctx_, total, out->list, out->compact, v.vol, out->neighbours);
}

Status DeviceOps::DeformVertices(const DeviceVolume& v, DeviceMesh* mesh) {
  if (!v.has_deformation()) return FailedPrecondition("DeformVertices: the grid has no deformation field");
  return ocl::kDeformVertices(*ctx_, mesh->num_vertices, mesh->positions_grid, v.def_pos, v.vol, mesh->positions);
}

Status DeviceOps::Rasterize(const DeviceMesh& mesh, VdPose world_to_cam, VdCamera cam, DeviceRaster* out) {
  const size_t n = static_cast<size_t>(cam.width) * cam.height;
  out->cam = cam;
  VD_RETURN_IF_ERROR(ctx_->Reserve(&out->depth_bits, n));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&out->ids, n));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&out->vertex, n));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&out->normal, n));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&out->bary, n));
  VD_RETURN_IF_ERROR(ctx_->Fill(out->depth_bits, VD_RASTER_EMPTY, n));
  VD_RETURN_IF_ERROR(ctx_->Fill(out->ids, VD_RASTER_EMPTY, n));
  VD_RETURN_IF_ERROR(ocl::kRasterDepthPass(*ctx_, mesh.num_triangles, mesh.positions, mesh.triangles, world_to_cam, cam,
                                           out->depth_bits));
  VD_RETURN_IF_ERROR(ocl::kRasterIdPass(*ctx_, mesh.num_triangles, mesh.positions, mesh.triangles, world_to_cam, cam,
                                        out->depth_bits, out->ids));
  return ocl::kRasterResolve(*ctx_, n, mesh.positions, mesh.normals, mesh.triangles, world_to_cam, cam, out->ids,
                             out->vertex, out->normal, out->bary);
}

Status DeviceOps::IcpReduce(const ocl::Buffer<vd_float4>& vmap, const ocl::Buffer<vd_float4>& nmap,
                            const ocl::Buffer<vd_float4>& model_v, const ocl::Buffer<vd_float4>& model_n, int n,
                            const VdIcpParams& params, double acc[VD_ICP_ACC]) {
  const size_t groups = (static_cast<size_t>(n) + kIcpChunk - 1) / kIcpChunk;
  VD_RETURN_IF_ERROR(ctx_->Reserve(&icp_partials_, groups * VD_ICP_ACC));
  VD_RETURN_IF_ERROR(ocl::kIcpReduce(*ctx_, groups, vmap, nmap, model_v, model_n, n, kIcpChunk, params, icp_partials_));
  icp_host_.resize(groups * VD_ICP_ACC);
  VD_RETURN_IF_ERROR(ctx_->Download(icp_partials_, icp_host_.data(), icp_host_.size()));
  for (int k = 0; k < VD_ICP_ACC; ++k) acc[k] = 0.0;
  for (size_t g = 0; g < groups; ++g)
    for (int k = 0; k < VD_ICP_ACC; ++k) acc[k] += icp_host_[g * VD_ICP_ACC + k];
  return Status::Ok();
}

}  // namespace vd
