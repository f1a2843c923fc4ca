#include "snapshot.h"

#include "vd/common/codecs.h"

namespace vd {

StatusOr<std::filesystem::path> SnapshotPath(const std::string& dir, const std::string& name) {
  if (name.empty()) return InvalidArgument("empty snapshot name");
  const std::filesystem::path rel(name);
  if (rel.is_absolute()) return InvalidArgument("snapshot path '" + name + "' is absolute");
  for (const auto& part : rel)
    if (part == "..") return InvalidArgument("snapshot path '" + name + "' leaves the snapshot directory");
  return std::filesystem::path(dir) / rel;
}

Status WriteSnapshot(const std::filesystem::path& path, const TriangleMesh* live, const TriangleMesh* canonical,
                     const EngineState* model) {
  std::error_code ec;
  std::filesystem::create_directories(path, ec);
  if (ec) return Unavailable("cannot create '" + path.string() + "': " + ec.message());
  if (live) VD_RETURN_IF_ERROR(WritePly((path / kSnapshotLiveFile).string(), *live));
  if (canonical) VD_RETURN_IF_ERROR(WritePly((path / kSnapshotCanonicalFile).string(), *canonical));
  // WriteCheckpoint validates the state and writes it atomically beside the meshes.
  if (model) VD_RETURN_IF_ERROR(WriteCheckpoint(path.string(), *model));
  return Status::Ok();
}

}  // namespace vd
