#include "core/checkpoint.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <type_traits>

#include "shared/deformation.h"
#include "vd/common/auth.h"

namespace vd {
namespace {

constexpr char kMagic[8] = {'V', 'D', 'C', 'K', 'P', 'T', '0', '1'};
// 2: the tracked mesh after the keyframes. 3: the feature links after the tracked mesh. 4: a sparse
// flag after the deformation flag; a sparse volume stores its bricks by key where the dense grid
// stores its brick list. 5: a sparse volume may hold the deformation field (t_i and R_i after each
// voxel's colour). 6: the colour's registration verdict after the links. Version 1 to 5 files
// (no tracked mesh, no links, dense or rigid) are still read.
constexpr uint32_t kFormatVersion = 6;
constexpr size_t kBrickVoxels = 512;
// Bricks a sparse checkpoint may declare (2^28 is the most a brick table holds).
constexpr size_t kMaxBricks = size_t(1) << 28;
constexpr size_t kMaxTrackedVertices = size_t(1) << 24;
constexpr size_t kHeaderBytes = 8 + 8 + 32;
constexpr int kBrick = 8;
// Reset values of a grid point (DeviceOps::ResetVolume, vd_deformation_reset_row).
constexpr float kRestTsdf = 1.0f;
// Deformed positions within this of the rest position count as untouched (host and device may
// round origin + voxel_size * x differently in the last bit).
constexpr float kRestTolerance = 1e-6f;
// Refuse absurd sizes before allocating (a corrupt count cannot ask for terabytes).
constexpr size_t kMaxVoxels = size_t(1) << 31;
constexpr size_t kMaxKeypoints = 1 << 20;
constexpr size_t kMaxHistoryFrames = 1 << 20;
constexpr size_t kMaxLinks = 1 << 26;

class Writer {
 public:
  template <typename T>
  void Put(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    out_.append(reinterpret_cast<const char*>(&v), sizeof(T));
  }
  template <typename T>
  void PutVector(const std::vector<T>& v) {
    Put<uint64_t>(v.size());
    if (!v.empty()) out_.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
  }
  void PutString(const std::string& s) {
    Put<uint64_t>(s.size());
    out_.append(s);
  }
  std::string& bytes() { return out_; }

 private:
  std::string out_;
};

class Reader {
 public:
  Reader(const char* data, size_t size) : data_(data), size_(size) {}
  template <typename T>
  Status Get(T* v, const char* what) {
    if (size_ - pos_ < sizeof(T)) return DataLoss(std::string("checkpoint ends inside ") + what);
    std::memcpy(v, data_ + pos_, sizeof(T));
    pos_ += sizeof(T);
    return Status::Ok();
  }
  template <typename T>
  Status GetVector(std::vector<T>* v, size_t max_count, const char* what) {
    uint64_t n = 0;
    VD_RETURN_IF_ERROR(Get(&n, what));
    if (n > max_count || n > (size_ - pos_) / sizeof(T))
      return DataLoss(std::string("checkpoint ") + what + " declares " + std::to_string(n) + " entries");
    v->resize(n);
    if (n) std::memcpy(v->data(), data_ + pos_, n * sizeof(T));
    pos_ += n * sizeof(T);
    return Status::Ok();
  }
  Status GetString(std::string* s, const char* what) {
    std::vector<char> v;
    VD_RETURN_IF_ERROR(GetVector(&v, 4096, what));
    s->assign(v.begin(), v.end());
    return Status::Ok();
  }
  size_t remaining() const { return size_ - pos_; }

