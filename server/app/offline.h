#pragma once
// Offline mode: the engine over a data set or synthetic source, without LCM. Its own library
// (vd_server_offline), the one part of the server that links the frame sources (vd::capture).
#include <cstdint>

#include "server_options.h"
#include "vd/capture/source.h"

namespace vd {

// The source flags of the offline mode (--intrinsics, --depth-scale, --start, --count, --stride).
SourceOptions ToSourceOptions(const ServerOptions& options);
// Index in the source of the frame delivered after `delivered` others: start + delivered * stride,
// as every source selects them (the offline mode never loops). --save-dir names files by it.
int64_t SourceFrameIndex(const SourceOptions& options, int64_t delivered);
// Returns the exit code.
int RunOffline(const ServerOptions& options);

}  // namespace vd
