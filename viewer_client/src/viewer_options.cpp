#include "vd/viewer/viewer_options.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>

namespace vd {
namespace {

StatusOr<int64_t> ParseInt(const std::string& flag, const std::string& text) {
  errno = 0;
  char* end = nullptr;
  const long long value = std::strtoll(text.c_str(), &end, 10);
  if (text.empty() || errno != 0 || end == nullptr || *end != '\0')
    return InvalidArgument(flag + " expects an integer, got '" + text + "'");
  return static_cast<int64_t>(value);
}

StatusOr<double> ParseDouble(const std::string& flag, const std::string& text) {
  errno = 0;
  char* end = nullptr;
  const double value = std::strtod(text.c_str(), &end);
  if (text.empty() || errno != 0 || end == nullptr || *end != '\0' || !std::isfinite(value))
    return InvalidArgument(flag + " expects a number, got '" + text + "'");
  return value;
}

}  // namespace

Status ViewerOptions::Validate() const {
  if (png && save_dir.empty()) return InvalidArgument("--png needs --save-dir DIR (where the PNGs go)");
  if (image_width < 16 || image_width > 8192 || image_height < 16 || image_height > 8192)
    return InvalidArgument("--png-size = " + std::to_string(image_width) + "x" + std::to_string(image_height) +
                           " violates 16 <= width, height <= 8192");
  if (count < 0) return InvalidArgument("--count = " + std::to_string(count) + " violates count >= 0");
  if (!std::isfinite(timeout_s) || timeout_s < 0.0 || timeout_s > 1e6)
    return InvalidArgument("--timeout = " + std::to_string(timeout_s) + " violates 0 <= timeout <= 1e6 seconds");
  return Status::Ok();
}

Status ParseImageSize(const std::string& text, int* width, int* height) {
  const size_t x = text.find_first_of("xX");
  if (x == std::string::npos) return InvalidArgument("--png-size expects WxH (e.g. 640x480), got '" + text + "'");
  auto w = ParseInt("--png-size width", text.substr(0, x));
  auto h = ParseInt("--png-size height", text.substr(x + 1));
  if (!w.ok()) return w.status();
  if (!h.ok()) return h.status();
  if (*w < 16 || *w > 8192 || *h < 16 || *h > 8192)
    return InvalidArgument("--png-size = " + text + " violates 16 <= width, height <= 8192");
  *width = static_cast<int>(*w);
  *height = static_cast<int>(*h);
  return Status::Ok();
}

StatusOr<ViewerOptions> ParseViewerArgs(const std::vector<std::string>& args) {
  ViewerOptions options;
  for (size_t i = 0; i < args.size(); ++i) {
    std::string flag = args[i];
    std::string value;
    bool has_inline_value = false;
    // --flag=value is accepted as well as --flag value.
    const size_t eq = flag.find('=');
    if (flag.rfind("--", 0) == 0 && eq != std::string::npos) {
      value = flag.substr(eq + 1);
      flag = flag.substr(0, eq);
      has_inline_value = true;
    }
    auto take_value = [&]() -> StatusOr<std::string> {
      if (has_inline_value) return value;
      if (i + 1 >= args.size()) return InvalidArgument(flag + " needs a value");
      return args[++i];
    };
    auto no_value = [&]() -> Status {
      return has_inline_value ? InvalidArgument(flag + " takes no value") : Status::Ok();
    };
    if (flag == "--help" || flag == "-h") {
      VD_RETURN_IF_ERROR(no_value());
      options.help = true;
    } else if (flag == "--headless") {
      VD_RETURN_IF_ERROR(no_value());
      options.headless = true;
    } else if (flag == "--png") {
      VD_RETURN_IF_ERROR(no_value());
      options.png = true;
    } else if (flag == "--quiet") {
      VD_RETURN_IF_ERROR(no_value());
      options.quiet = true;
    } else if (flag == "--no-request") {
      VD_RETURN_IF_ERROR(no_value());
      options.no_request = true;
    } else if (flag == "--lcm-url") {
      VD_ASSIGN_OR_RETURN(options.lcm_url, take_value());
    } else if (flag == "--save-dir") {
      VD_ASSIGN_OR_RETURN(options.save_dir, take_value());
      if (options.save_dir.empty()) return InvalidArgument("--save-dir needs a non-empty directory");
    } else if (flag == "--png-size") {
      VD_ASSIGN_OR_RETURN(std::string size, take_value());
      VD_RETURN_IF_ERROR(ParseImageSize(size, &options.image_width, &options.image_height));
    } else if (flag == "--count") {
      VD_ASSIGN_OR_RETURN(std::string text, take_value());
      VD_ASSIGN_OR_RETURN(options.count, ParseInt("--count", text));
    } else if (flag == "--timeout") {
      VD_ASSIGN_OR_RETURN(std::string text, take_value());
      VD_ASSIGN_OR_RETURN(options.timeout_s, ParseDouble("--timeout", text));
    } else if (flag == "--color") {
      VD_ASSIGN_OR_RETURN(std::string text, take_value());
      VD_ASSIGN_OR_RETURN(options.color_mode, ParseColorMode(text));
    } else {
      return InvalidArgument("unknown argument '" + args[i] + "' (see --help)");
    }
  }
  if (!options.help) VD_RETURN_IF_ERROR(options.Validate());
  return options;
}

std::string ViewerHelpText() {
  return R"(vdeform-viewer: shows, and optionally saves, the meshes vdeform-server publishes over LCM.

Usage: vdeform-viewer [flags]

With a display ($DISPLAY or $WAYLAND_DISPLAY set) and without --headless it opens a window with
the shaded live mesh and a status overlay: left-drag rotates, wheel or right-drag zooms, c cycles
the colouring (canonical -> vertex -> shade), r resets the view, q or Esc quits. Otherwise it
prints a status line (refreshed in place on a terminal, one line per second when piped).
At start-up it asks the server for its current meshes (REQUEST_MESH), so it shows them at once.

Flags:
  --lcm-url URL     LCM URL to listen on. Default: $LCM_DEFAULT_URL if set, else
                    udpm://239.255.76.67:7667?ttl=0&recv_buf_size=4194304
                    A recorded log replays with file:///path/log.lcm?speed=0 (the end of the
                    log ends the run, exit 0 unless --count was not reached).
  --headless        never open a window; print the status line instead.
  --save-dir DIR    write each received mesh as DIR/frame-%06d.mesh.ply (LIVE, the frame's seq)
                    and DIR/frame-%06d.canonical.ply (CANONICAL); DIR is created if missing.
  --png             also write CPU-rendered images DIR/frame-%06d.png of each live mesh, seen from
                    the live camera, and DIR/final.png of the last mesh at exit (needs --save-dir).
  --png-size WxH    size of the PNGs and of the window. Default 640x480.
  --color MODE      colouring: canonical (each point coloured by its position in the canonical
                    pose, VolumeDeform Fig. 8; the mesh's own colour until a canonical mesh of the
                    same frame arrives), vertex (the mesh's colour), shade (grey). Default canonical.
  --count N         exit 0 after N new live meshes. Default 0: run until SIGINT/SIGTERM.
  --timeout S       exit 1 with a message if no mesh or status message arrives for S seconds.
                    Default 0: wait forever.
  --quiet           no status line and no informational messages (warnings, errors and the
                    exit summary are still printed).
  --no-request      do not send REQUEST_MESH at start-up.
  --help, -h        print this text and exit.

SIGINT/SIGTERM end it cleanly: it prints a summary (meshes received/decoded/failed, bytes, last
seq, last server status, files written) and exits 0. Corrupt messages are counted, logged once
per kind, and skipped.
Exit status: 0 done (count reached or signal), 1 time-out or run-time failure, 2 bad flags.
)";
}

}  // namespace vd
