#pragma once
// Options of vdeform-server shared by the offline mode and the LCM node.
#include <string>

#include "core/engine.h"
#include "flags.h"
#include "gate.h"

namespace vd {

struct ServerOptions {
  // Offline mode: a source spec as for vdeform-capture --source; empty = run the LCM node.
  std::string input;
  std::string intrinsics;
  double depth_scale = 0;
  double voxel_size = 0.004;
  double min_depth = 0.2;
  double max_depth = 3.5;
  double max_grid_mb = 600.0;
  double volume_margin = 0.10;
  // ICP iterations per pyramid level, finest first ("10,5,4").
  std::string icp_iterations = "10,5,4";
  double icp_degeneracy = 5e-5;
  // Non-rigid solver (defaults from EngineParams / SolverParams).
  int64_t levels = SolverParams().levels;
  int64_t outer_iterations = EngineParams().nonrigid_outer_iterations;
  int64_t flip_flop_iterations = SolverParams().flip_flop_iterations;
  int64_t coarse_iterations = SolverParams().coarse_flip_flop_iterations;
  int64_t pcg_iterations = SolverParams().pcg_iterations;
  // Sparse colour features (E_sparse).
  bool no_sift = false;
  double w_sparse = FeatureParams().w_sparse;
  int64_t count = -1;
  int64_t start = 0;
  int64_t stride = 1;
  std::string save_dir;
  std::string stats_json;
  bool rigid_only = false;
  bool no_bilateral = false;
  // OpenCL device: index or name substring; empty = first GPU, else first CPU device.
  std::string device;
  bool list_devices = false;
  // LCM node.
  std::string lcm_url;
  std::string snapshot_dir = "snapshots";
  // Checkpoints (empty = none): written every checkpoint_interval seconds while the model changes,
  // on SAVE_SNAPSHOT and at shutdown; --resume continues from the newest valid one.
  std::string checkpoint_dir;
  double checkpoint_interval = 30.0;
  bool resume = false;
  // Security: frames only from these source ids (comma-separated; empty = any); control commands
  // that change state only with an HMAC under the key in this file.
  std::string accept_sources;
  std::string control_key_file;
  // Largest frame accepted, in pixels (checked before decoding).
  int64_t max_frame_pixels = GateOptions().max_frame_pixels;
  bool quiet = false;

  void Register(FlagParser* flags);
  // Fails on malformed --icp-iterations.
  StatusOr<EngineParams> ToEngineParams() const;
  // Reads the key file and splits accept_sources; fails on an unreadable or weak key.
  StatusOr<GateOptions> ToGateOptions() const;
};

}  // namespace vd
