#pragma once
// Offline mode: the engine over a data set or synthetic source, without LCM. Its own library
// (vd_server_offline), the one part of the server that links the frame sources (vd::capture).
#include "server_options.h"
#include "vd/capture/source.h"

namespace vd {

// The source flags of the offline mode (--intrinsics, --depth-scale, --start, --count, --stride).
SourceOptions ToSourceOptions(const ServerOptions& options);
// Returns the exit code.
int RunOffline(const ServerOptions& options);

}  // namespace vd
