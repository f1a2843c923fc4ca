// DeviceOps' launchers of kernels/tsdf.cl (class in ocl/device_ops.h).
#include "ocl/tsdf_ocl.h"

#include "ocl/brick_hash_ocl.h"
#include "ocl/device_ops.h"

namespace vd {

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
      ocl::kBrickMark(*ctx_, bricks, depth_tiles_, cam, world_to_cam, v.vol, brick_flags_, brick_masks_, v.touched));
  uint32_t total = 0;
  VD_RETURN_IF_ERROR(ScanExclusive(brick_flags_, bricks, brick_offsets_, &total));
  VD_RETURN_IF_ERROR(ocl::kDenseBrickCompact(*ctx_, bricks, brick_flags_, brick_offsets_, brick_list_));
  brick_count_ = total;
  return ocl::kTsdfIntegrateBricks(*ctx_, size_t(total) * VD_BRICK_ITEMS, brick_list_, brick_masks_, v.tsdf, v.weight,
                                   v.color, v.vol, cam, world_to_cam, depth, rgba);
}

Status DeviceOps::IntegrateTsdfDense(DeviceVolume& v, VdCamera cam, VdPose world_to_cam,
                                     const ocl::Buffer<float>& depth, const ocl::Buffer<uint32_t>& rgba) {
  VD_RETURN_IF_ERROR(
      ocl::kTsdfIntegrate(*ctx_, v.num_rows(), v.tsdf, v.weight, v.color, v.vol, cam, world_to_cam, depth, rgba));
  return MarkTouched(v);
}

Status DeviceOps::MarkTouched(DeviceVolume& v) {
  VD_RETURN_IF_ERROR(ctx_->Reserve(&v.touched, v.num_bricks()));
  return ocl::kVolumeTouched(*ctx_, v.num_bricks(), v.weight, v.vol, v.touched);
}

Status DeviceOps::IntegrateActive(DeviceVolume& v, const DeviceActiveSet& active, const VdFusionParams& fp,
                                  VdCamera cam, VdPose world_to_cam, const ocl::Buffer<float>& depth,
                                  const ocl::Buffer<uint32_t>& rgba) {
  if (!v.has_deformation()) return FailedPrecondition("IntegrateActive needs a deformation field");
  return ocl::kTsdfIntegrateActive(*ctx_, active.count, v.tsdf, v.weight, v.color, v.touched, 1, active.list, v.def_pos,
                                   fp, v.vol, cam, world_to_cam, depth, rgba);
}

Status DeviceOps::IntegrateActive(ocl::BrickPool& pool, const DeviceActiveSet& active, const VdFusionParams& fp,
                                  VdVolume vol, VdCamera cam, VdPose world_to_cam, const ocl::Buffer<float>& depth,
                                  const ocl::Buffer<uint32_t>& rgba) {
  if (!pool.with_field) return FailedPrecondition("IntegrateActive needs a brick pool with a deformation field");
  return ocl::kTsdfIntegrateActive(*ctx_, active.count, pool.tsdf, pool.weight, pool.color, no_touched_, 0, active.list,
                                   pool.def_pos, fp, vol, cam, world_to_cam, depth, rgba);
}

}  // namespace vd
