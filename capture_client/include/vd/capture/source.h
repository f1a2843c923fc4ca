#pragma once
// Frame sources: live OpenNI2 sensors, .oni playback, data set folders and synthetic scenes.
// The same spec syntax is used by vdeform-capture --source and vdeform-server --input.
#include <memory>
#include <optional>
#include <string>

#include "vd/common/frame.h"
#include "vd/common/status.h"

namespace vd {

struct SourceOptions {
  // "fx,fy,cx,cy" overriding the source's intrinsics (empty: use the source's own).
  std::string intrinsics;
  // Raw depth units per metre overriding the source's (0: use the source's own).
  float depth_scale = 0.f;
  // First frame index to deliver (finite sources).
  int64_t start = 0;
  // Deliver at most this many frames (-1: all).
  int64_t count = -1;
  // Deliver every n-th frame (the paper's speed test uses 2..6).
  int stride = 1;
  // Restart at `start` after the last frame.
  bool loop = false;
  // Synthetic scenes: add Kinect-like depth noise.
  bool synthetic_noise = true;
  // Synthetic scenes: frames in one pass of the motion (0: the scene's own, 60). More frames, the
  // same motion: a long take with less motion per frame.
  int64_t synthetic_frames = 0;
  // Time-out for one blocking read from a device or .oni file, seconds.
  double read_timeout_s = 2.0;
  Status Validate() const;
};

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  // The next frame; std::nullopt at the end of a finite source; an error on a failed read.
  virtual StatusOr<std::optional<RgbdFrame>> Next() = 0;
  // The rate the source was recorded or is produced at, frames per second.
  virtual double NominalFps() const = 0;
  // Number of frames Next() will deliver (after start/count/stride), -1 when unknown or endless.
  virtual int64_t NumFrames() const = 0;
  // One line for logs: kind, path/device, layout, size, intrinsics.
  virtual std::string Describe() const = 0;
};

// spec: "openni2[:URI]", "oni:FILE", "folder:DIR", "synthetic:SCENE". A clear error for a
// missing folder, an unknown layout, a missing intrinsics file, an absent sensor, an unknown scene.
StatusOr<std::unique_ptr<FrameSource>> OpenSource(const std::string& spec, const SourceOptions& options);

}  // namespace vd
