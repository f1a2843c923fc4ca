// vdeform-server's flags and their translation into engine and gate parameters.
#include "server_options.h"

#include <algorithm>
#include <cstdio>

namespace vd {

void ServerOptions::Register(FlagParser* f) {
  f->AddString("input", &input,
               "Offline mode: process SOURCE (openni2[:URI], oni:FILE, folder:DIR, synthetic:NAME) without LCM");
  f->AddString("intrinsics", &intrinsics, "fx,fy,cx,cy overriding the source's intrinsics (offline mode)");
  f->AddFloat("depth-scale", &depth_scale, "Raw depth units per metre overriding the source's (offline mode; 0 = source's)");
  f->AddFloat("voxel-size", &voxel_size, "Grid spacing in metres");
  f->AddFloat("min-depth", &min_depth, "Depth below this many metres is ignored");
  f->AddFloat("max-depth", &max_depth, "Depth beyond this many metres is ignored");
  f->AddFloat("max-grid-mb", &max_grid_mb,
              "Memory the grid may use, MB (12 bytes per point with --rigid-only, 44 with the deformation field)");
  f->AddFloat("volume-margin", &volume_margin,
              "Space added around the first frame's points when placing the grid, metres (larger for a moving "
              "camera that will see more of the scene)");
  f->AddString("icp-iterations", &icp_iterations, "Rigid ICP iterations per pyramid level, finest first");
  f->AddFloat("icp-degeneracy", &icp_degeneracy,
              "ICP information ratio below which a pose direction is held at the last pose (0 = off)");
  f->AddInt("levels", &levels, "Levels of the non-rigid solver's coarse-to-fine hierarchy (1 = fine grid only)");
  f->AddInt("outer-iterations", &outer_iterations,
            "Non-rigid outer iterations per frame (new correspondences each; 0 = rigid tracking with the field kept)");
  f->AddInt("flip-flop-iterations", &flip_flop_iterations, "Flip-flop iterations on the fine level per outer iteration");
  f->AddInt("coarse-iterations", &coarse_iterations, "Flip-flop iterations on each coarse level per outer iteration");
  f->AddInt("pcg-iterations", &pcg_iterations, "PCG iterations per position step (at most)");
  f->AddBool("no-sift", &no_sift,
             "Turn the sparse colour term off: no SIFT features, depth-only non-rigid tracking (for comparisons)");
  f->AddFloat("w-sparse", &w_sparse, "Weight of the sparse SIFT term E_sparse per match, relative to the dense term");
  f->AddInt("count", &count, "Offline mode: process at most N frames (-1 = all)");
  f->AddInt("start", &start, "Offline mode: first frame index");
  f->AddInt("stride", &stride, "Offline mode: use every n-th frame");
  f->AddString("save-dir", &save_dir,
               "Offline mode: write frame-%06d.mesh.ply (live, camera coordinates), frame-%06d.canonical.ply and "
               "frame-%06d.pose.txt (camera-to-world) per frame, numbered by the frame's index in the source "
               "(--start 3 --stride 2: 3, 5, 7, ...)");
  f->AddString("stats-json", &stats_json, "Offline mode: write per-stage timing statistics, fps and peak memory");
  f->AddBool("rigid-only", &rigid_only,
             "Rigid tracking and fusion only: no deformation field (12 instead of 44 bytes per grid point), no "
             "non-rigid solve");
  f->AddBool("no-bilateral", &no_bilateral, "Track on the unfiltered depth");
  f->AddString("device", &device, "OpenCL device: index (see --list-devices) or name substring; default first GPU, else CPU");
  f->AddBool("list-devices", &list_devices, "List the OpenCL devices and exit");
  f->AddString("lcm-url", &lcm_url, "LCM URL (default: $LCM_DEFAULT_URL, else host-only multicast with a 4 MB receive buffer)");
  f->AddString("snapshot-dir", &snapshot_dir, "Directory SAVE_SNAPSHOT commands write into (paths cannot leave it)");
  f->AddString("checkpoint", &checkpoint_dir,
               "Directory for checkpoints of the model (volume, deformation field, feature history), written "
               "atomically every --checkpoint-interval seconds, on SAVE_SNAPSHOT and at shutdown; empty = none");
  f->AddFloat("checkpoint-interval", &checkpoint_interval,
              "Seconds between periodic checkpoints while the model changes (0 = only on SAVE_SNAPSHOT and shutdown)");
  f->AddBool("resume", &resume,
             "Continue from the newest valid checkpoint in --checkpoint (a torn or corrupt one is reported, "
             "kept aside and never loaded)");
  f->AddString("accept-sources", &accept_sources,
               "Comma-separated source ids whose frames are accepted (empty = any); others are counted and ignored");
  f->AddString("control-key-file", &control_key_file,
               "File holding the HMAC-SHA256 key (>= 16 bytes, mode 600) that RESET and SAVE_SNAPSHOT commands must "
               "be signed with (vdeform-control --key-file); empty = control is not authenticated");
  f->AddInt("max-frame-pixels", &max_frame_pixels,
             "Frames declaring more pixels (width x height) are refused before decoding (0 = up to 8192 x 8192)");
  f->AddBool("quiet", &quiet, "Only warnings and errors");
}

StatusOr<EngineParams> ServerOptions::ToEngineParams() const {
  EngineParams p;
  int a = 0, b = 0, c = 0;
  char tail = 0;
  if (std::sscanf(icp_iterations.c_str(), "%d,%d,%d%c", &a, &b, &c, &tail) != 3)
    return InvalidArgument("--icp-iterations expects three counts like 10,5,4, got '" + icp_iterations + "'");
  p.icp_iterations = {a, b, c};
  p.icp_degeneracy = float(icp_degeneracy);
  p.voxel_size = float(voxel_size);
  p.solver.levels = int(levels);
  p.nonrigid_outer_iterations = int(outer_iterations);
  p.solver.flip_flop_iterations = int(flip_flop_iterations);
  p.solver.coarse_flip_flop_iterations = int(coarse_iterations);
  p.solver.pcg_iterations = int(pcg_iterations);
  p.features.enabled = !no_sift;
  p.features.w_sparse = float(w_sparse);
  p.min_depth = float(min_depth);
  p.max_depth = float(max_depth);
  p.max_grid_mb = max_grid_mb;
  p.volume_margin = float(volume_margin);
  p.rigid_only = rigid_only;
  p.bilateral = !no_bilateral;
  return p;
}

StatusOr<GateOptions> ServerOptions::ToGateOptions() const {
  GateOptions g;
  if (max_frame_pixels < 0) return InvalidArgument("--max-frame-pixels must be >= 0");
  g.max_frame_pixels = max_frame_pixels;
  size_t begin = 0;
  while (begin <= accept_sources.size() && !accept_sources.empty()) {
    const size_t end = std::min(accept_sources.find(',', begin), accept_sources.size());
    const std::string id = accept_sources.substr(begin, end - begin);
    if (id.empty()) return InvalidArgument("--accept-sources has an empty source id: '" + accept_sources + "'");
    g.accept_sources.push_back(id);
    begin = end + 1;
  }
  if (!control_key_file.empty()) {
    auto key = ReadControlKey(control_key_file);
    if (!key.ok()) return key.status();
    g.control_key = std::move(key).value();
  }
  return g;
}

}  // namespace vd
