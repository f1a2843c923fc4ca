// The engine on a recorded room (7-Scenes layout: frame-%06d.{color.png,depth.png,pose.txt}) against
// its ground-truth poses: trajectory error, frames lost, frame time, and device memory set against a
// dense grid over the same extent (issue 17's room-scale targets). Takes the server's flags, so any
// setting can be measured the way it runs.
//   vd_room_bench --input folder:../shared/data/7scenes_redkitchen --count 300 --voxel-size 0.01
//                 [--rigid-only] [--sparse-volume] [engine flags as for vdeform-server]
#include <csignal>
#include <cstdio>
#include <limits>

#include "../engine/trajectory_error.h"
#include "core/engine.h"
#include "offline.h"
#include "server_options.h"
#include "vd/common/log.h"

namespace {

volatile std::sig_atomic_t g_stop = 0;
void OnSignal(int) { g_stop = 1; }

// "folder:DIR" -> "DIR" (the ground truth lies beside the frames); empty for other sources.
std::string FolderOf(const std::string& input) {
  const std::string prefix = "folder:";
  return input.compare(0, prefix.size(), prefix) == 0 ? input.substr(prefix.size()) : std::string();
}

}  // namespace

int main(int argc, char** argv) {
  vd::ServerOptions options;
  std::string gt_dir;
  vd::FlagParser flags(
      "vd_room_bench: the engine on a recorded room against its ground-truth poses (ATE, frames lost, ms a frame,\n"
      "device memory against a dense grid over the same extent).\n"
      "  vd_room_bench --input folder:DIR [--count N] [engine flags as for vdeform-server]");
  options.Register(&flags);
  flags.Add("gt-dir", &gt_dir,
            "Folder of the ground-truth frame-%06d.pose.txt files (default: the --input folder); a frame's pose is "
            "read by its index in the data set, so --start and --stride are followed",
            "DIR");
  if (auto exit_code = flags.ParseCommandLine(argc, argv, "vd_room_bench", [&] { return options.Validate(); }))
    return *exit_code;
  if (gt_dir.empty()) gt_dir = FolderOf(options.input);
  if (gt_dir.empty()) {
    std::fprintf(stderr, "vd_room_bench: --input must be folder:DIR (or give --gt-dir)\n");
    return 2;
  }
  vd::SetLogLevel(vd::LogLevel::kWarning);
  const vd::SourceOptions source_options = vd::ToSourceOptions(options);
  auto source = vd::OpenSource(options.input, source_options);
  if (!source.ok()) {
    std::fprintf(stderr, "vd_room_bench: %s\n", source.status().ToString().c_str());
    return 1;
  }
  auto engine = vd::Engine::Create(options.engine, options.device);
  if (!engine.ok()) {
    std::fprintf(stderr, "vd_room_bench: %s\n", engine.status().ToString().c_str());
    return 1;
  }
  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);

  char path[4096];
  auto pose_path = [&](int64_t index) {
    std::snprintf(path, sizeof path, "%s/frame-%06lld.pose.txt", gt_dir.c_str(), static_cast<long long>(index));
    return std::string(path);
  };
  Eigen::Matrix4d gt0 = Eigen::Matrix4d::Identity();
  if (!vd::test::ReadPoseFile(pose_path(options.start), &gt0)) {
    std::fprintf(stderr, "vd_room_bench: no ground-truth pose %s\n", path);
    return 1;
  }
  const Eigen::Matrix4d gt0_inv = gt0.inverse();
  std::vector<Eigen::Vector3d> est, gt;
  int64_t frames = 0, lost = 0, bricks_used = 0, bricks_failed = 0, evicted = 0;
  double ms = 0;
  vd::TriangleMesh canonical;
  while (!g_stop) {
    auto next = (*source)->Next();
    if (!next.ok()) {
      std::fprintf(stderr, "vd_room_bench: %s\n", next.status().ToString().c_str());
      return 1;
    }
    if (!next->has_value()) break;
    const int64_t index = vd::SourceFrameIndex(source_options, frames);
    Eigen::Matrix4d truth;
    if (!vd::test::ReadPoseFile(pose_path(index), &truth)) {
      std::fprintf(stderr, "vd_room_bench: no ground-truth pose %s\n", path);
      return 1;
    }
    auto r = (*engine)->Process(**next);
    if (!r.ok()) {
      std::fprintf(stderr, "vd_room_bench: frame %lld: %s\n", static_cast<long long>(index),
                   r.status().ToString().c_str());
      return 1;
    }
    ms += r->times.Total();
    lost += !r->tracking_ok;
    est.push_back(r->pose.topRightCorner<3, 1>());
    gt.push_back((gt0_inv * truth).topRightCorner<3, 1>());
    bricks_used = r->bricks_used;
    bricks_failed += r->bricks_failed;
    evicted = r->bricks_evicted_total;
    canonical = std::move(r->canonical_mesh);
    ++frames;
    std::fprintf(stderr, "\rframe %lld  %.0f ms  lost %lld  bricks %lld   ", static_cast<long long>(frames),
                 r->times.Total(), static_cast<long long>(lost), static_cast<long long>(bricks_used));
  }
  std::fprintf(stderr, "\n");
  if (frames == 0) {
    std::fprintf(stderr, "vd_room_bench: no frames\n");
    return 1;
  }
  const vd::test::TrajectoryError ate = vd::test::ComputeTrajectoryError(est, gt);
  const auto& p = options.engine;
  std::printf("%s, %.1f mm, %s%s: %lld frames%s, tracking lost on %lld\n", options.input.c_str(), p.voxel_size * 1000,
              p.rigid_only ? "rigid-only" : "non-rigid", p.sparse_volume ? ", sparse volume" : "",
              static_cast<long long>(frames), g_stop ? " (interrupted)" : "", static_cast<long long>(lost));
  std::printf("ATE RMSE %.1f mm aligned (standard), %.1f mm anchored at the first frame (worst %.1f mm)\n",
              ate.aligned * 1000, ate.anchored * 1000, ate.worst * 1000);
  std::printf("stage sum %.1f ms a frame = %.2f fps\n", ms / frames, 1000.0 * frames / std::max(1e-9, ms));
  // The extent the model covers: the last canonical mesh's box (world metres), as grid points.
  Eigen::Array3d lo = Eigen::Array3d::Constant(std::numeric_limits<double>::max()), hi = -lo;
  for (size_t i = 0; i < canonical.num_vertices(); ++i) {
    const Eigen::Array3d v(canonical.positions[3 * i], canonical.positions[3 * i + 1], canonical.positions[3 * i + 2]);
    lo = lo.min(v);
    hi = hi.max(v);
  }
  const bool with_field = !p.rigid_only;
  std::printf("OpenCL buffers peak %.1f MB\n", (*engine)->device_peak_bytes() / 1e6);
  if (canonical.num_vertices() > 0) {
    const Eigen::Array3d points = ((hi - lo) / p.voxel_size).floor() + 1;
    const double dense_bytes = points.prod() * vd::DenseGridPointBytes(with_field);
    std::printf(
        "canonical extent %.2f x %.2f x %.2f m: a dense grid over it needs %.1f MB (%.0f points of %.0f bytes)\n",
        hi.x() - lo.x(), hi.y() - lo.y(), hi.z() - lo.z(), dense_bytes / 1e6, points.prod(),
        vd::DenseGridPointBytes(with_field));
    if (p.sparse_volume) {
      const double pool_bytes = bricks_used * vd::SparseBrickBytes(with_field);
      std::printf(
          "bricks: %lld in use, %.1f MB of pool data (%.1f %% of the dense grid over the extent); %lld not "
          "fused for want of room, %lld dropped\n",
          static_cast<long long>(bricks_used), pool_bytes / 1e6, 100.0 * pool_bytes / dense_bytes,
          static_cast<long long>(bricks_failed), static_cast<long long>(evicted));
    }
  }
  return 0;
}