 private:
  const char* data_;
  size_t size_;
  size_t pos_ = 0;
};

struct BrickGrid {
  int bx, by, bz;
  explicit BrickGrid(const VdVolume& v)
      : bx((v.dim_x + kBrick - 1) / kBrick), by((v.dim_y + kBrick - 1) / kBrick), bz((v.dim_z + kBrick - 1) / kBrick) {}
  size_t count() const { return size_t(bx) * by * bz; }
  // Calls f(linear voxel index, x, y, z) for each grid point of brick b.
  template <typename F>
  void ForEach(const VdVolume& v, size_t b, F&& f) const {
    const int x0 = int(b % bx) * kBrick, y0 = int((b / bx) % by) * kBrick, z0 = int(b / (size_t(bx) * by)) * kBrick;
    for (int z = z0; z < std::min(z0 + kBrick, v.dim_z); ++z)
      for (int y = y0; y < std::min(y0 + kBrick, v.dim_y); ++y)
        for (int x = x0; x < std::min(x0 + kBrick, v.dim_x); ++x)
          f(size_t(x) + size_t(v.dim_x) * (size_t(y) + size_t(v.dim_y) * size_t(z)), x, y, z);
  }
};

bool AtRest(const EngineState& s, size_t i, int x, int y, int z) {
  if (s.weight[i] != 0.f || s.tsdf[i] != kRestTsdf || s.color[i] != 0u) return false;
  if (!s.has_deformation) return true;
  const vd_float4 rest = vd_rest_position(s.vol, x, y, z);
  const vd_float4& p = s.def_pos[i];
  const vd_float4& r = s.def_rot[i];
  return std::fabs(p.x - rest.x) <= kRestTolerance && std::fabs(p.y - rest.y) <= kRestTolerance &&
         std::fabs(p.z - rest.z) <= kRestTolerance && p.w == 0.f && r.x == 0.f && r.y == 0.f && r.z == 0.f &&
         r.w == 1.f;
}

template <typename T>
bool AllFinite(const std::vector<T>& v) {
  for (const T& e : v) {
    if constexpr (std::is_same_v<T, vd_float4>) {
      if (!std::isfinite(e.x) || !std::isfinite(e.y) || !std::isfinite(e.z) || !std::isfinite(e.w)) return false;
    } else if constexpr (std::is_floating_point_v<T>) {
      if (!std::isfinite(e)) return false;
    }
  }
  return true;
}

Status SyncFile(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY);
  if (fd < 0) return Unavailable("cannot open '" + path + "' to sync: " + std::strerror(errno));
  const int rc = ::fsync(fd);
  ::close(fd);
  if (rc != 0) return Unavailable("fsync '" + path + "': " + std::strerror(errno));
  return Status::Ok();
}

}  // namespace

Status EngineState::Validate() const {
  if (sparse) {
    if (!(vol.voxel_size > 0.f && vol.voxel_size < 1.f) || !(vol.truncation > 0.f) || !(vol.max_weight > 0.f))
      return InvalidArgument("checkpoint volume parameters are invalid");
    const size_t n = brick_keys.size() * kBrickVoxels;
    if (brick_keys.size() > kMaxBricks || tsdf.size() != n || weight.size() != n || color.size() != n)
      return InvalidArgument("checkpoint brick arrays do not match its bricks");
    if (has_deformation ? (def_pos.size() != n || def_rot.size() != n) : (!def_pos.empty() || !def_rot.empty()))
      return InvalidArgument("checkpoint deformation arrays do not match its bricks");
    std::vector<uint32_t> sorted = brick_keys;
    std::sort(sorted.begin(), sorted.end());
    if (std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end())
      return InvalidArgument("checkpoint names a brick twice");
    for (uint32_t k : brick_keys)
      if (k >> 30) return InvalidArgument("checkpoint brick key " + std::to_string(k) + " is not a brick's");
  } else if (vol.dim_x < 2 || vol.dim_y < 2 || vol.dim_z < 2 || num_voxels() > kMaxVoxels) {
    return InvalidArgument("checkpoint grid " + std::to_string(vol.dim_x) + "x" + std::to_string(vol.dim_y) + "x" +
                           std::to_string(vol.dim_z) + " is out of range");
  }
  if (!(vol.voxel_size > 0.f && vol.voxel_size < 1.f) || !(vol.truncation > 0.f) || !(vol.max_weight > 0.f) ||
      !std::isfinite(vol.origin.x) || !std::isfinite(vol.origin.y) || !std::isfinite(vol.origin.z))
    return InvalidArgument("checkpoint grid placement is invalid");
  const size_t n = num_voxels();
  if (!sparse && (tsdf.size() != n || weight.size() != n || color.size() != n))
    return InvalidArgument("checkpoint volume arrays do not match the grid");
  if (!sparse && (has_deformation != (def_pos.size() == n) || def_rot.size() != def_pos.size()))
    return InvalidArgument("checkpoint deformation arrays do not match the grid");
  if (!pose.allFinite()) return InvalidArgument("checkpoint pose is not finite");
  if (cam.width <= 0 || cam.height <= 0 || cam.width > 16384 || cam.height > 16384 || !(cam.fx > 0.f) ||
      !(cam.fy > 0.f))
    return InvalidArgument("checkpoint camera is invalid");
  if (frames_fused < 0 || frames_seen < frames_fused) return InvalidArgument("checkpoint frame counts are invalid");
  if (colour_registration > 2) return InvalidArgument("checkpoint colour registration verdict is out of range");
  for (const FrameFeatures& f : history) {
    const size_t k = f.u.size();
    if (f.v.size() != k || f.size.size() != k || f.angle.size() != k || f.camera_points.size() != k ||
        f.canonical.size() != k || f.desc.size() != k * VD_DESC_BYTES)
      return InvalidArgument("checkpoint feature frame " + std::to_string(f.frame_index) + " has inconsistent arrays");
  }
  int last = -1;
  for (int k : keyframes) {
    if (k <= last || k >= int(history.size())) return InvalidArgument("checkpoint keyframe list is invalid");
    last = k;
  }
  std::map<int64_t, size_t> features;
  for (const FrameFeatures& f : history) features[f.frame_index] = f.size_keypoints();
  for (const FeatureLink& l : links) {
    auto a = features.find(l.frame_a), b = features.find(l.frame_b);
    if (a == features.end() || b == features.end() || l.feature_a < 0 || size_t(l.feature_a) >= a->second ||
        l.feature_b < 0 || size_t(l.feature_b) >= b->second)
      return InvalidArgument("checkpoint feature link names a feature the history does not have");
  }
  const size_t nv = tracked.num_vertices();
  if (tracked.positions.size() != 3 * nv || (!tracked.colors.empty() && tracked.colors.size() != 3 * nv) ||
      tracked.triangles.size() % 3 != 0 || (nv == 0) != tracked.triangles.empty())
    return InvalidArgument("checkpoint tracked mesh has inconsistent arrays");
  for (int32_t i : tracked.triangles)
    if (i < 0 || size_t(i) >= nv) return InvalidArgument("checkpoint tracked mesh names a vertex it does not have");
  if (!AllFinite(tracked.positions)) return InvalidArgument("checkpoint tracked mesh holds non-finite positions");
  return Status::Ok();
}

