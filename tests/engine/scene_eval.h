#pragma once
// Runs a synthetic scene through the engine and measures it against ground truth:
//   surface error = mean distance from live-mesh vertices to the true surface of that frame;
//   drift = mean distance between each live vertex and the true position, in that frame, of the
//   material point its canonical vertex lies on;
//   non-rigid displacement = mean distance between each live vertex and its canonical vertex moved
//   by the estimated camera pose only.
// Free of gtest: the engine suites and the scene benchmark (tests/bench/scene_bench.cpp) share it.
#include <time.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "core/engine.h"
#include "ocl/ocl.h"
#include "vd/capture/synthetic.h"
#include "vd/common/codecs.h"

namespace vd::test {

// One row of a long take (SceneRun::report_every): the frames since the previous row.
struct TakeWindow {
  int last_frame = 0;
  // Mean surface error over the window's frames; drift at its last frame.
  double mean_surface_mm = 0, drift_mm = 0;
  // The canonical model's truth at the window's last frame: share of canonical vertices within
  // 5 mm of the true first-frame surface, and the 90th percentile of their distance to it.
  double canonical_within_5mm = 0, canonical_p90_mm = 0;
};

struct SceneErrors {
  double worst_surface_mm = 0, mean_surface_mm = 0, last_drift_mm = 0, last_nonrigid_mm = 0;
  // The canonical model's truth at the last frame (as in TakeWindow), and its vertex count there.
  double canonical_within_5mm = 0, canonical_p90_mm = 0;
  size_t canonical_vertices = 0;
  // With SceneRun::track_mesh: the tracked mesh's vertex count (constant) and the mean distance of
  // its vertices to their material points' true positions at the last frame.
  size_t tracked_vertices = 0;
  double tracked_mean_mm = 0, tracked_median_mm = 0, tracked_within_5mm = 0;
  // Rows every SceneRun::report_every frames (and at the last frame); empty when it is 0.
  std::vector<TakeWindow> windows;
  // Engine statistics over the processed frames: stage means (ms), frames, mean active set size.
  std::array<double, StageTimes::kCount> stage_ms{};
  double total_ms = 0;
  // Wall-clock ms per Engine::Process call (feature detection prefetched on another thread
  // competes for the same cores; this includes that contention).
  double process_wall_ms = 0;
  // CPU ms of the whole process (every thread: PoCL's, the feature thread) per Process call: over
  // process_wall_ms it says how many of the cores the frame kept busy (idle cores = host waits).
  double process_cpu_ms = 0;
  int frames = 0;
  double mean_active_voxels = 0;
  double mean_solved_voxels = 0;
  // Levels of the solver's hierarchy per processed frame (fewer while the field is static).
  std::vector<int> solver_levels;
  size_t device_peak_bytes = 0;
  // Whether the dense colour term ran at the end (on and the colour found registered).
  bool colour_term_active = false;
  // Sparse features per frame (means): detected, lifted, matches used; detection + description ms.
  double mean_features = 0, mean_lifted = 0, mean_matches = 0, mean_extract_ms = 0, mean_match_ms = 0,
         mean_lift_ms = 0;
  // Keyframe bundle adjustment per frame (means): ms, links, nodes, link disagreement before and
  // after (voxels).
  double mean_bundle_ms = 0, mean_bundle_links = 0, mean_bundle_nodes = 0, mean_bundle_rms_before = 0,
         mean_bundle_rms_after = 0;
};

struct SceneRun {
  std::string name;
  EngineParams params;
  // Frames of one pass of the motion, and which of them are fed (every stride-th).
  int num_frames = 60;
  int stride = 1;
  // Print one line per frame.
  bool verbose = false;
  std::string device;
  // Long takes: a TakeWindow every this many frames (0 = none).
  int report_every = 0;
  // Track the first frame's mesh (Engine::TrackMesh) and measure it at the last frame.
  bool track_mesh = false;
  // Where to write the last frame's canonical mesh as a PLY coloured by each vertex's distance to
  // the true first-frame surface (empty: not written); see CanonicalErrorColours.
  std::string save_canonical;
};

inline Eigen::Vector3f V(const TriangleMesh& m, size_t i) {
  return Eigen::Vector3f(m.positions[3 * i], m.positions[3 * i + 1], m.positions[3 * i + 2]);
}

// Share of the canonical vertices within 5 mm of the true first-frame surface, and the 90th
// percentile of their distances (mm).
inline void CanonicalTruth(const TriangleMesh& canonical, const MeshDistance& gt0, double* within_5mm,
                           double* p90_mm) {
  std::vector<float> d(canonical.num_vertices());
  size_t within = 0;
  for (size_t i = 0; i < d.size(); ++i) {
    d[i] = 1000.f * gt0.Closest(V(canonical, i)).distance;
    within += d[i] <= 5.f;
  }
  *within_5mm = d.empty() ? 0.0 : double(within) / double(d.size());
  *p90_mm = 0;
  if (d.empty()) return;
  const size_t k = std::min(d.size() - 1, size_t(0.9 * double(d.size())));
  std::nth_element(d.begin(), d.begin() + long(k), d.end());
  *p90_mm = d[k];
}

// Colours a canonical mesh by each vertex's distance to the true first-frame surface: green at 0,
// yellow at 2.5 mm, red at 5 mm and beyond (the canonical-truth bound), so a viewer of the PLY sees
// where wrong geometry grows.
inline void CanonicalErrorColours(TriangleMesh* canonical, const MeshDistance& gt0) {
  canonical->colors.resize(3 * canonical->num_vertices());
  for (size_t i = 0; i < canonical->num_vertices(); ++i) {
    const float t = std::min(1.f, 1000.f * gt0.Closest(V(*canonical, i)).distance / 5.f);
    canonical->colors[3 * i + 0] = uint8_t(255.f * std::min(1.f, 2.f * t));
    canonical->colors[3 * i + 1] = uint8_t(255.f * std::min(1.f, 2.f - 2.f * t));
    canonical->colors[3 * i + 2] = 0;
  }
}

inline double ProcessCpuMs() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return 1e3 * double(ts.tv_sec) + 1e-6 * double(ts.tv_nsec);
}

