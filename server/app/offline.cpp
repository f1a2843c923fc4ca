// Offline mode: the same engine over a data set or synthetic source, without LCM.
#include <unistd.h>

#include <atomic>
#include <condition_variable>
#include <mutex>
#include <optional>
#include <thread>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "offline.h"
#include "stats.h"
#include "vd/common/codecs.h"
#include "vd/common/log.h"

namespace vd {
namespace {

std::atomic<bool> g_stop{false};
void OnSignal(int) { g_stop = true; }

Status WritePose(const std::string& path, const Eigen::Matrix4d& T) {
  std::ofstream out(path);
  if (!out) return Unavailable("cannot write '" + path + "'");
  out.setf(std::ios::scientific);
  out.precision(9);
  for (int r = 0; r < 4; ++r) out << T(r, 0) << " " << T(r, 1) << " " << T(r, 2) << " " << T(r, 3) << "\n";
  return out ? Status::Ok() : Unavailable("write failed for '" + path + "'");
}

// Reads the source on its own thread, one frame ahead of the engine: frame k+1 is decoded and its
// features detected (Engine::Prefetch) while frame k is solved. Frames come out in source order,
// each exactly once; the source is only ever touched by the reader thread.
class FrameReader {
 public:
  FrameReader(FrameSource* source, Engine* engine) : source_(source), engine_(engine), thread_([this] { Loop(); }) {}
  ~FrameReader() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    cv_.notify_all();
    thread_.join();
  }
  // The next frame (std::nullopt at the end), or the read error; blocks until it is read.
  StatusOr<std::optional<RgbdFrame>> Next() {
    std::unique_lock<std::mutex> lock(mutex_);
    cv_.wait(lock, [this] { return slot_.has_value(); });
    StatusOr<std::optional<RgbdFrame>> out = std::move(*slot_);
    slot_.reset();
    cv_.notify_all();
    return out;
  }

 private:
  void Loop() {
    for (;;) {
      StatusOr<std::optional<RgbdFrame>> next = source_->Next();
      const bool last = !next.ok() || !next->has_value();
      if (!last) engine_->Prefetch(**next);
      std::unique_lock<std::mutex> lock(mutex_);
      cv_.wait(lock, [this] { return stop_ || !slot_.has_value(); });
      if (stop_) return;
      slot_ = std::move(next);
      cv_.notify_all();
      if (last) return;
    }
  }

  FrameSource* source_;
  Engine* engine_;
  std::mutex mutex_;
  std::condition_variable cv_;
  // The frame read ahead, waiting for Next(); empty while the reader reads.
  std::optional<StatusOr<std::optional<RgbdFrame>>> slot_;
  bool stop_ = false;
  // Declared last: it starts reading as soon as the members above exist.
  std::thread thread_;
};

}  // namespace

SourceOptions ToSourceOptions(const ServerOptions& options) {
  SourceOptions s;
  s.intrinsics = options.intrinsics;
  s.depth_scale = float(options.depth_scale);
  s.start = options.start;
  s.count = options.count;
  s.stride = int(options.stride);
  s.synthetic_frames = options.synthetic_frames;
  return s;
}

int64_t SourceFrameIndex(const SourceOptions& options, int64_t delivered) {
  return options.start + delivered * options.stride;
}