std::string EncodeCheckpoint(const EngineState& s) {
  Writer w;
  w.Put(kFormatVersion);
  w.Put<uint32_t>(sizeof(VdVolume));
  w.Put(s.vol);
  w.Put<uint8_t>(s.has_deformation);
  w.Put<uint8_t>(s.sparse);
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) w.Put(s.pose(r, c));
  w.Put<uint32_t>(sizeof(VdCamera));
  w.Put(s.cam);
  w.Put(s.frames_fused);
  w.Put(s.frames_seen);
  w.Put(s.last_seq);
  w.PutString(s.source_id);
  if (s.sparse) {
    // Every slot's brick, in slot order, each stored whole.
    w.PutVector(s.brick_keys);
    for (size_t i = 0; i < s.tsdf.size(); ++i) {
      w.Put(s.tsdf[i]);
      w.Put(s.weight[i]);
      w.Put(s.color[i]);
      if (s.has_deformation) {
        w.Put(s.def_pos[i]);
        w.Put(s.def_rot[i]);
      }
    }
  }
  // Bricks holding anything but reset values, each stored whole (none for a sparse volume).
  const BrickGrid grid(s.vol);
  std::vector<uint32_t> stored;
  for (size_t b = 0; !s.sparse && b < grid.count(); ++b) {
    bool rest = true;
    grid.ForEach(s.vol, b, [&](size_t i, int x, int y, int z) { rest = rest && AtRest(s, i, x, y, z); });
    if (!rest) stored.push_back(uint32_t(b));
  }
  w.PutVector(stored);
  for (uint32_t b : stored) {
    grid.ForEach(s.vol, b, [&](size_t i, int, int, int) {
      w.Put(s.tsdf[i]);
      w.Put(s.weight[i]);
      w.Put(s.color[i]);
      if (s.has_deformation) {
        w.Put(s.def_pos[i]);
        w.Put(s.def_rot[i]);
      }
    });
  }
  w.Put<uint64_t>(s.history.size());
  for (const FrameFeatures& f : s.history) {
    w.Put(f.seq);
    w.Put(f.frame_index);
    w.PutVector(f.u);
    w.PutVector(f.v);
    w.PutVector(f.size);
    w.PutVector(f.angle);
    w.PutVector(f.camera_points);
    w.PutVector(f.desc);
    w.PutVector(f.canonical);
  }
  w.PutVector(s.keyframes);
  w.PutVector(s.tracked.positions);
  w.PutVector(s.tracked.colors);
  w.PutVector(s.tracked.triangles);
  w.PutVector(s.links);
  w.Put(s.colour_registration);
  const std::string& payload = w.bytes();
  std::string out(kMagic, sizeof(kMagic));
  const uint64_t size = payload.size();
  out.append(reinterpret_cast<const char*>(&size), sizeof(size));
  const Sha256Digest digest = Sha256(payload.data(), payload.size());
  out.append(reinterpret_cast<const char*>(digest.data()), digest.size());
  out.append(payload);
  return out;
}

