// vdeform-viewer: subscribes to the server's meshes and status, shows them in a window or as a
// terminal status line, and saves PLY files and PNG renderings. See --help.
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include <lcm/lcm-cpp.hpp>

#include "vd/common/auth.h"
#include "vd/common/log.h"
#include "vd/common/lcm_guard.h"
#include "vd/common/messages.h"
#include "vd/common/stop_signal.h"
#include "vd/viewer/display.h"
#include "vd/viewer/receiver.h"
#include "vd/viewer/status_text.h"
#include "vd/viewer/viewer_options.h"
#include "window.h"

namespace {

int Main(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  vd::StatusOr<vd::ViewerOptions> parsed = vd::ParseViewerArgs(args);
  if (!parsed.ok()) {
    std::fprintf(stderr, "vdeform-viewer: %s\n", parsed.status().message().c_str());
    return 2;
  }
  const vd::ViewerOptions& options = *parsed;
  if (options.help) {
    std::printf("%s", vd::ViewerHelpText().c_str());
    return 0;
  }
  if (options.quiet) vd::SetLogLevel(vd::LogLevel::kWarning);
  const vd::StatusOr<std::string> output_key = vd::OutputKeyFromFlag(options.key_file);
  if (!output_key.ok()) {
    std::fprintf(stderr, "vdeform-viewer: %s\n", output_key.status().message().c_str());
    return 2;
  }
  vd::InstallStopSignalHandlers();
  std::atomic<bool>& g_stop = vd::StopFlag();

  bool windowed = !options.headless;
  if (windowed) {
    vd::Status display = vd::CheckDisplay();
    if (!display.ok()) {
      VD_LOG_WARNING << "no display (" << display.message() << "): running headless";
      windowed = false;
    }
  }

  const std::string url = vd::ResolveLcmUrl(options.lcm_url);
  lcm::LCM lcm(url);
  if (!lcm.good()) {
    std::fprintf(stderr, "vdeform-viewer: cannot open LCM at '%s' %s\n",
                 url.c_str(), vd::kLcmRouteHint);
    return 1;
  }

  vd::ReceiverOptions receiver_options;
  receiver_options.save_dir = options.save_dir;
  receiver_options.write_png = options.png;
  receiver_options.render.width = options.image_width;
  receiver_options.render.height = options.image_height;
  receiver_options.color_mode = options.color_mode;
  receiver_options.request_mesh = !options.no_request;
  receiver_options.sender = "vdeform-viewer:" + std::to_string(getpid());
  receiver_options.channels = *vd::ChannelsOfStream(options.stream);
  receiver_options.output_key = *output_key;
  // Saving every mesh matters more than latency: ride out ~8 s of a 30 Hz server at 2x our pace.
  if (!options.save_dir.empty()) receiver_options.mesh_queue_capacity = 240;
  vd::StatusOr<std::unique_ptr<vd::MeshReceiver>> created = vd::MeshReceiver::Create(&lcm, receiver_options);
  if (!created.ok()) {
    std::fprintf(stderr, "vdeform-viewer: %s\n", created.status().ToString().c_str());
    return 1;
  }
  vd::MeshReceiver& receiver = **created;
  vd::GuardLcmOrWarn(url, "vdeform-viewer");
  VD_LOG_INFO << "listening on " << url << " (" << receiver_options.channels.mesh << ", "
              << receiver_options.channels.status << ")"
              << (receiver.stats().requests_sent > 0 ? "; asked the server for its current meshes" : "")
              << (options.save_dir.empty() ? "" : "; saving to " + options.save_dir)
              << (output_key->empty() ? "" : "; only output signed under the key");

  vd::RunOptions run;
  run.count = options.count;
  run.timeout_s = options.timeout_s;
  vd::StatusPrinter printer(!options.quiet && !windowed);
  std::unique_ptr<vd::MeshWindow> window;
  if (windowed) {
    vd::StatusOr<std::unique_ptr<vd::MeshWindow>> opened =
        vd::MeshWindow::Open("vdeform-viewer", receiver_options.render, options.color_mode);
    if (opened.ok()) {
      window = std::move(opened).value();
    } else {
      VD_LOG_WARNING << opened.status().ToString() << ": running headless";
      printer = vd::StatusPrinter(!options.quiet);
    }
  }
  std::function<void()> tick;
  if (window) {
    // Short LCM waits keep the window responsive; waitKey does the rest of the pacing.
    run.poll_ms = 5;
    tick = [&] {
      if (!window->Update(receiver, 10)) g_stop.store(true);
    };
  } else {
    tick = [&] { printer.Tick([&] { return vd::StatusLine(receiver.stats(), receiver.last_status()); }); };
  }

  vd::Status ran = receiver.Run(run, &g_stop, tick);
  // A file:// log being replayed ends with LCM refusing to handle more: the end of the input.
  const bool replay = url.rfind("file://", 0) == 0;
  if (replay && ran.code() == vd::StatusCode::kUnavailable) {
    if (options.count > 0 && receiver.stats().live_meshes < options.count) {
      ran = vd::OutOfRange("the log ended after " + std::to_string(receiver.stats().live_meshes) + " of the " +
                           std::to_string(options.count) + " live meshes asked for (--count)");
    } else {
      VD_LOG_INFO << "end of the log " << url;
      ran = vd::Status::Ok();
    }
  }
  printer.Finish();
  window.reset();
  const vd::Status finished = receiver.Finish();
  if (!finished.ok()) std::fprintf(stderr, "vdeform-viewer: %s\n", finished.ToString().c_str());
  std::printf("%s", vd::SummaryText(receiver.stats(), receiver.last_status(), receiver.written_paths()).c_str());
  std::fflush(stdout);
  if (!ran.ok()) {
    std::fprintf(stderr, "vdeform-viewer: %s\n", ran.message().c_str());
    return 1;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return Main(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "vdeform-viewer: unexpected error: %s\n", e.what());
    return 1;
  }
}
