// DeviceOps' launchers of kernels/correspondence.cl (class in ocl/device_ops.h).
#include "ocl/correspondence_ocl.h"

#include "ocl/device_ops.h"

namespace vd {
namespace {
// What a mesh that names no owning bricks passes: its constraints carry no hint.
const ocl::Buffer<int32_t> kNoOwners;
}  // namespace

Status DeviceOps::Correspondences(const DeviceRaster& model, const ocl::Buffer<vd_float4>& obs_v,
                                  const ocl::Buffer<vd_float4>& obs_n, const DeviceMesh& mesh,
                                  const VdCorrParams& params, ocl::Buffer<VdCorrespondence>& out) {
  const size_t n = static_cast<size_t>(model.cam.width) * model.cam.height;
  if (out.size() < n) return OutOfRange("correspondence buffer smaller than the image");
  // A mesh over the bricks names each vertex's owning brick: the constraints carry it as a hint.
  const bool owned = mesh.num_vertices > 0 && mesh.num_brick_slots == mesh.num_vertices;
  return ocl::kCorrespondences(*ctx_, n, model.vertex, model.normal, model.ids, model.bary, obs_v, obs_n,
                               mesh.positions_grid, mesh.triangles, owned ? mesh.brick_slots : kNoOwners, params, out);
}

Status DeviceOps::PhotometricCorrespondences(const DeviceRaster& model, const ocl::Buffer<vd_float4>& obs_v,
                                             const DeviceMesh& mesh, const ocl::Buffer<float>& intensity,
                                             const VdPhotoParams& params, ocl::Buffer<VdCorrespondence>& rows) {
  const size_t n = static_cast<size_t>(model.cam.width) * model.cam.height;
  const size_t blocks = static_cast<size_t>(vd_photo_rows(model.cam.width, model.cam.height));
  if (rows.size() < n + blocks) return OutOfRange("correspondence buffer without room for the colour rows");
  if (intensity.size() < static_cast<size_t>(model.cam.width / 2) * (model.cam.height / 2))
    return OutOfRange("intensity image smaller than half the raster's resolution");
  if (params.cam.width != model.cam.width || params.cam.height != model.cam.height)
    return InvalidArgument("colour rows: camera and raster sizes differ");
  return ocl::kPhotometricCorrespondences(*ctx_, blocks, model.vertex, obs_v, model.ids, model.bary, mesh.colors,
                                          mesh.triangles, intensity, params, rows);
}

}  // namespace vd
