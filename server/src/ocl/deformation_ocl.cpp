// DeviceOps' launchers of kernels/deformation.cl (class in ocl/device_ops.h).
#include "ocl/deformation_ocl.h"

#include <algorithm>

#include "ocl/brick_hash_ocl.h"
#include "ocl/device_ops.h"

namespace vd {

Status DeviceOps::ResetVolume(DeviceVolume& v) {
  const size_t n = v.num_voxels();
  VD_RETURN_IF_ERROR(ctx_->Fill(v.tsdf, 1.0f, n));
  VD_RETURN_IF_ERROR(ctx_->Fill(v.weight, 0.0f, n));
  VD_RETURN_IF_ERROR(ctx_->Fill(v.color, 0u, n));
  // Reserved here, not in AllocVolume: the engine reuses a grid of the same size with other dims.
  VD_RETURN_IF_ERROR(ctx_->Reserve(&v.touched, v.num_bricks()));
  VD_RETURN_IF_ERROR(ctx_->Fill(v.touched, uint8_t{0}, v.num_bricks()));
  if (!v.has_deformation()) return Status::Ok();
  return ocl::kDeformationReset(*ctx_, v.num_rows(), v.def_pos, v.def_rot, v.vol);
}

Status DeviceOps::DeformVertices(const DeviceVolume& v, DeviceMesh* mesh) {
  if (!v.has_deformation()) return FailedPrecondition("DeformVertices: the grid has no deformation field");
  return ocl::kDeformVertices(*ctx_, mesh->num_vertices, mesh->positions_grid, v.def_pos, v.vol, mesh->positions);
}

Status DeviceOps::TransformField(DeviceVolume& v, const VdPose& a, vd_float4 q_a) {
  if (!v.has_deformation()) return FailedPrecondition("TransformField needs a deformation field");
  return ocl::kFieldRigid(*ctx_, v.num_voxels(), v.def_pos, v.def_rot, a, q_a);
}

Status DeviceOps::TransformField(ocl::BrickPool& pool, const VdPose& a, vd_float4 q_a) {
  if (!pool.with_field) return FailedPrecondition("TransformField needs a brick pool with a deformation field");
  return ocl::kFieldRigid(*ctx_, size_t(pool.slots) * VD_BRICK_VOXELS, pool.def_pos, pool.def_rot, a, q_a);
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

Status DeviceOps::Follow(DeviceVolume& v, const DeviceActiveSet& active) {
  if (!v.has_deformation()) return FailedPrecondition("Follow needs a deformation field");
  if (active.count == 0) return Status::Ok();
  if (active_surface_.size() < v.num_voxels()) return FailedPrecondition("Follow needs a BuildActiveSet on this grid");
  return ocl::kFollow(*ctx_, active.count, active.list, SolvedFlags(), v.def_pos, v.def_rot, v.vol);
}

}  // namespace vd
