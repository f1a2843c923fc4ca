// DeviceOps' marching cubes over the brick pool (kernels/sparse_mesh.cl; class in ocl/device_ops.h).
#include "ocl/sparse_mesh_ocl.h"

#include <algorithm>

#include "ocl/active_set_ocl.h"
#include "ocl/brick_hash_ocl.h"
#include "ocl/deformation_ocl.h"
#include "ocl/device_ops.h"

namespace vd {

Status DeviceOps::MarchingCubes(ocl::BrickTable& table, const ocl::BrickPool& pool, DeviceMesh* mesh) {
  VD_ASSIGN_OR_RETURN(const ocl::BrickCounts counts, table.Counts(*ctx_));
  if (pool.slots < counts.used)
    return InvalidArgument("the brick pool holds " + std::to_string(pool.slots) + " bricks; the table has handed out " +
                           std::to_string(counts.used));
  const size_t used = counts.used, n = used * VD_BRICK_VOXELS, rows = used * VD_BRICK_ROWS;
  mesh->num_vertices = mesh->num_triangles = mesh->num_brick_slots = 0;
  if (used == 0) return Status::Ok();
  VD_RETURN_IF_ERROR(table.BuildNeighbours(*ctx_, counts.used));
  const ocl::Buffer<int32_t>& nbr = table.neighbours();
  VD_RETURN_IF_ERROR(ReserveMarchingCubes(n, rows, /*vertex_offsets=*/false));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mc_brick_weighted_, used));
  VD_RETURN_IF_ERROR(ocl::kSparseMcWeighted(*ctx_, used, pool.weight, nbr, mc_brick_weighted_));
  VD_RETURN_IF_ERROR(ocl::kSparseMcClassify(*ctx_, rows, pool.tsdf, pool.weight, nbr, mc_brick_weighted_,
                                            mc_tri_counts_, mc_codes_, mc_row_tris_));
  VD_RETURN_IF_ERROR(ocl::kSparseMcMasks(*ctx_, rows, pool.tsdf, mc_codes_, nbr, mc_brick_weighted_, mc_row_tris_,
                                         mc_masks_, mc_row_verts_));
  VD_ASSIGN_OR_RETURN(const bool any, SizeMesh(rows, mesh));
  if (!any) return Status::Ok();
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mesh->brick_slots, mesh->num_vertices));
  VD_RETURN_IF_ERROR(ocl::kSparseMcVertices(*ctx_, rows, pool.tsdf, pool.color, nbr, table.slot_keys(), mc_masks_,
                                            mc_row_verts_, mc_row_vert_offset_, mesh->positions_grid, mesh->normals,
                                            mesh->colors, mesh->brick_slots));
  mesh->num_brick_slots = mesh->num_vertices;
  return ocl::kSparseMcTriangles(*ctx_, rows, mc_codes_, mc_row_tris_, mc_row_tri_offset_, mc_tri_table_, mc_masks_,
                                 mc_row_vert_offset_, nbr, mesh->triangles);
}

