#pragma once
// Pinhole camera intrinsics, and parsing of the intrinsics files of the supported data sets.
#include <string>

#include "vd/common/status.h"

namespace vd {

struct Intrinsics {
  // Focal lengths in pixels.
  float fx = 0.f;
  float fy = 0.f;
  // Principal point in pixels.
  float cx = 0.f;
  float cy = 0.f;
  // Image size the intrinsics refer to.
  int width = 0;
  int height = 0;

  // Rejects non-finite, non-positive or absurd values (names the field and the bound).
  Status Validate() const;
  // Intrinsics of the image downsampled by 2^level (pixel centres kept consistent).
  Intrinsics Scaled(int level) const;
  std::string ToString() const;
};

// "fx,fy,cx,cy" as given on the command line.
StatusOr<Intrinsics> ParseIntrinsicsFlag(const std::string& text, int width, int height);

// Reads an intrinsics text file: a 3x3 or 4x4 matrix (7-Scenes, DeepDeform, KillingFusion) or a
// single line "fx fy cx cy". Width and height are filled in by the caller.
StatusOr<Intrinsics> LoadIntrinsicsFile(const std::string& path);

}  // namespace vd
