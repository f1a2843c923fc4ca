#pragma once
// Private pieces shared by the frame sources: the start/count/stride/loop arithmetic and the
// per-kind factories OpenSource dispatches to.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "vd/capture/source.h"

namespace vd {

// Which raw frame indices a finite source delivers: start, start + stride, ... below the number
// of raw frames, at most `count` of them per pass, repeated from `start` when looping.
class FrameSelection {
 public:
  // `what` names the source in errors (a start past the end is an error, not an empty source).
  static StatusOr<FrameSelection> Make(int64_t num_raw, const SourceOptions& options, const std::string& what);

  // Raw index of the next frame and advances; std::nullopt at the end of a non-looping source.
  std::optional<int64_t> Advance();
  // Frames delivered per pass.
  int64_t per_pass() const { return per_pass_; }
  // Frames Next() will deliver in all: per_pass, or -1 when looping (endless).
  int64_t NumFrames() const { return loop_ ? -1 : per_pass_; }
  // Completed passes before the frame last returned by Advance() (0 during the first pass).
  int64_t pass() const { return pass_; }
  // Frames returned by Advance() so far, across passes.
  int64_t delivered() const { return delivered_; }

 private:
  int64_t start_ = 0;
  int64_t stride_ = 1;
  int64_t per_pass_ = 0;
  bool loop_ = false;
  // Position within the current pass (0 .. per_pass_).
  int64_t position_ = 0;
  int64_t pass_ = 0;
  int64_t delivered_ = 0;
};

// Applies SourceOptions::intrinsics (if given) to intrinsics of an image of width x height.
StatusOr<Intrinsics> ResolveIntrinsics(const std::optional<Intrinsics>& own, const SourceOptions& options, int width,
                                       int height, const std::string& what);

StatusOr<std::unique_ptr<FrameSource>> OpenFolderSource(const std::string& dir, const SourceOptions& options);
StatusOr<std::unique_ptr<FrameSource>> OpenSyntheticSource(const std::string& name, const SourceOptions& options);
// uri: empty for the first device found, else an OpenNI2 URI ("Dummy" for the fake device).
StatusOr<std::unique_ptr<FrameSource>> OpenOpenNiSource(const std::string& uri, const SourceOptions& options);
StatusOr<std::unique_ptr<FrameSource>> OpenOniSource(const std::string& path, const SourceOptions& options);

}  // namespace vd
