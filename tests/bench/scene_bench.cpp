// The whole engine on a synthetic scene against its ground truth: surface error, drift, non-rigid
// displacement, per-stage ms, frames per second, active set size and device memory. Takes the
// server's engine flags (vdeform-server --help), so any setting can be measured the way it runs.
//   vd_scene_bench --scene tube [--voxel-size 0.004] [--frames 60] [--stride 1] [--rigid-only] ...
#include <cstdio>
#include <map>

#include "../engine/scene_eval.h"
#include "server_options.h"
#include "vd/common/log.h"

int main(int argc, char** argv) {
  vd::ServerOptions options;
  std::string scene = "tube";
  int64_t stride = 1, report_every = 0;
  bool verbose = false;
  vd::FlagParser flags("vd_scene_bench: the engine on a synthetic scene against ground truth.\n"
                       "  vd_scene_bench --scene NAME [engine flags as for vdeform-server]");
  options.Register(&flags);
  flags.Add("scene", &scene,
            "Synthetic scene: " + vd::SyntheticSceneList() + " (bend: the tube closing to 150 degrees and staying)");
  flags.Add("report-every", &report_every,
            "Long takes: surface error, drift and the canonical model's truth every N frames (0 = at the end only)");
  flags.Add("feed-stride", &stride, "Feed every n-th frame (fast motion)");
  flags.AddSwitch("verbose", &verbose, "One line per frame");
  std::string save_canonical;
  flags.Add("save-canonical", &save_canonical,
            "Write the last frame's canonical mesh here as a PLY coloured by each vertex's distance to the true "
            "first-frame surface: green 0, yellow 2.5 mm, red 5 mm and beyond",
            "FILE");
  if (auto exit_code = flags.ParseCommandLine(argc, argv, "vd_scene_bench", [&] { return options.Validate(); }))
    return *exit_code;
  vd::SetLogLevel(vd::LogLevel::kWarning);
  vd::test::SceneRun run;
  run.name = scene;
  run.params = options.engine;
  // --frames (the server's flag for synthetic: inputs): frames in one pass of the motion.
  run.num_frames = options.synthetic_frames > 0 ? int(options.synthetic_frames) : 60;
  run.report_every = int(std::max<int64_t>(0, report_every));
  run.track_mesh = options.track_mesh;
  run.save_canonical = save_canonical;
  run.stride = int(stride);
  run.verbose = verbose;
  run.device = options.device;
  auto e = vd::test::EvaluateScene(run);
  if (!e.ok()) {
    std::fprintf(stderr, "vd_scene_bench: %s\n", e.status().ToString().c_str());
    return 1;
  }
  char label[160];
  std::snprintf(label, sizeof label, "%s, %.1f mm, %s, %d frames (stride %d)", scene.c_str(),
                run.params.voxel_size * 1000, run.params.rigid_only ? "rigid-only" : "non-rigid", e->frames,
                run.stride);
  vd::test::PrintErrors(label, *e);
  std::printf("stages (mean ms):");
  for (int i = 0; i < vd::StageTimes::kCount; ++i) std::printf(" %s %.1f |", vd::StageTimes::kNames[i], e->stage_ms[i]);
  std::printf(" total %.1f ms = %.2f fps\n", e->total_ms, 1000.0 / std::max(1e-9, e->total_ms));
  std::printf("wall clock per frame (Engine::Process) %.1f ms = %.2f fps; CPU %.1f ms (%.2f cores busy)\n",
              e->process_wall_ms, 1000.0 / std::max(1e-9, e->process_wall_ms), e->process_cpu_ms,
              e->process_cpu_ms / std::max(1e-9, e->process_wall_ms));
  std::printf("features per frame (mean): %.0f detected, %.0f lifted, %.0f matches; detection + description %.1f ms "
              "(beside the frame's thread), matching %.2f ms, lifting %.2f ms\n",
              e->mean_features, e->mean_lifted, e->mean_matches, e->mean_extract_ms, e->mean_match_ms,
              e->mean_lift_ms);
  if (e->mean_bundle_links > 0)
    std::printf(
        "bundle adjustment per frame (mean): %.1f ms, %.0f links, %.0f nodes, disagreement %.2f -> %.2f voxels\n",
        e->mean_bundle_ms, e->mean_bundle_links, e->mean_bundle_nodes, e->mean_bundle_rms_before,
        e->mean_bundle_rms_after);
  std::printf(
      "active grid points (mean) %.0f, of them solved %.0f, OpenCL buffers peak %.1f MB, resident peak %.1f MB\n",
      e->mean_active_voxels, e->mean_solved_voxels, e->device_peak_bytes / 1e6, vd::PeakResidentBytes() / 1e6);
  // How often the field was found static and solved on fewer levels (EngineParams::static_levels).
  std::map<int, int> levels;
  for (int l : e->solver_levels) ++levels[l];
  std::printf("solver levels:");
  for (const auto& [l, frames] : levels) std::printf(" %d on %d frames;", l, frames);
  std::printf("\n");
  return 0;
}