StatusOr<EngineState> DecodeCheckpoint(const std::string& bytes) {
  if (bytes.size() < kHeaderBytes || std::memcmp(bytes.data(), kMagic, sizeof(kMagic)) != 0)
    return DataLoss("not a vdeform checkpoint (bad magic or shorter than its header)");
  uint64_t size = 0;
  std::memcpy(&size, bytes.data() + 8, sizeof(size));
  if (size != bytes.size() - kHeaderBytes)
    return DataLoss("torn checkpoint: the header declares " + std::to_string(size) + " payload bytes, the file has " +
                    std::to_string(bytes.size() - kHeaderBytes));
  const Sha256Digest digest = Sha256(bytes.data() + kHeaderBytes, size);
  if (std::memcmp(digest.data(), bytes.data() + 16, digest.size()) != 0)
    return DataLoss("corrupt checkpoint: SHA-256 of the contents does not match the header");
  Reader r(bytes.data() + kHeaderBytes, size);
  EngineState s;
  uint32_t version = 0, struct_size = 0;
  VD_RETURN_IF_ERROR(r.Get(&version, "version"));
  if (version < 1 || version > kFormatVersion)
    return DataLoss("checkpoint format version " + std::to_string(version) + " is not 1 to " +
                    std::to_string(kFormatVersion));
  VD_RETURN_IF_ERROR(r.Get(&struct_size, "volume size"));
  if (struct_size != sizeof(VdVolume)) return DataLoss("checkpoint volume record has the wrong size");
  VD_RETURN_IF_ERROR(r.Get(&s.vol, "volume"));
  uint8_t has_def = 0;
  VD_RETURN_IF_ERROR(r.Get(&has_def, "deformation flag"));
  s.has_deformation = has_def != 0;
  if (version >= 4) {
    uint8_t sparse = 0;
    VD_RETURN_IF_ERROR(r.Get(&sparse, "sparse flag"));
    s.sparse = sparse != 0;
  }
  for (int row = 0; row < 4; ++row)
    for (int c = 0; c < 4; ++c) VD_RETURN_IF_ERROR(r.Get(&s.pose(row, c), "pose"));
  VD_RETURN_IF_ERROR(r.Get(&struct_size, "camera size"));
  if (struct_size != sizeof(VdCamera)) return DataLoss("checkpoint camera record has the wrong size");
  VD_RETURN_IF_ERROR(r.Get(&s.cam, "camera"));
  VD_RETURN_IF_ERROR(r.Get(&s.frames_fused, "frames_fused"));
  VD_RETURN_IF_ERROR(r.Get(&s.frames_seen, "frames_seen"));
  VD_RETURN_IF_ERROR(r.Get(&s.last_seq, "last_seq"));
  VD_RETURN_IF_ERROR(r.GetString(&s.source_id, "source_id"));
  if (s.sparse) {
    if (s.has_deformation && version < 5) return DataLoss("checkpoint of a sparse volume with a deformation field");
    VD_RETURN_IF_ERROR(r.GetVector(&s.brick_keys, kMaxBricks, "brick keys"));
    const size_t voxels = s.brick_keys.size() * kBrickVoxels;
    const size_t voxel_bytes = s.has_deformation ? 12 + 2 * sizeof(vd_float4) : 12;
    if (voxels > r.remaining() / voxel_bytes) return DataLoss("checkpoint declares more bricks than it holds");
    s.tsdf.resize(voxels);
    s.weight.resize(voxels);
    s.color.resize(voxels);
    s.def_pos.resize(s.has_deformation ? voxels : 0);
    s.def_rot.resize(s.has_deformation ? voxels : 0);
    for (size_t i = 0; i < voxels; ++i) {
      VD_RETURN_IF_ERROR(r.Get(&s.tsdf[i], "tsdf"));
      VD_RETURN_IF_ERROR(r.Get(&s.weight[i], "weight"));
      VD_RETURN_IF_ERROR(r.Get(&s.color[i], "color"));
      if (s.has_deformation) {
        VD_RETURN_IF_ERROR(r.Get(&s.def_pos[i], "def_pos"));
        VD_RETURN_IF_ERROR(r.Get(&s.def_rot[i], "def_rot"));
      }
    }
  } else if (s.vol.dim_x < 2 || s.vol.dim_y < 2 || s.vol.dim_z < 2 || s.num_voxels() > kMaxVoxels) {
    return DataLoss("checkpoint grid dimensions are out of range");
  }
  // Rest values everywhere, then the stored bricks over them.
  const size_t n = s.sparse ? 0 : s.num_voxels();
  if (!s.sparse) {
    s.tsdf.assign(n, kRestTsdf);
    s.weight.assign(n, 0.f);
    s.color.assign(n, 0u);
  }
  const BrickGrid grid(s.vol);
  if (s.has_deformation && !s.sparse) {
    s.def_pos.resize(n);
    s.def_rot.assign(n, vd_float4{0.f, 0.f, 0.f, 1.f});
    for (size_t b = 0; b < grid.count(); ++b)
      grid.ForEach(s.vol, b, [&](size_t i, int x, int y, int z) { s.def_pos[i] = vd_rest_position(s.vol, x, y, z); });
  }
  std::vector<uint32_t> stored;
  VD_RETURN_IF_ERROR(r.GetVector(&stored, s.sparse ? 0 : grid.count(), "brick list"));
  uint32_t last = 0;
  for (size_t k = 0; k < stored.size(); ++k) {
    const uint32_t b = stored[k];
    if (b >= grid.count() || (k > 0 && b <= last)) return DataLoss("checkpoint brick list is not increasing");
    last = b;
    Status st = Status::Ok();
    grid.ForEach(s.vol, b, [&](size_t i, int, int, int) {
      if (!st.ok()) return;
      st = r.Get(&s.tsdf[i], "tsdf");
      if (st.ok()) st = r.Get(&s.weight[i], "weight");
      if (st.ok()) st = r.Get(&s.color[i], "color");
      if (st.ok() && s.has_deformation) st = r.Get(&s.def_pos[i], "def_pos");
      if (st.ok() && s.has_deformation) st = r.Get(&s.def_rot[i], "def_rot");
    });
    VD_RETURN_IF_ERROR(st);
  }
  uint64_t frames = 0;
  VD_RETURN_IF_ERROR(r.Get(&frames, "history size"));
  if (frames > kMaxHistoryFrames) return DataLoss("checkpoint history size is out of range");
  s.history.resize(frames);
  for (FrameFeatures& f : s.history) {
    VD_RETURN_IF_ERROR(r.Get(&f.seq, "feature seq"));
    VD_RETURN_IF_ERROR(r.Get(&f.frame_index, "feature frame index"));
    VD_RETURN_IF_ERROR(r.GetVector(&f.u, kMaxKeypoints, "keypoint u"));
    VD_RETURN_IF_ERROR(r.GetVector(&f.v, kMaxKeypoints, "keypoint v"));
    VD_RETURN_IF_ERROR(r.GetVector(&f.size, kMaxKeypoints, "keypoint size"));
    VD_RETURN_IF_ERROR(r.GetVector(&f.angle, kMaxKeypoints, "keypoint angle"));
    VD_RETURN_IF_ERROR(r.GetVector(&f.camera_points, kMaxKeypoints, "keypoint points"));
    VD_RETURN_IF_ERROR(r.GetVector(&f.desc, kMaxKeypoints * VD_DESC_BYTES, "descriptors"));
    VD_RETURN_IF_ERROR(r.GetVector(&f.canonical, kMaxKeypoints, "keypoint canonical"));
  }
  VD_RETURN_IF_ERROR(r.GetVector(&s.keyframes, kMaxHistoryFrames, "keyframes"));
  if (version >= 2) {
    VD_RETURN_IF_ERROR(r.GetVector(&s.tracked.positions, 3 * kMaxTrackedVertices, "tracked positions"));
    VD_RETURN_IF_ERROR(r.GetVector(&s.tracked.colors, 3 * kMaxTrackedVertices, "tracked colours"));
    VD_RETURN_IF_ERROR(r.GetVector(&s.tracked.triangles, 6 * kMaxTrackedVertices, "tracked faces"));
  }
  if (version >= 3) VD_RETURN_IF_ERROR(r.GetVector(&s.links, kMaxLinks, "feature links"));
  if (version >= 6) VD_RETURN_IF_ERROR(r.Get(&s.colour_registration, "colour registration"));
  if (r.remaining() != 0) return DataLoss("checkpoint has " + std::to_string(r.remaining()) + " trailing bytes");
  if (!AllFinite(s.tsdf) || !AllFinite(s.weight) || !AllFinite(s.def_pos) || !AllFinite(s.def_rot))
    return DataLoss("checkpoint volume holds non-finite values");
  Status valid = s.Validate();
  if (!valid.ok()) return DataLoss(valid.message());
  return s;
}

