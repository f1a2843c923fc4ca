// DeviceOps' launchers of kernels/correspondence.cl (class in ocl/device_ops.h).
#include "ocl/correspondence_ocl.h"

#include "ocl/device_ops.h"

namespace vd {

Status DeviceOps::Correspondences(const DeviceRaster& model, const ocl::Buffer<vd_float4>& obs_v,
                                  const ocl::Buffer<vd_float4>& obs_n, const DeviceMesh& mesh,
                                  const VdCorrParams& params, ocl::Buffer<VdCorrespondence>& out) {
  const size_t n = static_cast<size_t>(model.cam.width) * model.cam.height;
  if (out.size() < n) return OutOfRange("correspondence buffer smaller than the image");
  return ocl::kCorrespondences(*ctx_, n, model.vertex, model.normal, model.ids, model.bary, obs_v, obs_n,
                               mesh.positions_grid, mesh.triangles, params, out);
}

}  // namespace vd
