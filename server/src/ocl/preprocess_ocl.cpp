// DeviceOps' launchers of kernels/preprocess.cl (class in ocl/device_ops.h).
#include "ocl/preprocess_ocl.h"

#include "ocl/device_ops.h"

namespace vd {

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

Status DeviceOps::Intensity(const ocl::Buffer<uint32_t>& rgba, ocl::Buffer<float>& tmp, ocl::Buffer<float>& out,
                            int width, int height) {
  const int w = width / 2, h = height / 2;
  const size_t n = static_cast<size_t>(w) * h;
  if (w < 2 || h < 2) return InvalidArgument("intensity image: the colour image is smaller than 4x4");
  if (tmp.size() < n || out.size() < n) return OutOfRange("intensity image: buffers smaller than half resolution");
  VD_RETURN_IF_ERROR(ocl::kLumaHalf(*ctx_, n, rgba, out, width, w));
  VD_RETURN_IF_ERROR(ocl::kHBlur(*ctx_, n, out, tmp, w));
  return ocl::kVBlur(*ctx_, n, tmp, out, w, h);
}

}  // namespace vd
