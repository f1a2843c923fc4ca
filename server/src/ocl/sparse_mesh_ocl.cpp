// DeviceOps' marching cubes over the brick pool (kernels/sparse_mesh.cl; class in ocl/device_ops.h).
#include "ocl/sparse_mesh_ocl.h"

#include "ocl/brick_hash_ocl.h"
#include "ocl/device_ops.h"

namespace vd {

Status DeviceOps::MarchingCubes(ocl::BrickTable& table, const ocl::BrickPool& pool, DeviceMesh* mesh) {
  VD_ASSIGN_OR_RETURN(const ocl::BrickCounts counts, table.Counts(*ctx_));
  if (pool.slots < counts.used)
    return InvalidArgument("the brick pool holds " + std::to_string(pool.slots) + " bricks; the table has handed out " +
                           std::to_string(counts.used));
  const size_t used = counts.used, n = used * VD_BRICK_VOXELS, rows = used * VD_BRICK_ROWS;
  mesh->num_vertices = mesh->num_triangles = 0;
  if (used == 0) return Status::Ok();
  VD_RETURN_IF_ERROR(table.BuildNeighbours(*ctx_, counts.used));
  const ocl::Buffer<int32_t>& nbr = table.neighbours();
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mc_codes_, n));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mc_masks_, n));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mc_vert_offset_, n));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mc_row_tris_, rows));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mc_row_verts_, rows));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mc_row_tri_offset_, rows + 1));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&mc_row_vert_offset_, rows + 1));
  VD_RETURN_IF_ERROR(
      ocl::kSparseMcClassify(*ctx_, rows, pool.tsdf, pool.weight, nbr, mc_tri_counts_, mc_codes_, mc_row_tris_));
  VD_RETURN_IF_ERROR(ocl::kSparseMcMasks(*ctx_, rows, pool.tsdf, mc_codes_, nbr, mc_masks_, mc_row_verts_));
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
  VD_RETURN_IF_ERROR(ocl::kSparseMcVertices(*ctx_, rows, pool.tsdf, pool.color, nbr, table.slot_keys(), mc_masks_,
                                            mc_row_verts_, mc_row_vert_offset_, mc_vert_offset_, mesh->positions_grid,
                                            mesh->normals, mesh->colors));
  return ocl::kSparseMcTriangles(*ctx_, rows, mc_codes_, mc_row_tris_, mc_row_tri_offset_, mc_tri_table_, mc_masks_,
                                 mc_vert_offset_, nbr, mesh->triangles);
}

}  // namespace vd