inline StatusOr<SceneErrors> EvaluateScene(const SceneRun& run) {
  SceneErrors out;
  SyntheticOptions so;
  so.noise = true;
  so.num_frames = run.num_frames;
  VD_ASSIGN_OR_RETURN(auto scene, MakeSyntheticScene(run.name, so));
  VD_ASSIGN_OR_RETURN(auto engine, Engine::Create(run.params, run.device));
  if (run.track_mesh) VD_RETURN_IF_ERROR(engine->TrackMesh());
  TriangleMesh first_canonical;
  const MeshDistance gt0(scene->GroundTruthMesh(0));
  double sum_surface = 0, sum_active = 0, sum_solved = 0, window_surface = 0;
  int window_frames = 0;
  int last = 0;
  const int step = std::max(1, run.stride);
  for (int k = 0; k < run.num_frames; k += step) last = k;
  RgbdFrame next = scene->Render(0);
  for (int k = 0; k < run.num_frames; k += step) {
    const RgbdFrame frame = next;
    // The next frame's features are detected while this one is solved, as the server does.
    if (k + step < run.num_frames) {
      next = scene->Render(k + step);
      engine->Prefetch(next);
    }
    const auto t0 = std::chrono::steady_clock::now();
    const double cpu0 = ProcessCpuMs();
    VD_ASSIGN_OR_RETURN(FrameResult r, engine->Process(frame));
    out.process_wall_ms += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    out.process_cpu_ms += ProcessCpuMs() - cpu0;
    out.mean_features += r.features_detected;
    out.mean_lifted += r.features_lifted;
    out.mean_matches += r.sparse_matches;
    out.mean_extract_ms += r.feature_extract_ms;
    out.mean_match_ms += r.feature_match_ms;
    out.mean_lift_ms += r.feature_lift_ms;
    out.mean_bundle_ms += r.bundle_ms;
    out.mean_bundle_links += r.bundle.links;
    out.mean_bundle_nodes += r.bundle.nodes;
    out.mean_bundle_rms_before += r.bundle.rms_before;
    out.mean_bundle_rms_after += r.bundle.rms_after;
    const TriangleMesh gt = scene->GroundTruthMesh(k);
    const MeshDistance dist(gt);
    double s = 0;
    for (size_t i = 0; i < r.live_mesh.num_vertices(); ++i) s += dist.Closest(V(r.live_mesh, i)).distance;
    const double surface_mm = 1000 * s / std::max<size_t>(1, r.live_mesh.num_vertices());
    out.worst_surface_mm = std::max(out.worst_surface_mm, surface_mm);
    sum_surface += surface_mm;
    window_surface += surface_mm;
    ++window_frames;
    ++out.frames;
    for (int i = 0; i < StageTimes::kCount; ++i) {
      out.stage_ms[i] += r.times.ms[i];
      out.total_ms += r.times.ms[i];
    }
    sum_active += double(r.active_voxels);
    sum_solved += double(r.solved_voxels);
    out.solver_levels.push_back(r.solver_levels);
    if (run.track_mesh && out.frames == 1) first_canonical = r.canonical_mesh;
    if (run.track_mesh && k == last) {
      // Each tracked vertex's material point (its closest point on frame 0's true surface), where
      // it really is now (the ground truth is in this frame's camera), against where the tracked
      // mesh put it.
      const TriangleMesh& t = r.tracked_mesh;
      std::vector<float> d;
      for (size_t i = 0; i < t.num_vertices() && i < first_canonical.num_vertices(); ++i) {
        const Eigen::Vector3f truth = MeshDistance::Evaluate(gt, gt0.Closest(V(first_canonical, i)).where);
        d.push_back(1000.f * (truth - V(t, i)).norm());
      }
      out.tracked_vertices = t.num_vertices();
      if (!d.empty()) {
        double sum = 0;
        size_t within = 0;
        for (float v : d) {
          sum += v;
          within += v <= 5.f;
        }
        out.tracked_mean_mm = sum / double(d.size());
        out.tracked_within_5mm = double(within) / double(d.size());
        std::nth_element(d.begin(), d.begin() + long(d.size() / 2), d.end());
        out.tracked_median_mm = d[d.size() / 2];
      }
    }
    if (run.verbose) {
      std::printf("frame %3d: surface %.2f mm, %zu vertices, %lld active, E %.4g -> %.4g, %d constraints, features "
                  "%d/%d lifted, %d matches\n",
                  k, surface_mm, r.live_mesh.num_vertices(), static_cast<long long>(r.active_voxels), r.energy_initial,
                  r.energy_final, r.dense_correspondences, r.features_lifted, r.features_detected, r.sparse_matches);
      std::printf("frame %3d: pose t (%.1f, %.1f, %.1f) mm vs true (%.1f, %.1f, %.1f) mm, ICP %d inliers\n", k,
                  1000 * r.pose(0, 3), 1000 * r.pose(1, 3), 1000 * r.pose(2, 3), 1000 * scene->CameraPose(k)(0, 3),
                  1000 * scene->CameraPose(k)(1, 3), 1000 * scene->CameraPose(k)(2, 3), r.icp_inliers);
      if (!r.tracking_ok) std::printf("frame %3d: tracking failed: %s\n", k, r.tracking_message.c_str());
    }
    const bool report = run.report_every > 0 && (k % run.report_every == run.report_every - 1 || k == last);
    if (k == last || report || (run.verbose && k % 10 == 0)) {
      // Drift: canonical vertex -> material point on frame 0's true surface -> its true position now.
      double d = 0, nr = 0;
      const Eigen::Matrix4f cam_from_world = r.pose.inverse().cast<float>();
      for (size_t i = 0; i < r.live_mesh.num_vertices(); ++i) {
        const ClosestPoint c = gt0.Closest(V(r.canonical_mesh, i));
        const Eigen::Vector3f truth_k = MeshDistance::Evaluate(gt, c.where);
        d += (truth_k - V(r.live_mesh, i)).norm();
        // Non-rigid displacement: live vertex vs its canonical vertex moved rigidly by the pose.
        const Eigen::Vector3f rigid = (cam_from_world * V(r.canonical_mesh, i).homogeneous()).head<3>();
        nr += (rigid - V(r.live_mesh, i)).norm();
      }
      out.last_drift_mm = 1000 * d / std::max<size_t>(1, r.live_mesh.num_vertices());
      out.last_nonrigid_mm = 1000 * nr / std::max<size_t>(1, r.live_mesh.num_vertices());
      if (run.verbose)
        std::printf("frame %3d: drift %.2f mm, mean non-rigid displacement %.2f mm\n", k, out.last_drift_mm,
                    out.last_nonrigid_mm);
      if (report || k == last)
        CanonicalTruth(r.canonical_mesh, gt0, &out.canonical_within_5mm, &out.canonical_p90_mm);
      if (k == last) out.canonical_vertices = r.canonical_mesh.num_vertices();
      if (k == last && !run.save_canonical.empty()) {
        TriangleMesh coloured = r.canonical_mesh;
        CanonicalErrorColours(&coloured, gt0);
        VD_RETURN_IF_ERROR(WritePly(run.save_canonical, coloured).WithContext("--save-canonical"));
      }
      if (report) {
        TakeWindow w;
        w.last_frame = k;
        w.mean_surface_mm = window_surface / std::max(1, window_frames);
        w.drift_mm = out.last_drift_mm;
        w.canonical_within_5mm = out.canonical_within_5mm;
        w.canonical_p90_mm = out.canonical_p90_mm;
        out.windows.push_back(w);
        window_surface = 0;
        window_frames = 0;
        if (run.verbose)
          std::printf("frames to %3d: surface %.2f mm, drift %.2f mm, canonical within 5 mm %.1f %%, p90 %.2f mm\n", k,
                      w.mean_surface_mm, w.drift_mm, 100 * w.canonical_within_5mm, w.canonical_p90_mm);
      }
    }
  }
  const int n = std::max(1, out.frames);
  out.mean_surface_mm = sum_surface / n;
  out.mean_active_voxels = sum_active / n;
  out.mean_solved_voxels = sum_solved / n;
  out.mean_features /= n;
  out.mean_lifted /= n;
  out.mean_matches /= n;
  out.mean_extract_ms /= n;
  out.mean_match_ms /= n;
  out.mean_lift_ms /= n;
  for (double* v : {&out.mean_bundle_ms, &out.mean_bundle_links, &out.mean_bundle_nodes, &out.mean_bundle_rms_before,
                    &out.mean_bundle_rms_after})
    *v /= n;
  for (double& v : out.stage_ms) v /= n;
  out.total_ms /= n;
  out.process_wall_ms /= n;
  out.process_cpu_ms /= n;
  out.device_peak_bytes = engine->device_peak_bytes();
  out.colour_term_active = engine->colour_term_active();
  return out;
}

