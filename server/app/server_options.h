#pragma once
// Options of vdeform-server shared by the offline mode and the LCM node.
#include <string>

#include "core/engine.h"
#include "gate.h"
#include "vd/common/codecs.h"
#include "vd/common/flags.h"

namespace vd {

struct ServerOptions {
  // The engine's parameters, bound to their flags directly (EngineParams::Bind): one default, one
  // help text, validated once by Validate().
  EngineParams engine;
  // Offline mode: a source spec as for vdeform-capture --source; empty = run the LCM node.
  std::string input;
  std::string intrinsics;
  double depth_scale = 0;
  int64_t count = -1;
  int64_t start = 0;
  int64_t stride = 1;
  // synthetic: inputs: frames in one pass of the motion (0: the scene's own).
  int64_t synthetic_frames = 0;
  std::string save_dir;
  // Fixed-topology tracked mesh: the first frame's mesh (or --track-mesh-from's, canonical
  // coordinates) deformed into every frame, frame-%06d.tracked.ply with --save-dir.
  bool track_mesh = false;
  std::string track_mesh_from;
  bool tracks_mesh() const { return track_mesh || !track_mesh_from.empty(); }
  std::string stats_json;
  // OpenCL device: index or name substring; empty = first GPU, else first CPU device.
  std::string device;
  bool list_devices = false;
  // LCM node.
  std::string lcm_url;
  // Stream name (--stream): channels VDEFORM_<NAME>_FRAMES, _MESH, _STATUS, _CONTROL; empty: today's.
  std::string stream;
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
  // Frames only when signed under their source's key in this file (one key, or SOURCE_ID KEY lines).
  std::string frame_key_file;
  // Every mesh and status message signed under the key in this file (one line KEY), so viewers and
  // lockstep captures given it take only what this server sent; empty = the output goes unsigned.
  std::string output_key_file;
  // Draco speed of the published meshes (DracoOptions::speed; PublishedMeshDraco). 10, sequential connectivity, encodes
  // the tube's 27 k triangles in ~3.5 ms against 6-10 ms for edgebreaker (7), which also falls back
  // to sequential on about half of the marching-cubes meshes (non-manifold vertices): the output
  // thread shares the two cores with the solve, so the fast one is the default (live 30 Hz: 73-80
  // of 150 frames against 51-77, BENCHMARKS "Session 34"); 0-9 give ~2.4x smaller messages.
  int64_t draco_speed = 10;
  // What the gate lets through: frame size, sequence jumps (bound to flags by GateParams::Bind).
  GateParams gate;
  bool quiet = false;

  void Register(FlagParser* flags);
  // The engine's parameters and the server's own; called once after parsing.
  Status Validate() const;
  // Reads the key files and splits accept_sources; fails on an unreadable or weak key, naming the
  // file (and the line of a frame key file).
  StatusOr<GateOptions> ToGateOptions() const;
};

// --track-mesh / --track-mesh-from: turns on the engine's tracked mesh (reading the PLY); nothing
// when neither is given. Errors name the flag.
Status ApplyTrackMesh(const ServerOptions& options, Engine* engine);
// How a published mesh of `triangles` triangles is Draco-coded: at --draco-speed, except that a
// mesh over kSequentialMaxTriangles takes edgebreaker (speed at most 7) whatever the flag, so a
// room-scale mesh stays well inside the receivers' 4 MB buffers (sequential: ~10.6 bytes a
// triangle, 1.6 MB at the limit; edgebreaker ~4.3).
inline constexpr size_t kSequentialMaxTriangles = 150000;
DracoOptions PublishedMeshDraco(const ServerOptions& options, size_t triangles);
// DIR/frame-%06d.SUFFIX: the per-frame files --save-dir holds.
std::string FramePath(const std::string& dir, int64_t index, const char* suffix);

}  // namespace vd