Status WriteFileAtomically(const std::filesystem::path& path, const std::function<void(std::ostream&)>& write,
                           const std::filesystem::path& previous) {
  namespace fs = std::filesystem;
  const fs::path tmp = path.string() + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    write(out);
    out.close();
    if (!out) return Unavailable("cannot write '" + tmp.string() + "' (disk full?)");
  }
  VD_RETURN_IF_ERROR(SyncFile(tmp.string()));
  std::error_code ec;
  // Each rename is atomic; a reader that finds no file at `path` between the two falls back to
  // `previous`.
  if (!previous.empty() && fs::exists(path, ec)) {
    fs::rename(path, previous, ec);
    if (ec) return Unavailable("cannot keep '" + path.string() + "' as '" + previous.string() + "': " + ec.message());
  }
  fs::rename(tmp, path, ec);
  if (ec) return Unavailable("cannot rename '" + tmp.string() + "': " + ec.message());
  (void)SyncFile(path.parent_path().empty() ? "." : path.parent_path().string());
  return Status::Ok();
}

Status WriteCheckpoint(const std::string& dir, const EngineState& state, size_t* bytes_written) {
  VD_RETURN_IF_ERROR(state.Validate());
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return Unavailable("cannot create checkpoint directory '" + dir + "': " + ec.message());
  const std::string bytes = EncodeCheckpoint(state);
  VD_RETURN_IF_ERROR(WriteFileAtomically(
      fs::path(dir) / kCheckpointFile,
      [&](std::ostream& out) { out.write(bytes.data(), std::streamsize(bytes.size())); },
      fs::path(dir) / kPreviousCheckpointFile));
  if (bytes_written) *bytes_written = bytes.size();
  return Status::Ok();
}

StatusOr<EngineState> ReadCheckpoint(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return NotFound("cannot open checkpoint '" + path + "'");
  std::stringstream ss;
  ss << in.rdbuf();
  auto state = DecodeCheckpoint(ss.str());
  if (!state.ok()) return state.status().WithContext(path);
  return state;
}

ResumeResult LoadLatestCheckpoint(const std::string& dir) {
  namespace fs = std::filesystem;
  ResumeResult result;
  for (const char* name : {kCheckpointFile, kPreviousCheckpointFile}) {
    const fs::path p = fs::path(dir) / name;
    std::error_code ec;
    if (!fs::exists(p, ec)) continue;
    auto state = ReadCheckpoint(p.string());
    if (state.ok()) {
      result.state = std::move(state).value();
      result.loaded_path = p.string();
      return result;
    }
    const auto stamp = std::chrono::duration_cast<std::chrono::seconds>(
                           std::chrono::system_clock::now().time_since_epoch())
                           .count();
    const fs::path kept = p.string() + ".corrupt-" + std::to_string(stamp);
    fs::rename(p, kept, ec);
    result.problems.push_back(state.status().message() + (ec ? "" : " (kept as " + kept.filename().string() + ")"));
  }
  return result;
}

}  // namespace vd
