// vdeform-capture: reads RGB-D frames from a sensor, a recording, a data set folder or a synthetic
// scene, compresses them and publishes vdeform::rgbd_frame_t on the LCM frame channel.
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include <lcm/lcm-cpp.hpp>

#include "vd/capture/pacing.h"
#include "vd/capture/source.h"
#include "vd/capture/synthetic.h"
#include "vd/common/auth.h"
#include "vd/common/codecs.h"
#include "vd/common/flags.h"
#include "vd/common/log.h"
#include "vd/common/lcm_guard.h"
#include "vd/common/messages.h"
#include "vd/common/stop_signal.h"

namespace vd {
namespace {

constexpr const char* kUsage = R"(Usage: vdeform-capture [options]

Reads RGB-D frames and publishes them as vdeform::rgbd_frame_t on the LCM channel VDEFORM_FRAMES,
with sequence numbers from 0 and utime = capture time.)";

constexpr const char* kEpilogue =
    "Exit status: 0 on success or after SIGINT/SIGTERM, 1 on a run-time error, 2 on bad arguments.\n";

std::atomic<bool>& g_stop = vd::StopFlag();

struct Args {
  std::string source = "synthetic:tube";
  // --stream: the channels' name; empty: today's names.
  std::string stream;
  SourceOptions source_options;
  // Used only when --fps is given (has_fps); otherwise the source's own rate.
  double fps = 0.0;
  bool has_fps = false;
  bool max_rate = false;
  bool lockstep = false;
  double lockstep_timeout_s = 10.0;
  int lockstep_retries = 3;
  FrameEncodeOptions encode;
  std::string source_id;
  // --frame-key-file, and the key of our source id read from it (empty = frames go unsigned).
  std::string frame_key_file;
  std::string frame_key;
  // --output-key-file, and the server's output key read from it (empty = status not verified).
  std::string output_key_file;
  std::string output_key;
  std::string lcm_url;
  std::string write_dir;
  bool quiet = false;
};

void Bind(FlagParser* f, Args* a) {
  f->Section("Source");
  f->Add("source", &a->source,
         "openni2[:URI] live OpenNI2 sensor (first real device, or URI; openni2:Dummy is OpenNI2's fake device); "
         "oni:FILE OpenNI2 recording; folder:DIR data set folder: VolumeDeform, 7-Scenes/BundleFusion, DeepDeform, "
         "TUM RGB-D or KillingFusion (detected); synthetic:NAME synthetic scene (" +
             SyntheticSceneList() + ")",
         "SPEC");
  f->Add("intrinsics", &a->source_options.intrinsics, "Override the source's intrinsics, pixels", "FX,FY,CX,CY");
  f->Add("depth-scale", &a->source_options.depth_scale, "Override the raw depth units per metre (0 = source's)", "S");
  f->Add("start", &a->source_options.start, "First frame to send (finite sources)", "N");
  f->Add("count", &a->source_options.count, "Send at most N frames (with --loop: per pass; -1 = all)", "N");
  f->Add("stride", &a->source_options.stride, "Send every N-th frame", "N");
  f->AddSwitch("loop", &a->source_options.loop, "Restart at --start after the last frame (endless)");
  f->AddNegation("no-noise", &a->source_options.synthetic_noise, "Synthetic scenes without Kinect-like depth noise");
  f->Add("frames", &a->source_options.synthetic_frames,
         "Synthetic scenes: frames in one pass of the motion, also with --write (0 = the scene's own, 60; more = a "
         "long take of the same motion)",
         "N");
  f->Add("read-timeout", &a->source_options.read_timeout_s, "Give up on a sensor/recording read after S seconds", "S");
  f->Section("Rate");
  f->AddCustom("fps", "N", "the source's own rate", "Send at N frames per second", [a](const std::string& v) {
    VD_ASSIGN_OR_RETURN(a->fps, ParseFlagNumber("fps", v));
    return Status::Ok();
  });
  f->AddSwitch("max-rate", &a->max_rate, "Send as fast as possible (no pacing)");
  f->AddSwitch("lockstep", &a->lockstep,
               "Send frame k+1 only after the server reported frame k processed (server_status_t on VDEFORM_STATUS "
               "naming our --source-id)");
  f->Add("lockstep-timeout", &a->lockstep_timeout_s, "Seconds to wait for that report before re-sending", "S");
  f->Add("lockstep-retries", &a->lockstep_retries, "Re-sends of an unacknowledged frame before giving up", "N");
  f->Section("Encoding and transport");
  f->AddCustom("depth-codec", "C", DepthEncodingName(a->encode.depth), "rvl, png or raw", [a](const std::string& v) {
    VD_ASSIGN_OR_RETURN(a->encode.depth, ParseDepthEncoding(v));
    return Status::Ok();
  });
  f->AddCustom("color-codec", "C", ColorEncodingName(a->encode.color), "jpeg, raw or none", [a](const std::string& v) {
    VD_ASSIGN_OR_RETURN(a->encode.color, ParseColorEncoding(v));
    return Status::Ok();
  });
  f->Add("jpeg-quality", &a->encode.jpeg_quality, "JPEG quality, 1..100", "Q");
  f->Add("source-id", &a->source_id, "Source id in every frame (default capture-<hostname>-<pid>)", "ID");
  f->AddCustom("stream", "NAME", "",
               "Publish on the stream NAME: channel VDEFORM_<NAME>_FRAMES (lockstep listens to VDEFORM_<NAME>_STATUS), "
               "for a server started with the same --stream. Default: the unnamed stream (VDEFORM_FRAMES).",
               [a](const std::string& v) {
                 VD_RETURN_IF_ERROR(ValidateStreamName(v).WithContext("--stream"));
                 a->stream = v;
                 return Status::Ok();
               });
  f->Add("lcm-url", &a->lcm_url,
         "LCM URL (default: $LCM_DEFAULT_URL, else udpm://239.255.76.67:7667?ttl=0&recv_buf_size=4194304)", "URL");
  f->Add("frame-key-file", &a->frame_key_file,
         "Sign every frame with HMAC-SHA256 under the key for --source-id in FILE (the server's --frame-key-file: "
         "one line KEY for every source, or SOURCE_ID KEY lines; KEY is 64 hex digits, mode 600); empty = unsigned",
         "FILE");
  f->Add("output-key-file", &a->output_key_file,
         "With --lockstep: the server's --output-key-file (one line KEY, 64 hex digits, mode 600); only status "
         "messages signed under it by the running server acknowledge a frame, others are ignored and counted in "
         "the summary; empty = every status counts",
         "FILE");
  f->Section("Other");
  f->Add("write", &a->write_dir,
         "With a synthetic source: write the scene as a VolumeDeform-layout folder (colour, depth, intrinsics.txt, "
         "ground-truth .gt.ply and .pose.txt) and exit without LCM; --count N spreads the scene's motion over N frames",
         "DIR");
  f->AddSwitch("quiet", &a->quiet, "No progress line and no informational log (errors and the summary remain)");
}

// What the flags alone cannot check: combinations that would be silently ignored, the default id.
Status Finish(const FlagParser& flags, Args* args) {
  Args& a = *args;
  a.has_fps = flags.Given("fps");
  VD_RETURN_IF_ERROR(a.source_options.Validate());
  VD_RETURN_IF_ERROR(a.encode.Validate());
  if (a.has_fps && a.max_rate) return InvalidArgument("--fps and --max-rate exclude each other");
  if (a.has_fps && !(a.fps > 0.0 && a.fps <= 10000.0))
    return InvalidArgument("--fps " + std::to_string(a.fps) + " violates 0 < fps <= 10000");
  if (!a.lockstep && (flags.Given("lockstep-timeout") || flags.Given("lockstep-retries")))
    return InvalidArgument("--lockstep-timeout and --lockstep-retries need --lockstep");
  if (!a.write_dir.empty()) {
    if (a.source.rfind("synthetic:", 0) != 0)
      return InvalidArgument("--write needs a synthetic source (--source synthetic:NAME), got '" + a.source + "'");
    for (const char* f : {"start", "stride", "loop", "lockstep", "intrinsics", "depth-scale"})
      if (flags.Given(f)) return InvalidArgument(std::string("--") + f + " does not apply to --write");
  }
  if (a.source_id.empty()) {
    char host[256] = {0};
    if (gethostname(host, sizeof(host) - 1) != 0) std::snprintf(host, sizeof(host), "unknown");
    a.source_id = "capture-" + std::string(host) + "-" + std::to_string(getpid());
  }
  if (!a.frame_key_file.empty()) {
    if (!a.write_dir.empty()) return InvalidArgument("--frame-key-file does not apply to --write");
    VD_ASSIGN_OR_RETURN(const FrameKeys keys, ReadFrameKeys(a.frame_key_file));
    const std::string* key = keys.For(a.source_id);
    if (key == nullptr)
      return InvalidArgument("frame key file '" + a.frame_key_file + "' has no key for source '" + a.source_id +
                             "' (give --source-id, or add a line '" + a.source_id + " KEY')");
    a.frame_key = *key;
  }
  if (!a.output_key_file.empty() && !a.lockstep)
    return InvalidArgument("--output-key-file needs --lockstep (only lockstep reads the server's status)");
  VD_ASSIGN_OR_RETURN(a.output_key, OutputKeyFromFlag(a.output_key_file));
  return Status::Ok();
}

int WriteDataset(const Args& a) {
  SyntheticOptions options;
  options.noise = a.source_options.synthetic_noise;
  if (a.source_options.synthetic_frames > 0) {
    options.num_frames = static_cast<int>(a.source_options.synthetic_frames);
  } else if (a.source_options.count > 0) {
    if (a.source_options.count > 1000000) {
      std::fprintf(stderr, "vdeform-capture: error: --count %lld is too many frames to write\n",
                   static_cast<long long>(a.source_options.count));
      return 2;
    }
    options.num_frames = static_cast<int>(a.source_options.count);
  }
  const std::string name = a.source.substr(std::string("synthetic:").size());
  auto scene = MakeSyntheticScene(name, options);
  if (!scene.ok()) {
    std::fprintf(stderr, "vdeform-capture: error: %s\n", scene.status().ToString().c_str());
    return 1;
  }
  const auto t0 = std::chrono::steady_clock::now();
  const Status s = WriteSyntheticDataset(**scene, a.write_dir, (*scene)->num_frames());
  if (!s.ok()) {
    std::fprintf(stderr, "vdeform-capture: error: writing %s: %s\n", a.write_dir.c_str(), s.ToString().c_str());
    return 1;
  }
  std::fprintf(stderr, "vdeform-capture: wrote %d frames of %s to %s in %.2f s\n", (*scene)->num_frames(),
               a.source.c_str(), a.write_dir.c_str(),
               std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  return 0;
}

int64_t NowMicros() {
  return std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// A synthetic scene is rendered on this host's CPU (~40 ms of a 2-core machine per 640x480 frame),
// unlike a sensor, which costs nothing to read: rendered while streaming at 30 fps it takes more
// than a core from a server beside it. So a finite synthetic take is rendered and encoded once,
// before streaming, and sent from memory (~75 KB a frame); stamping and signing happen per send.
constexpr int64_t kMaxPrerenderedFrames = 3000;

// Not in --lockstep: there the server waits for the capture anyway, and rendering between frames
// costs it nothing.
bool Prerenders(const Args& a, int64_t total) {
  return a.source.rfind("synthetic:", 0) == 0 && !a.lockstep && total > 0 && total <= kMaxPrerenderedFrames;
}

// Renders and encodes every frame of the source; stops early (short vector) on a stop signal.
StatusOr<std::vector<vdeform::rgbd_frame_t>> Prerender(FrameSource* source, const Args& a, int64_t total) {
  std::vector<vdeform::rgbd_frame_t> out;
  out.reserve(size_t(total));
  const bool progress = !a.quiet && isatty(STDERR_FILENO);
  while (!g_stop.load()) {
    VD_ASSIGN_OR_RETURN(std::optional<RgbdFrame> frame, source->Next());
    if (!frame) break;
    frame->source_id = a.source_id;  // checked here; seq, epoch and time are stamped at send
    VD_ASSIGN_OR_RETURN(vdeform::rgbd_frame_t msg, FrameToMessage(*frame, a.encode));
    out.push_back(std::move(msg));
    if (progress)
      std::fprintf(stderr, "\rvdeform-capture: rendering %zu/%lld frames before streaming   ", out.size(),
                   static_cast<long long>(total));
  }
  if (progress) std::fprintf(stderr, "\n");
  return out;
}

int Run(const Args& a) {
  if (a.quiet) SetLogLevel(LogLevel::kWarning);
  if (!a.write_dir.empty()) return WriteDataset(a);

  auto source = OpenSource(a.source, a.source_options);
  if (!source.ok()) {
    std::fprintf(stderr, "vdeform-capture: error: %s\n", source.status().ToString().c_str());
    return 1;
  }
  VD_LOG_INFO << "source: " << (*source)->Describe();

  const std::string url = ResolveLcmUrl(a.lcm_url);
  lcm::LCM lcm(url);
  if (!lcm.good()) {
    std::fprintf(stderr,
                 "vdeform-capture: error: cannot initialise LCM at '%s' %s\n", url.c_str(), vd::kLcmRouteHint);
    return 1;
  }
  PacingOptions pacing;
  pacing.fps = a.max_rate ? 0.0 : (a.has_fps ? a.fps : (*source)->NominalFps());
  pacing.lockstep = a.lockstep;
  pacing.lockstep_timeout_s = a.lockstep_timeout_s;
  pacing.lockstep_retries = a.lockstep_retries;
  pacing.source_id = a.source_id;
  pacing.channels = *ChannelsOfStream(a.stream);
  pacing.output_key = a.output_key;
  auto pacer = FramePacer::Create(&lcm, pacing, &g_stop);
  if (!pacer.ok()) {
    std::fprintf(stderr, "vdeform-capture: error: %s\n", pacer.status().ToString().c_str());
    return 1;
  }
  // Only --lockstep subscribes (to the status), and so has a receive socket to guard.
  if (pacing.lockstep) GuardLcmOrWarn(url, "vdeform-capture");
  VD_LOG_INFO << "publishing on " << pacing.channels.frames << " at " << url << " as '" << a.source_id << "', "
              << (pacing.fps > 0 ? std::to_string(pacing.fps) + " fps" : std::string("max rate"))
              << (pacing.lockstep ? ", lockstep" : "") << ", depth " << DepthEncodingName(a.encode.depth)
              << ", colour " << ColorEncodingName(a.encode.color) << (a.frame_key.empty() ? "" : ", signed")
              << (a.output_key.empty() ? "" : ", status verified");

  vd::InstallStopSignalHandlers();

  // (epoch, seq) names each frame of this run: the server tells our restart (a new epoch) from
  // a recording of an earlier run played back.
  const int64_t epoch = RandomEpoch();
  const int64_t total = (*source)->NumFrames();
  const bool progress = !a.quiet && isatty(STDERR_FILENO) && total > 0;
  std::vector<vdeform::rgbd_frame_t> prerendered;
  const bool from_memory = Prerenders(a, total);
  if (from_memory) {
    auto rendered = Prerender(source->get(), a, total);
    if (!rendered.ok()) {
      std::fprintf(stderr, "vdeform-capture: error: %s\n", rendered.status().ToString().c_str());
      return 1;
    }
    prerendered = std::move(rendered).value();
    VD_LOG_INFO << "rendered " << prerendered.size() << " frames before streaming";
  }
  const auto t0 = std::chrono::steady_clock::now();
  auto last_progress = t0;
  int64_t sent = 0;
  int64_t bytes = 0;
  int rc = 0;
  while (!g_stop.load()) {
    StatusOr<vdeform::rgbd_frame_t> msg = InvalidArgument("no frame");
    if (from_memory) {
      if (sent >= static_cast<int64_t>(prerendered.size())) break;
      msg = prerendered[size_t(sent)];
      msg->seq = sent;
      msg->epoch = epoch;
      msg->source_id = a.source_id;
      msg->utime = NowMicros();
    } else {
      auto next = (*source)->Next();
      if (!next.ok()) {
        if (progress) std::fprintf(stderr, "\n");
        std::fprintf(stderr, "vdeform-capture: error: frame %lld: %s\n", static_cast<long long>(sent),
                     next.status().ToString().c_str());
        rc = 1;
        break;
      }
      if (!next->has_value()) break;
      RgbdFrame& frame = **next;
      frame.seq = sent;
      frame.epoch = epoch;
      frame.source_id = a.source_id;
      frame.utime = NowMicros();
      msg = FrameToMessage(frame, a.encode);
    }
    if (msg.ok() && !a.frame_key.empty()) {
      const Status signed_ok = SignFrame(a.frame_key, &*msg);
      if (!signed_ok.ok()) msg = signed_ok;
    }
    if (!msg.ok()) {
      if (progress) std::fprintf(stderr, "\n");
      std::fprintf(stderr, "vdeform-capture: error: encoding frame %lld: %s\n", static_cast<long long>(sent),
                   msg.status().ToString().c_str());
      rc = 1;
      break;
    }
    const int64_t published_before = (*pacer)->stats().published;
    const Status s = (*pacer)->Send(*msg);
    if (!s.ok()) {
      if (progress) std::fprintf(stderr, "\n");
      std::fprintf(stderr, "vdeform-capture: error: %s\n", s.ToString().c_str());
      rc = 1;
      break;
    }
    // A stop request during the rate wait returns before publishing.
    if ((*pacer)->stats().published == published_before) break;
    ++sent;
    bytes += msg->getEncodedSize();
    const auto now = std::chrono::steady_clock::now();
    if (progress && (now - last_progress > std::chrono::milliseconds(250) || sent == total)) {
      last_progress = now;
      const double elapsed = std::chrono::duration<double>(now - t0).count();
      std::fprintf(stderr, "\rvdeform-capture: %lld/%lld frames  %.1f fps  %.1f KB/frame   ",
                   static_cast<long long>(sent), static_cast<long long>(total), elapsed > 0 ? sent / elapsed : 0.0,
                   bytes / 1024.0 / static_cast<double>(sent));
      std::fflush(stderr);
    }
  }
  if (progress) std::fprintf(stderr, "\n");
  const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::fprintf(stderr,
               "vdeform-capture: sent %lld frames (%lld re-sent) in %.2f s (%.1f fps), mean %.1f KB/frame%s\n",
               static_cast<long long>(sent), static_cast<long long>((*pacer)->stats().resends), elapsed,
               elapsed > 0 ? sent / elapsed : 0.0, sent > 0 ? bytes / 1024.0 / static_cast<double>(sent) : 0.0,
               g_stop.load() ? ", stopped by signal" : "");
  if (!a.output_key.empty()) {
    const OutputRefusals& refused = (*pacer)->stats().status_refused;
    std::fprintf(stderr, "vdeform-capture: ignored %lld status messages not signed by the server (%s)\n",
                 static_cast<long long>(refused.total()), refused.ToString().c_str());
  }
  // Destroying the source stops a live sensor before we return.
  source->reset();
  return rc;
}

}  // namespace
}  // namespace vd

int main(int argc, char** argv) {
  vd::Args args;
  vd::FlagParser flags(vd::kUsage, vd::kEpilogue);
  vd::Bind(&flags, &args);
  if (auto exit_code = flags.ParseCommandLine(argc, argv, "vdeform-capture", [&] { return vd::Finish(flags, &args); }))
    return *exit_code;
  return vd::Run(args);
}
