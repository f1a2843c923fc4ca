#pragma once
// vdeform-viewer's command line: flags, defaults, validation and --help text.
#include <cstdint>
#include <string>
#include <vector>

#include "vd/common/status.h"
#include "vd/viewer/render.h"

namespace vd {

struct ViewerOptions {
  // LCM URL; empty: $LCM_DEFAULT_URL, else vd::kDefaultLcmUrl (see ResolveLcmUrl).
  std::string lcm_url;
  // Stream name (--stream): channels VDEFORM_<NAME>_MESH ...; empty: today's names.
  std::string stream;
  // No window even when a display is available: a terminal status line instead.
  bool headless = false;
  // Where received meshes (and PNGs) go; empty: nothing is saved.
  std::string save_dir;
  // Write CPU-rendered PNGs of each live mesh and final.png at exit (needs save_dir).
  bool png = false;
  // PNG and window size in pixels.
  int image_width = 640;
  int image_height = 480;
  // Exit 0 after this many new live meshes; 0: run until a signal.
  int64_t count = 0;
  // Exit non-zero when nothing arrived for this many seconds; 0: wait forever.
  double timeout_s = 0.0;
  // No status line and no informational log lines; warnings, errors and the summary remain.
  bool quiet = false;
  // Initial colouring (the window's c key cycles it).
  ColorMode color_mode = ColorMode::kCanonical;
  // Do not send REQUEST_MESH at start-up (then the first mesh is the next one the server makes).
  bool no_request = false;
  // The server's --output-key-file: show and save only meshes and status signed under it; empty:
  // everything on the channels is taken.
  std::string key_file;
  // --help was given: print ViewerHelpText() and exit 0.
  bool help = false;
  Status Validate() const;
};

// Parses argv[1..]; unknown flags, missing values and bad numbers are errors naming the flag.
StatusOr<ViewerOptions> ParseViewerArgs(const std::vector<std::string>& args);
// "WxH" with both in 16..8192.
Status ParseImageSize(const std::string& text, int* width, int* height);
std::string ViewerHelpText();

}  // namespace vd
