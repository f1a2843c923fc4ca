// DeviceOps' launchers of kernels/raster.cl (class in ocl/device_ops.h).
#include "ocl/raster_ocl.h"

#include <algorithm>

#include "ocl/device_ops.h"

namespace vd {

Status DeviceOps::Rasterize(const DeviceMesh& mesh, VdPose world_to_cam, VdCamera cam, DeviceRaster* out) {
  const size_t n = static_cast<size_t>(cam.width) * cam.height;
  out->cam = cam;
  VD_RETURN_IF_ERROR(ctx_->Reserve(&out->depth_id, n));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&out->ids, n));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&out->vertex, n));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&out->normal, n));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&out->bary, n));
  VD_RETURN_IF_ERROR(ctx_->Fill(out->depth_id, uint64_t{VD_RASTER_EMPTY64}, n));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&raster_setups_, std::max<size_t>(mesh.num_triangles, 1)));
  VD_RETURN_IF_ERROR(ocl::kRasterPass(*ctx_, mesh.num_triangles, mesh.positions, mesh.triangles, world_to_cam, cam,
                                      out->depth_id, raster_setups_));
  return ocl::kRasterResolve(*ctx_, n, mesh.positions, mesh.normals, mesh.triangles, raster_setups_, world_to_cam, cam,
                             out->depth_id, out->ids, out->vertex, out->normal, out->bary);
}

}  // namespace vd