Status DeviceOps::BuildActiveSet(const ocl::BrickTable& table, DeviceActiveSet* out, DeviceActiveSet* solved,
                                 const SolveView* view, const ocl::Buffer<vd_float4>* def_pos) {
  VD_ASSIGN_OR_RETURN(const ocl::BrickCounts counts, table.Counts(*ctx_));
  const size_t n = size_t(counts.used) * VD_BRICK_VOXELS, rows = size_t(counts.used) * VD_BRICK_ROWS;
  if (mc_codes_.size() < n || mc_row_tris_.size() < rows ||
      table.neighbours().size() < size_t(VD_BRICK_NEIGHBOURS) * counts.used)
    return FailedPrecondition("BuildActiveSet needs a MarchingCubes() run on these bricks");
  out->count = 0;
  out->kept = VdVolume{};
  solved_in_view_ = false;
  if (view && (!def_pos || def_pos->size() < n))
    return FailedPrecondition("a solve limited to the view needs the pool's field");
  if (solved) {
    solved->count = 0;
    solved->kept = VdVolume{};
  }
  if (counts.used == 0) return Status::Ok();
  const ocl::Buffer<int32_t>& nbr = table.neighbours();
  VD_RETURN_IF_ERROR(ctx_->Reserve(&active_surface_, n));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&active_member_, n));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&active_row_count_, rows));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&active_row_offset_, rows + 1));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&out->compact, n));
  VD_RETURN_IF_ERROR(ctx_->Fill(active_surface_, uint8_t(0), n));
  VD_RETURN_IF_ERROR(ctx_->Fill(active_member_, uint8_t(0), n));
  VD_RETURN_IF_ERROR(
      ocl::kSparseActiveSurface(*ctx_, rows, mc_codes_, mc_tri_counts_, mc_row_tris_, nbr, active_surface_));
  VD_RETURN_IF_ERROR(ocl::kSparseActiveDilate(*ctx_, rows, active_surface_, nbr, active_member_));
  VD_RETURN_IF_ERROR(ocl::kSparseActiveRows(*ctx_, rows, active_member_, active_row_count_));
  VD_RETURN_IF_ERROR(SizeActiveSet(rows, active_row_count_, out));
  VD_RETURN_IF_ERROR(
      ocl::kSparseActiveCompact(*ctx_, rows, active_member_, active_row_offset_, out->list, out->compact));
  VD_RETURN_IF_ERROR(ocl::kSparseActiveNeighbours(*ctx_, out->count, out->list, out->compact, nbr, out->neighbours));
  if (!solved) return Status::Ok();
  VD_RETURN_IF_ERROR(ctx_->Reserve(&active_row_surface_, rows));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&solved->compact, n));
  VD_RETURN_IF_ERROR(ocl::kSparseActiveRows(*ctx_, rows, active_surface_, active_row_surface_));
  if (view) {
    VD_RETURN_IF_ERROR(ctx_->Reserve(&active_in_view_, n));
    VD_RETURN_IF_ERROR(ctx_->Reserve(&active_row_in_view_, rows));
    VD_RETURN_IF_ERROR(ocl::kActiveInView(*ctx_, rows, active_surface_, active_row_surface_, *def_pos, VD_BRICK,
                                          view->cam, view->world_to_cam, view->margin, active_in_view_,
                                          active_row_in_view_));
    solved_in_view_ = true;
  }
  VD_RETURN_IF_ERROR(SizeActiveSet(rows, view ? active_row_in_view_ : active_row_surface_, solved));
  VD_RETURN_IF_ERROR(
      ocl::kSparseActiveCompact(*ctx_, rows, SolvedFlags(), active_row_offset_, solved->list, solved->compact));
  return ocl::kSparseActiveNeighbours(*ctx_, solved->count, solved->list, solved->compact, nbr, solved->neighbours);
}

Status DeviceOps::Follow(const ocl::BrickTable& table, ocl::BrickPool& pool, const DeviceActiveSet& active,
                         float voxel_size) {
  if (!pool.with_field) return FailedPrecondition("Follow needs a brick pool with a deformation field");
  if (active.count == 0) return Status::Ok();
  if (active_surface_.size() == 0) return FailedPrecondition("Follow needs a BuildActiveSet on these bricks");
  return ocl::kSparseFollow(*ctx_, active.count, active.list, SolvedFlags(), table.neighbours(), pool.def_pos,
                            pool.def_rot, voxel_size);
}

StatusOr<uint32_t> DeviceOps::AllocateActiveRing(ocl::BrickTable& table) {
  return table.AllocateRing(*ctx_, active_surface_);
}

Status DeviceOps::Extrapolate(const ocl::BrickTable& table, ocl::BrickPool& pool, const DeviceActiveSet& active,
                              float voxel_size) {
  if (!pool.with_field) return FailedPrecondition("Extrapolate needs a brick pool with a deformation field");
  if (active.count == 0) return Status::Ok();
  VD_RETURN_IF_ERROR(ctx_->Reserve(&extrapolated_pos_, active.count));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&extrapolated_rot_, active.count));
  VD_RETURN_IF_ERROR(ocl::kSparseExtrapolate(*ctx_, active.count, active.list, table.neighbours(), pool.def_pos,
                                             pool.def_rot, voxel_size, extrapolated_pos_, extrapolated_rot_));
  return ocl::kExtrapolateCommit(*ctx_, active.count, active.list, extrapolated_pos_, extrapolated_rot_, pool.def_pos,
                                 pool.def_rot);
}

Status DeviceOps::DeformVertices(const ocl::BrickTable& table, const ocl::BrickPool& pool, float voxel_size,
                                 DeviceMesh* mesh) {
  if (!pool.with_field) return FailedPrecondition("DeformVertices needs a brick pool with a deformation field");
  if (mesh->num_vertices == 0) return Status::Ok();
  if (mesh->num_brick_slots == mesh->num_vertices)
    return ocl::kSparseDeformMeshVertices(
        *ctx_, mesh->num_vertices, mesh->positions_grid, mesh->brick_slots, int32_t(table.pool()), table.slot_keys(),
        table.keys(), table.slots(), table.capacity(), table.neighbours(), pool.def_pos, voxel_size, mesh->positions);
  return ocl::kSparseDeformVertices(*ctx_, mesh->num_vertices, mesh->positions_grid, table.keys(), table.slots(),
                                    table.capacity(), table.neighbours(), pool.def_pos, voxel_size, mesh->positions);
}

}  // namespace vd
