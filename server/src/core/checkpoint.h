#pragma once
// Checkpoints: everything needed to continue a model in a new process (the canonical volume, the
// deformation field, the camera pose and intrinsics, the feature history, the tracked mesh), written atomically
// (temporary file, fsync, rename; the previous checkpoint kept beside it) with a SHA-256 of the
// contents, so a torn or corrupt file is detected and reported, never loaded. Untouched 8^3
// bricks (the reset values throughout) are not stored: a checkpoint is the size of the surface.
#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "core/features.h"
#include "shared/vd_types.h"
#include "vd/common/mesh.h"
#include "vd/common/status.h"

namespace vd {

// Host copy of an engine's model.
struct EngineState {
  VdVolume vol{};
  bool has_deformation = false;
  // A sparse volume (--sparse-volume): vol gives voxel size, truncation and weight cap only (no
  // box), brick_keys the key of each pool slot in slot order, and tsdf, weight and colour 512
  // voxels per slot in the same order, so a restored pool has every brick in its old slot.
  bool sparse = false;
  std::vector<uint32_t> brick_keys;
  std::vector<float> tsdf, weight;
  std::vector<uint32_t> color;
  std::vector<vd_float4> def_pos, def_rot;
  Eigen::Matrix4d pose = Eigen::Matrix4d::Identity();
  VdCamera cam{};
  int64_t frames_fused = 0;
  int64_t frames_seen = 0;
  std::vector<FrameFeatures> history;
  std::vector<int> keyframes;
  // Matched pairs of stored features (the bundle adjustment's links).
  std::vector<FeatureLink> links;
  // The fixed-topology tracked mesh (--track-mesh) in canonical world metres, once fixed (the
  // first frame's canonical mesh or the given one): positions, colours (empty or 3 per vertex) and
  // faces, so a resumed run goes on deforming the same vertices. Empty when not tracking.
  TriangleMesh tracked;
  // The colour's registration as measured (core/colour_registration.h: 0 undecided, 1 registered,
  // 2 not registered), so a resumed model runs the dense colour term as before without measuring
  // again on the frames after the resume. Version 6 on; older checkpoints read 0 (measured again).
  uint8_t colour_registration = 0;
  // Sequence number and source of the last frame fused (for the log and the status).
  int64_t last_seq = -1;
  std::string source_id;

  size_t num_voxels() const { return size_t(vol.dim_x) * vol.dim_y * vol.dim_z; }
  // Sizes consistent with vol, finite pose, history indices in range.
  Status Validate() const;
};

// The serialised form (header + SHA-256 + payload).
std::string EncodeCheckpoint(const EngineState& state);
// Refuses wrong magic, a size other than the header says (torn), a digest mismatch (corrupt), and
// any field out of range; never returns a partial state.
StatusOr<EngineState> DecodeCheckpoint(const std::string& bytes);

// File names inside a checkpoint directory.
inline constexpr const char* kCheckpointFile = "checkpoint.vdck";
inline constexpr const char* kPreviousCheckpointFile = "checkpoint.prev.vdck";

// Writes `path` so that a reader never sees a partial file: `write` fills path.tmp, which is synced
// and renamed over `path`; when `previous` is given, the file at `path` is first renamed to it.
Status WriteFileAtomically(const std::filesystem::path& path, const std::function<void(std::ostream&)>& write,
                           const std::filesystem::path& previous = {});

// Writes dir/checkpoint.vdck atomically, keeping the one before as checkpoint.prev.vdck.
// bytes_written receives the file size when not null.
Status WriteCheckpoint(const std::string& dir, const EngineState& state, size_t* bytes_written = nullptr);
StatusOr<EngineState> ReadCheckpoint(const std::string& path);

struct ResumeResult {
  std::optional<EngineState> state;
  // Which file was loaded, and one line per file refused (torn, corrupt, unreadable).
  std::string loaded_path;
  std::vector<std::string> problems;
};
// The newest valid checkpoint in dir: checkpoint.vdck, else checkpoint.prev.vdck. A refused file
// is renamed to <name>.corrupt-<utime> (kept for inspection, never overwritten or loaded again).
ResumeResult LoadLatestCheckpoint(const std::string& dir);

}  // namespace vd
