// DeviceOps' launchers of kernels/marching_cubes.cl (class in ocl/device_ops.h).
#include "ocl/marching_cubes_ocl.h"

#include "ocl/device_ops.h"

namespace vd {

Status DeviceOps::ReserveMarchingCubes(size_t points, size_t rows, bool vertex_offsets) {
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mc_codes_, points));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mc_masks_, points));
  if (vertex_offsets) VD_RETURN_IF_ERROR(ctx_->Reserve(&mc_vert_offset_, points));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mc_row_tris_, rows));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mc_row_verts_, rows));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mc_row_tri_offset_, rows + 1));
  return ctx_->Reserve(&mc_row_vert_offset_, rows + 1);
}

StatusOr<bool> DeviceOps::SizeMesh(size_t rows, DeviceMesh* mesh) {
  uint32_t nt = 0, nv = 0;
  VD_RETURN_IF_ERROR(ScanExclusive(mc_row_tris_, rows, mc_row_tri_offset_, &nt));
  VD_RETURN_IF_ERROR(ScanExclusive(mc_row_verts_, rows, mc_row_vert_offset_, &nv));
  mesh->num_vertices = nv;
  mesh->num_triangles = nt;
  mesh->num_brick_slots = 0;
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mesh->positions_grid, nv));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mesh->positions, nv));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mesh->normals, nv));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mesh->colors, nv));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mesh->triangles, 3 * static_cast<size_t>(nt)));
  return nv > 0 && nt > 0;
}

Status DeviceOps::MarchingCubes(const DeviceVolume& v, DeviceMesh* mesh) {
  const size_t n = v.num_voxels(), rows = v.num_rows();
  VD_RETURN_IF_ERROR(ReserveMarchingCubes(n, rows, /*vertex_offsets=*/true));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mc_chunk_tris_, rows * vd_mc_chunks_x(v.vol)));
  VD_RETURN_IF_ERROR(ocl::kMcClassify(*ctx_, rows, v.tsdf, v.weight, v.touched, v.vol, mc_tri_counts_, mc_codes_,
                                      mc_row_tris_, mc_chunk_tris_));
  VD_RETURN_IF_ERROR(
      ocl::kMcMasks(*ctx_, rows, v.tsdf, mc_codes_, mc_row_tris_, mc_chunk_tris_, v.vol, mc_masks_, mc_row_verts_));
  VD_ASSIGN_OR_RETURN(const bool any, SizeMesh(rows, mesh));
  if (!any) return Status::Ok();
  VD_RETURN_IF_ERROR(ocl::kMcVertices(*ctx_, rows, v.tsdf, v.color, v.vol, mc_masks_, mc_row_verts_,
                                      mc_row_vert_offset_, mc_vert_offset_, mesh->positions_grid, mesh->normals,
                                      mesh->colors));
  return ocl::kMcTriangles(*ctx_, rows, mc_codes_, mc_row_tris_, mc_row_tri_offset_, mc_tri_table_, mc_masks_,
                           mc_vert_offset_, v.vol, mesh->triangles);
}

Status DeviceOps::GridToWorld(const VdVolume& vol, DeviceMesh* mesh) {
  return ocl::kGridToWorld(*ctx_, mesh->num_vertices, mesh->positions_grid, vol, mesh->positions);
}

}  // namespace vd
