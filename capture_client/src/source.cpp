#include "vd/capture/source.h"

#include <cmath>
#include <sstream>

#include "source_internal.h"

namespace vd {

Status SourceOptions::Validate() const {
  auto bad = [](const char* field, const std::string& value, const char* bound) {
    return InvalidArgument(std::string("source option ") + field + " = " + value + " violates " + bound);
  };
  if (!intrinsics.empty()) {
    // Only the syntax can be checked here; the image size is known once the source is open.
    auto parsed = ParseIntrinsicsFlag(intrinsics, 640, 480);
    if (!parsed.ok()) return parsed.status();
  }
  if (!std::isfinite(depth_scale) || depth_scale < 0.f || depth_scale >= 1e6f)
    return bad("depth_scale", std::to_string(depth_scale), "0 <= depth_scale < 1e6 (0: the source's own)");
  if (start < 0) return bad("start", std::to_string(start), "start >= 0");
  if (count < -1 || count == 0) return bad("count", std::to_string(count), "count > 0 or -1 (all)");
  if (stride < 1 || stride > 10000) return bad("stride", std::to_string(stride), "1 <= stride <= 10000");
  if (synthetic_frames < 0 || synthetic_frames > 1000000)
    return bad("frames", std::to_string(synthetic_frames), "0 <= frames <= 1000000 (0: the scene's own)");
  if (!std::isfinite(read_timeout_s) || read_timeout_s <= 0.0 || read_timeout_s > 3600.0)
    return bad("read_timeout_s", std::to_string(read_timeout_s), "0 < read_timeout_s <= 3600");
  return Status::Ok();
}

StatusOr<FrameSelection> FrameSelection::Make(int64_t num_raw, const SourceOptions& options, const std::string& what) {
  VD_RETURN_IF_ERROR(options.Validate());
  if (num_raw <= 0) return NotFound(what + " has no frames");
  if (options.start >= num_raw)
    return OutOfRange(what + ": start " + std::to_string(options.start) + " is past the last frame (" +
                      std::to_string(num_raw) + " frames, first index 0)");
  FrameSelection s;
  s.start_ = options.start;
  s.stride_ = options.stride;
  s.loop_ = options.loop;
  // ceil((num_raw - start) / stride) frames remain after start.
  const int64_t available = (num_raw - options.start + options.stride - 1) / options.stride;
  s.per_pass_ = options.count < 0 ? available : std::min(available, options.count);
  return s;
}

std::optional<int64_t> FrameSelection::Advance() {
  if (position_ >= per_pass_) {
    if (!loop_) return std::nullopt;
    position_ = 0;
    ++pass_;
  }
  const int64_t raw = start_ + position_ * stride_;
  ++position_;
  ++delivered_;
  return raw;
}

StatusOr<Intrinsics> ResolveIntrinsics(const std::optional<Intrinsics>& own, const SourceOptions& options, int width,
                                       int height, const std::string& what) {
  Intrinsics k;
  if (!options.intrinsics.empty()) {
    VD_ASSIGN_OR_RETURN(k, ParseIntrinsicsFlag(options.intrinsics, width, height));
  } else if (own) {
    k = *own;
    k.width = width;
    k.height = height;
  } else {
    return FailedPrecondition(what + " has no intrinsics: give them with --intrinsics fx,fy,cx,cy");
  }
  Status valid = k.Validate();
  if (!valid.ok()) return valid.WithContext(what);
  return k;
}

StatusOr<std::unique_ptr<FrameSource>> OpenSource(const std::string& spec, const SourceOptions& options) {
  VD_RETURN_IF_ERROR(options.Validate());
  const size_t colon = spec.find(':');
  const std::string scheme = spec.substr(0, colon);
  const std::string rest = colon == std::string::npos ? std::string() : spec.substr(colon + 1);
  const bool has_rest = colon != std::string::npos;
  if (scheme == "folder") {
    if (rest.empty()) return InvalidArgument("source '" + spec + "': expected folder:DIR");
    return OpenFolderSource(rest, options);
  }
  if (scheme == "synthetic") {
    if (rest.empty()) return InvalidArgument("source '" + spec + "': expected synthetic:SCENE");
    return OpenSyntheticSource(rest, options);
  }
  if (scheme == "openni2") {
    if (has_rest && rest.empty()) return InvalidArgument("source '" + spec + "': expected openni2 or openni2:URI");
    return OpenOpenNiSource(rest, options);
  }
  if (scheme == "oni") {
    if (rest.empty()) return InvalidArgument("source '" + spec + "': expected oni:FILE");
    return OpenOniSource(rest, options);
  }
  return InvalidArgument("unknown source '" + spec +
                         "': valid sources are openni2[:URI], oni:FILE, folder:DIR, synthetic:SCENE");
}

}  // namespace vd