int RunOffline(const ServerOptions& options) {
  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  auto fail = [](const Status& s) {
    std::fprintf(stderr, "vdeform-server: %s\n", s.ToString().c_str());
    return 1;
  };
  const SourceOptions source_options = ToSourceOptions(options);
  if (Status s = source_options.Validate(); !s.ok()) return fail(s);
  auto source = OpenSource(options.input, source_options);
  if (!source.ok()) return fail(source.status());
  VD_LOG_INFO << "input: " << (*source)->Describe();
  if (!options.save_dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(options.save_dir, ec);
    if (ec) return fail(Unavailable("cannot create --save-dir '" + options.save_dir + "': " + ec.message()));
  }
  auto engine = Engine::Create(options.engine, options.device);
  if (!engine.ok()) return fail(engine.status());
  VD_LOG_INFO << "OpenCL device: " << (*engine)->DeviceDescription();
  if (Status s = ApplyTrackMesh(options, engine->get()); !s.ok()) return fail(s);

  StageStats stats;
  const int64_t total = (*source)->NumFrames();
  const bool tty = isatty(fileno(stderr));
  int64_t processed = 0, lost = 0;
  // Frames taken from the source so far; names the output files by their index in the source.
  int64_t delivered = 0;
  const auto t_start = std::chrono::steady_clock::now();
  FrameReader reader(source->get(), engine->get());
  while (!g_stop) {
    auto next = reader.Next();
    if (!next.ok()) {
      const int64_t index = SourceFrameIndex(source_options, delivered);
      return fail(next.status().WithContext("reading frame " + std::to_string(index)));
    }
    if (!next->has_value()) break;
    const RgbdFrame frame = std::move(**next);
    const int64_t index = SourceFrameIndex(source_options, delivered++);
    const auto t0 = std::chrono::steady_clock::now();
    auto result = (*engine)->Process(frame);
    if (!result.ok()) return fail(result.status().WithContext("frame " + std::to_string(frame.seq)));
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    stats.Add(result->times, ms);
    if (!result->tracking_ok) {
      ++lost;
      VD_LOG_WARNING << "frame " << index << ": " << result->tracking_message;
    }
    if (!options.save_dir.empty()) {
      Status s = WritePly(FramePath(options.save_dir, index, "mesh.ply"), result->live_mesh);
      if (s.ok()) s = WritePly(FramePath(options.save_dir, index, "canonical.ply"), result->canonical_mesh);
      if (s.ok()) s = WritePose(FramePath(options.save_dir, index, "pose.txt"), result->pose);
      if (s.ok() && !result->tracked_mesh.triangles.empty())
        s = WritePly(FramePath(options.save_dir, index, "tracked.ply"), result->tracked_mesh);
      if (!s.ok()) return fail(s);
    }
    ++processed;
    if (!options.quiet) {
      char line[512];
      std::snprintf(line, sizeof(line), "frame %lld%s%s  %.1f ms  %zu triangles  icp inliers %d%s%s%s",
                    static_cast<long long>(processed), total > 0 ? "/" : "",
                    total > 0 ? std::to_string(total).c_str() : "", ms, result->live_mesh.num_triangles(),
                    result->icp_inliers, result->tracking_ok ? "" : "  LOST", result->bricks_pool > 0 ? "  " : "",
                    result->bricks_pool > 0 ? BrickPoolNote(*result).c_str() : "");
      std::fprintf(stderr, tty ? "\r%s\033[K" : "%s\n", line);
    }
  }
  if (!options.quiet && tty) std::fprintf(stderr, "\n");
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  const double fps = processed / std::max(secs, 1e-9);
  std::printf("processed %lld frames in %.1f s (%.2f fps), tracking lost on %lld\n", static_cast<long long>(processed),
              secs, fps, static_cast<long long>(lost));
  std::printf("stages (mean ms): %s\n", stats.Summary().c_str());
  std::printf("peak memory: %.1f MB resident, %.1f MB OpenCL buffers\n", PeakResidentBytes() / 1e6,
              (*engine)->device_peak_bytes() / 1e6);
  if (!options.stats_json.empty()) {
    std::ofstream out(options.stats_json);
    out << "{\"input\": \"" << options.input << "\", \"frames\": " << processed << ", \"tracking_lost\": " << lost
        << ", \"seconds\": " << secs << ", \"fps\": " << fps << ", \"voxel_size\": " << options.engine.voxel_size
        << ", \"peak_resident_bytes\": " << PeakResidentBytes()
        << ", \"peak_device_bytes\": " << (*engine)->device_peak_bytes() << ", \"device\": \""
        << (*engine)->DeviceDescription() << "\", \"stages\": " << stats.Json() << "}\n";
    if (!out) return fail(Unavailable("cannot write --stats-json '" + options.stats_json + "'"));
    std::printf("wrote %s\n", options.stats_json.c_str());
  }
  if (!options.save_dir.empty()) std::printf("wrote %lld frames to %s\n", static_cast<long long>(processed), options.save_dir.c_str());
  return g_stop ? 130 : 0;
}

}  // namespace vd
