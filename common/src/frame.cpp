#include "vd/common/frame.h"

#include <limits>

namespace vd {

Status RgbdFrame::Validate() const {
  VD_RETURN_IF_ERROR(intrinsics.Validate());
  if (depth.empty()) return InvalidArgument("frame has no depth image");
  if (depth.type() != CV_16UC1) return InvalidArgument("depth must be CV_16UC1");
  if (depth.cols != intrinsics.width || depth.rows != intrinsics.height)
    return InvalidArgument("depth is " + std::to_string(depth.cols) + "x" + std::to_string(depth.rows) +
                           " but intrinsics say " + std::to_string(intrinsics.width) + "x" +
                           std::to_string(intrinsics.height));
  if (!color.empty()) {
    if (color.type() != CV_8UC3) return InvalidArgument("colour must be CV_8UC3");
    if (color.size() != depth.size())
      return InvalidArgument("colour is " + std::to_string(color.cols) + "x" + std::to_string(color.rows) +
                             ", depth " + std::to_string(depth.cols) + "x" + std::to_string(depth.rows));
  }
  if (!(depth_scale > 0.f) || !(depth_scale < 1e6f))
    return InvalidArgument("depth_scale = " + std::to_string(depth_scale) + " violates 0 < depth_scale < 1e6");
  return Status::Ok();
}

cv::Mat RgbdFrame::DepthMetres() const {
  cv::Mat out(depth.size(), CV_32FC1);
  const float inv = 1.f / depth_scale;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int y = 0; y < depth.rows; ++y) {
    const uint16_t* src = depth.ptr<uint16_t>(y);
    float* dst = out.ptr<float>(y);
    for (int x = 0; x < depth.cols; ++x) dst[x] = src[x] ? src[x] * inv : nan;
  }
  return out;
}

}  // namespace vd