inline void PrintErrors(const std::string& label, const SceneErrors& e) {
  std::printf("%s: surface error mean %.2f mm, worst frame %.2f mm; last frame drift %.2f mm, mean non-rigid "
              "displacement %.2f mm\n",
              label.c_str(), e.mean_surface_mm, e.worst_surface_mm, e.last_drift_mm, e.last_nonrigid_mm);
  std::printf("%s: canonical model at the last frame: %.1f %% of vertices within 5 mm of the true surface, p90 %.2f "
              "mm\n",
              label.c_str(), 100 * e.canonical_within_5mm, e.canonical_p90_mm);
  if (e.tracked_vertices > 0)
    std::printf("%s: tracked mesh (%zu vertices) at the last frame: mean %.2f mm, median %.2f mm from the true "
                "positions, %.1f %% within 5 mm\n",
                label.c_str(), e.tracked_vertices, e.tracked_mean_mm, e.tracked_median_mm, 100 * e.tracked_within_5mm);
  for (const TakeWindow& w : e.windows)
    std::printf("  frames to %4d: surface %.2f mm, drift %.2f mm, canonical within 5 mm %5.1f %%, p90 %.2f mm\n",
                w.last_frame, w.mean_surface_mm, w.drift_mm, 100 * w.canonical_within_5mm, w.canonical_p90_mm);
}

// The engine suites' defaults: sensor noise, 4 mm voxels, 60 frames, default parameters.
inline SceneErrors RunScene(const std::string& name, bool rigid_only, int stride = 1) {
  SceneRun run;
  run.name = name;
  run.params.rigid_only = rigid_only;
  run.stride = stride;
  auto e = EvaluateScene(run);
  if (!e.ok()) {
    std::fprintf(stderr, "%s: %s\n", name.c_str(), e.status().ToString().c_str());
    SceneErrors failed;
    failed.worst_surface_mm = failed.mean_surface_mm = failed.last_drift_mm = failed.last_nonrigid_mm = 1e9;
    return failed;
  }
  PrintErrors(name + (rigid_only ? " (rigid-only)" : " (non-rigid)"), *e);
  return *e;
}

inline bool HaveDevice() {
  auto d = ocl::ListDevices();
  return d.ok() && !d->empty();
}

}  // namespace vd::test
