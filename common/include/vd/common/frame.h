#pragma once
// An uncompressed RGB-D frame as the programs pass it around.
#include <cstdint>
#include <string>

#include <opencv2/core.hpp>

#include "vd/common/camera.h"

namespace vd {

struct RgbdFrame {
  // Capture time in microseconds since the epoch (or since the start of a recording).
  int64_t utime = 0;
  // Monotonic frame number of the source.
  int64_t seq = 0;
  // The run of the source this frame belongs to: a random number each capture process picks.
  int64_t epoch = 0;
  std::string source_id;
  Intrinsics intrinsics;
  // Raw depth units per metre (1000 for millimetres).
  float depth_scale = 1000.f;
  // CV_16UC1, 0 = invalid.
  cv::Mat depth;
  // CV_8UC3 BGR, same size as depth; may be empty when the source has no colour.
  cv::Mat color;

  // Checks sizes, types and intrinsics agree.
  Status Validate() const;
  // Depth in metres as CV_32FC1 with NaN for invalid pixels.
  cv::Mat DepthMetres() const;
};

}  // namespace vd
