#include "vd/viewer/viewer_options.h"

#include <cmath>

#include "vd/common/flags.h"
#include "vd/common/messages.h"

namespace vd {
namespace {

constexpr const char* kUsage = R"(vdeform-viewer: shows, and optionally saves, the meshes vdeform-server publishes over LCM.

Usage: vdeform-viewer [flags]

With a display ($DISPLAY or $WAYLAND_DISPLAY set) and without --headless it opens a window with
the shaded live mesh and a status overlay: left-drag rotates, wheel or right-drag zooms, c cycles
the colouring (canonical -> vertex -> shade), r resets the view, q or Esc quits. Otherwise it
prints a status line (refreshed in place on a terminal, one line per second when piped).
At start-up it asks the server for its current meshes (REQUEST_MESH), so it shows them at once.)";

constexpr const char* kEpilogue = R"(SIGINT/SIGTERM end it cleanly: it prints a summary (meshes received/decoded/failed, bytes, last
seq, last server status, files written) and exits 0. Corrupt messages are counted, logged once
per kind, and skipped.
Exit status: 0 done (count reached or signal), 1 time-out or run-time failure, 2 bad flags or --key-file.
)";

void Bind(FlagParser* f, ViewerOptions* o) {
  f->Add("lcm-url", &o->lcm_url,
         "LCM URL to listen on. Default: $LCM_DEFAULT_URL if set, else "
         "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=4194304. A recorded log replays with "
         "file:///path/log.lcm?speed=0 (the end of the log ends the run, exit 0 unless --count was not reached).",
         "URL");
  f->AddCustom("stream", "NAME", "",
               "Show the stream NAME: channels VDEFORM_<NAME>_MESH, _STATUS and _CONTROL (several servers on one LCM "
               "URL). Default: the unnamed stream (VDEFORM_MESH, ...).",
               [o](const std::string& v) {
                 VD_RETURN_IF_ERROR(ValidateStreamName(v).WithContext("--stream"));
                 o->stream = v;
                 return Status::Ok();
               });
  f->AddSwitch("headless", &o->headless, "Never open a window; print the status line instead.");
  f->AddCustom("save-dir", "DIR", "",
               "Write each received mesh as DIR/frame-%06d.mesh.ply (LIVE, the frame's seq), "
               "DIR/frame-%06d.canonical.ply (CANONICAL) and DIR/frame-%06d.tracked.ply (TRACKED, from a server with "
               "--track-mesh); DIR is created if missing.",
               [o](const std::string& v) {
                 if (v.empty()) return InvalidArgument("--save-dir needs a non-empty directory");
                 o->save_dir = v;
                 return Status::Ok();
               });
  f->AddSwitch("png", &o->png,
               "Also write CPU-rendered images DIR/frame-%06d.png of each live mesh, seen from the live camera, and "
               "DIR/final.png of the last mesh at exit (needs --save-dir).");
  f->AddCustom("png-size", "WxH", std::to_string(o->image_width) + "x" + std::to_string(o->image_height),
               "Size of the PNGs and of the window.",
               [o](const std::string& v) { return ParseImageSize(v, &o->image_width, &o->image_height); });
  f->AddCustom("color", "MODE", ColorModeName(o->color_mode),
               "Colouring: canonical (each point coloured by its position in the canonical pose, VolumeDeform "
               "Fig. 8; the mesh's own colour until a canonical mesh of the same frame arrives), vertex (the "
               "mesh's colour), shade (grey).",
               [o](const std::string& v) {
                 VD_ASSIGN_OR_RETURN(o->color_mode, ParseColorMode(v));
                 return Status::Ok();
               });
  f->Add("count", &o->count, "Exit 0 after N new live meshes (0: run until SIGINT/SIGTERM).", "N");
  f->Add("timeout", &o->timeout_s,
         "Exit 1 with a message if no mesh or status message arrives for S seconds (0: wait forever).", "S");
  f->AddSwitch("quiet", &o->quiet,
               "No status line and no informational messages (warnings, errors and the exit summary are still "
               "printed).");
  f->AddSwitch("no-request", &o->no_request, "Do not send REQUEST_MESH at start-up.");
  f->Add("key-file", &o->key_file,
         "The server's --output-key-file (one line KEY, 64 hex digits, mode 600): show and save only meshes and "
         "status signed under it by the running server; unsigned, wrongly signed and replayed ones are counted "
         "(status line, summary) and dropped. Default: everything is shown.",
         "FILE");
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
  VD_ASSIGN_OR_RETURN(int64_t w, ParseFlagInteger("png-size width", text.substr(0, x)));
  VD_ASSIGN_OR_RETURN(int64_t h, ParseFlagInteger("png-size height", text.substr(x + 1)));
  if (w < 16 || w > 8192 || h < 16 || h > 8192)
    return InvalidArgument("--png-size = " + text + " violates 16 <= width, height <= 8192");
  *width = static_cast<int>(w);
  *height = static_cast<int>(h);
  return Status::Ok();
}

StatusOr<ViewerOptions> ParseViewerArgs(const std::vector<std::string>& args) {
  ViewerOptions options;
  FlagParser flags(kUsage, kEpilogue);
  Bind(&flags, &options);
  VD_RETURN_IF_ERROR(flags.Parse(args, &options.help));
  if (!options.help) VD_RETURN_IF_ERROR(options.Validate());
  return options;
}

std::string ViewerHelpText() {
  ViewerOptions defaults;
  FlagParser flags(kUsage, kEpilogue);
  Bind(&flags, &defaults);
  return flags.Help();
}

}  // namespace vd
