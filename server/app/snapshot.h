#pragma once
// SAVE_SNAPSHOT's files: the live and canonical meshes as PLY and the model in the checkpoint
// format (versioned, SHA-256 of the contents, written atomically), so ReadCheckpoint reads a
// snapshot's model and a snapshot directory can be resumed from like a checkpoint directory.
#include <filesystem>
#include <string>

#include "core/checkpoint.h"
#include "vd/common/mesh.h"
#include "vd/common/status.h"

namespace vd {

// Files inside a snapshot directory; the model is kCheckpointFile (checkpoint.vdck).
inline constexpr const char* kSnapshotLiveFile = "live.ply";
inline constexpr const char* kSnapshotCanonicalFile = "canonical.ply";

// Keeps a relative snapshot name inside the snapshot directory: an empty or absolute name, or one
// with a ".." component, is refused.
StatusOr<std::filesystem::path> SnapshotPath(const std::string& dir, const std::string& name);

// Writes into `path` (created when missing) what is given: each of the meshes and the model may be
// null (nothing received yet, no model). Stops at the first failure, which names the file.
Status WriteSnapshot(const std::filesystem::path& path, const TriangleMesh* live, const TriangleMesh* canonical,
                     const EngineState* model);

}  // namespace vd
