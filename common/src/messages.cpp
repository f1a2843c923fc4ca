// Conversion between frames/meshes and the vdeform LCM messages, and a non-allocating check of
// LCM wire bytes that runs before lcm-gen's decode (see ValidateLcmWire in messages.h).
#include "vd/common/messages.h"

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace vd {

Status ValidateStreamName(std::string_view name) {
  if (name.size() > 64)
    return InvalidArgument("stream name of " + std::to_string(name.size()) + " characters; at most 64 are allowed");
  for (char c : name) {
    const bool ok = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_' || c == '-';
    if (!ok) return InvalidArgument("stream name '" + std::string(name) + "' may hold only A-Z a-z 0-9 _ -");
  }
  return Status::Ok();
}

StatusOr<StreamChannels> ChannelsOfStream(const std::string& stream) {
  VD_RETURN_IF_ERROR(ValidateStreamName(stream));
  StreamChannels channels;
  if (stream.empty()) return channels;
  const std::string prefix = "VDEFORM_" + stream + "_";
  channels.frames = prefix + "FRAMES";
  channels.mesh = prefix + "MESH";
  channels.status = prefix + "STATUS";
  channels.control = prefix + "CONTROL";
  return channels;
}

std::optional<std::string> StreamOfChannel(const std::string& channel, const std::string& suffix) {
  const std::string prefix = "VDEFORM_";
  if (channel == prefix + suffix) return std::string();
  const std::string tail = "_" + suffix;
  if (channel.size() <= prefix.size() + tail.size() || channel.compare(0, prefix.size(), prefix) != 0 ||
      channel.compare(channel.size() - tail.size(), tail.size(), tail) != 0)
    return std::nullopt;
  std::string stream = channel.substr(prefix.size(), channel.size() - prefix.size() - tail.size());
  if (!ValidateStreamName(stream).ok()) return std::nullopt;
  return stream;
}

std::string AllStreamsChannelRegex(const std::string& suffix) { return "VDEFORM_([A-Za-z0-9_-]+_)?" + suffix; }

namespace {

// Longer source ids are not names a capture client would choose; the bound keeps logs sane.
constexpr size_t kMaxSourceIdLength = 256;

// Walks LCM's big-endian wire format, bounding every count and length by the bytes left.
class WireWalker {
 public:
  WireWalker(const void* data, size_t size, const char* type)
      : data_(static_cast<const uint8_t*>(data)), size_(data == nullptr ? 0 : size), type_(type) {}

  Status Hash(int64_t expected) {
    uint64_t hash = 0;
    VD_RETURN_IF_ERROR(ReadBigEndian(8, "hash", &hash));
    if (static_cast<int64_t>(hash) != expected)
      return DataLoss(std::string("LCM bytes are not a ") + type_ + " (fingerprint mismatch)");
    return Status::Ok();
  }
  Status Skip(size_t bytes, const char* field) {
    if (bytes > size_ - pos_) return Short(field, bytes);
    pos_ += bytes;
    return Status::Ok();
  }
  // A non-negative int32 count for the arrays that follow.
  Status Count(const char* field, int32_t* count) {
    uint64_t raw = 0;
    VD_RETURN_IF_ERROR(ReadBigEndian(4, field, &raw));
    *count = static_cast<int32_t>(static_cast<uint32_t>(raw));
    if (*count < 0) return DataLoss(std::string(type_) + "." + field + " = " + std::to_string(*count) + " is negative");
    return Status::Ok();
  }
  Status Array(int32_t count, size_t element_bytes, const char* field) {
    return Skip(static_cast<size_t>(count) * element_bytes, field);
  }
  // int32 length including the terminating NUL, then the bytes; lcm-gen assigns length - 1 chars.
  // LCM encoders write C strings (the C++ one takes the length from strlen), so the last byte must
  // be the NUL and no other byte may be: a string with a NUL inside decodes to more characters than
  // the file system, the logs and the next encode see (re-encoding it writes fewer bytes than
  // getEncodedSize() promises, and LCM publishes the rest of the buffer uninitialised).
  Status String(const char* field) {
    uint64_t raw = 0;
    VD_RETURN_IF_ERROR(ReadBigEndian(4, field, &raw));
    const int32_t length = static_cast<int32_t>(static_cast<uint32_t>(raw));
    if (length < 1) return DataLoss(std::string(type_) + "." + field + " has string length " + std::to_string(length));
    if (static_cast<size_t>(length) > size_ - pos_) return Short(field, static_cast<size_t>(length));
    const uint8_t* text = data_ + pos_;
    if (text[length - 1] != 0) return DataLoss(std::string(type_) + "." + field + " is not NUL-terminated");
    if (std::memchr(text, 0, static_cast<size_t>(length) - 1) != nullptr)
      return DataLoss(std::string(type_) + "." + field + " holds a NUL byte inside the string");
    pos_ += static_cast<size_t>(length);
    return Status::Ok();
  }
  Status Strings(int32_t count, const char* field) {
    // Each string takes at least 5 bytes; refuse before lcm-gen resizes the vector to count.
    if (static_cast<size_t>(count) > (size_ - pos_) / 5) return Short(field, static_cast<size_t>(count) * 5);
    for (int32_t i = 0; i < count; ++i) VD_RETURN_IF_ERROR(String(field));
    return Status::Ok();
  }
  size_t used() const { return pos_; }

 private:
  Status ReadBigEndian(size_t bytes, const char* field, uint64_t* out) {
    if (bytes > size_ - pos_) return Short(field, bytes);
    uint64_t v = 0;
    for (size_t k = 0; k < bytes; ++k) v = v << 8 | data_[pos_ + k];
    pos_ += bytes;
    *out = v;
    return Status::Ok();
  }
  Status Short(const char* field, size_t needed) const {
    return DataLoss(std::string(type_) + "." + field + " needs " + std::to_string(needed) + " bytes at offset " +
                    std::to_string(pos_) + ", " + std::to_string(size_ - pos_) + " remain");
  }
  const uint8_t* data_;
  size_t size_;
  size_t pos_ = 0;
  const char* type_;
};

bool IsDepthEncoding(int8_t e) {
  return e == vdeform::rgbd_frame_t::DEPTH_RAW16 || e == vdeform::rgbd_frame_t::DEPTH_PNG16 ||
         e == vdeform::rgbd_frame_t::DEPTH_RVL;
}

bool IsColorEncoding(int8_t e) {
  return e == vdeform::rgbd_frame_t::COLOR_NONE || e == vdeform::rgbd_frame_t::COLOR_RAW_BGR8 ||
         e == vdeform::rgbd_frame_t::COLOR_JPEG;
}

static_assert(static_cast<int8_t>(DepthEncoding::kRaw16) == vdeform::rgbd_frame_t::DEPTH_RAW16 &&
                  static_cast<int8_t>(DepthEncoding::kPng16) == vdeform::rgbd_frame_t::DEPTH_PNG16 &&
                  static_cast<int8_t>(DepthEncoding::kRvl) == vdeform::rgbd_frame_t::DEPTH_RVL,
              "DepthEncoding must match rgbd_frame_t");
static_assert(static_cast<int8_t>(ColorEncoding::kNone) == vdeform::rgbd_frame_t::COLOR_NONE &&
                  static_cast<int8_t>(ColorEncoding::kRawBgr8) == vdeform::rgbd_frame_t::COLOR_RAW_BGR8 &&
                  static_cast<int8_t>(ColorEncoding::kJpeg) == vdeform::rgbd_frame_t::COLOR_JPEG,
              "ColorEncoding must match rgbd_frame_t");

}  // namespace

template <>
Status ValidateLcmWire<vdeform::rgbd_frame_t>(const void* data, size_t size) {
  WireWalker w(data, size, "rgbd_frame_t");
  int32_t n = 0;
  VD_RETURN_IF_ERROR(w.Hash(vdeform::rgbd_frame_t::getHash()));
  VD_RETURN_IF_ERROR(w.Skip(3 * 8, "utime/seq/epoch"));
  VD_RETURN_IF_ERROR(w.String("source_id"));
  VD_RETURN_IF_ERROR(w.Skip(4 * 4 + 2 * 4 + 4 + 1, "intrinsics/depth_encoding"));
  VD_RETURN_IF_ERROR(w.Count("depth_size", &n));
  VD_RETURN_IF_ERROR(w.Array(n, 1, "depth_data"));
  VD_RETURN_IF_ERROR(w.Skip(1, "color_encoding"));
  VD_RETURN_IF_ERROR(w.Count("color_size", &n));
  VD_RETURN_IF_ERROR(w.Array(n, 1, "color_data"));
  VD_RETURN_IF_ERROR(w.Count("auth_size", &n));
  return w.Array(n, 1, "auth");
}

template <>
Status ValidateLcmWire<vdeform::mesh_t>(const void* data, size_t size) {
  WireWalker w(data, size, "mesh_t");
  int32_t n = 0;
  VD_RETURN_IF_ERROR(w.Hash(vdeform::mesh_t::getHash()));
  VD_RETURN_IF_ERROR(w.Skip(8 + 8 + 1 + 4 + 4 + 1, "utime/seq/kind/counts/encoding"));
  VD_RETURN_IF_ERROR(w.Count("data_size", &n));
  VD_RETURN_IF_ERROR(w.Array(n, 1, "data"));
  VD_RETURN_IF_ERROR(w.Skip(6 * 4 + 8 + 8, "bbox/epoch/out_seq"));
  VD_RETURN_IF_ERROR(w.Count("auth_size", &n));
  return w.Array(n, 1, "auth");
}

template <>
Status ValidateLcmWire<vdeform::server_status_t>(const void* data, size_t size) {
  WireWalker w(data, size, "server_status_t");
  int32_t n = 0;
  VD_RETURN_IF_ERROR(w.Hash(vdeform::server_status_t::getHash()));
  VD_RETURN_IF_ERROR(w.Skip(8 + 1, "utime/state"));
  VD_RETURN_IF_ERROR(w.String("message"));
  VD_RETURN_IF_ERROR(w.Skip(4 * 8, "frame counters"));
  VD_RETURN_IF_ERROR(w.Count("num_reject_reasons", &n));
  VD_RETURN_IF_ERROR(w.Strings(n, "reject_reason"));
  VD_RETURN_IF_ERROR(w.Array(n, 8, "reject_count"));
  VD_RETURN_IF_ERROR(w.Skip(11 * 8, "sequence, control, jump and rate counters"));
  VD_RETURN_IF_ERROR(w.Skip(8, "last_processed_seq"));
  VD_RETURN_IF_ERROR(w.String("last_source_id"));
  VD_RETURN_IF_ERROR(w.Skip(8, "last_epoch"));
  VD_RETURN_IF_ERROR(w.Count("num_stages", &n));
  VD_RETURN_IF_ERROR(w.Strings(n, "stage_name"));
  VD_RETURN_IF_ERROR(w.Array(n, 4, "stage_ms_last"));
  VD_RETURN_IF_ERROR(w.Array(n, 4, "stage_ms_mean"));
  VD_RETURN_IF_ERROR(w.Skip(4 + 3 * 4, "fps, latency_ms_last/p50/p95"));
  VD_RETURN_IF_ERROR(w.Skip(8 + 4 + 4 + 4 + 4 + 8, "active_voxels..resident_memory_bytes"));
  VD_RETURN_IF_ERROR(w.Skip(8 + 8, "model_frames/checkpoint_utime"));
  VD_RETURN_IF_ERROR(w.String("checkpoint_message"));
  VD_RETURN_IF_ERROR(w.Skip(8 + 8, "epoch/out_seq"));
  VD_RETURN_IF_ERROR(w.Count("auth_size", &n));
  return w.Array(n, 1, "auth");
}

template <>
Status ValidateLcmWire<vdeform::control_t>(const void* data, size_t size) {
  WireWalker w(data, size, "control_t");
  int32_t n = 0;
  VD_RETURN_IF_ERROR(w.Hash(vdeform::control_t::getHash()));
  VD_RETURN_IF_ERROR(w.Skip(8 + 1, "utime/command"));
  VD_RETURN_IF_ERROR(w.String("path"));
  VD_RETURN_IF_ERROR(w.String("sender"));
  VD_RETURN_IF_ERROR(w.Count("auth_size", &n));
  return w.Array(n, 1, "auth");
}

std::string ServerStateName(int8_t state) {
  switch (state) {
    case vdeform::server_status_t::STATE_IDLE:
      return "IDLE";
    case vdeform::server_status_t::STATE_TRACKING:
      return "TRACKING";
    case vdeform::server_status_t::STATE_TRACKING_LOST:
      return "TRACKING_LOST";
    case vdeform::server_status_t::STATE_ERROR:
      return "ERROR";
    default:
      return "INVALID(" + std::to_string(state) + ")";
  }
}

std::string ResolveLcmUrl(const std::string& flag_value) {
  if (!flag_value.empty()) return flag_value;
  const char* env = std::getenv("LCM_DEFAULT_URL");
  if (env != nullptr && env[0] != '\0') return env;
  return kDefaultLcmUrl;
}

Status FrameEncodeOptions::Validate() const {
  if (depth != DepthEncoding::kRaw16 && depth != DepthEncoding::kPng16 && depth != DepthEncoding::kRvl)
    return InvalidArgument("FrameEncodeOptions.depth = " + std::to_string(static_cast<int>(depth)) +
                           " is not raw (0), png (1) or rvl (2)");
  if (color != ColorEncoding::kNone && color != ColorEncoding::kRawBgr8 && color != ColorEncoding::kJpeg)
    return InvalidArgument("FrameEncodeOptions.color = " + std::to_string(static_cast<int>(color)) +
                           " is not none (0), raw (1) or jpeg (2)");
  if (jpeg_quality < 1 || jpeg_quality > 100)
    return InvalidArgument("FrameEncodeOptions.jpeg_quality = " + std::to_string(jpeg_quality) +
                           " violates 1 <= jpeg_quality <= 100");
  return Status::Ok();
}

StatusOr<vdeform::rgbd_frame_t> FrameToMessage(const RgbdFrame& frame, const FrameEncodeOptions& options) {
  VD_RETURN_IF_ERROR(options.Validate());
  VD_RETURN_IF_ERROR(frame.Validate());
  if (frame.source_id.size() > kMaxSourceIdLength)
    return InvalidArgument("source_id has " + std::to_string(frame.source_id.size()) + " characters, limit " +
                           std::to_string(kMaxSourceIdLength));
  vdeform::rgbd_frame_t msg;
  msg.utime = frame.utime;
  msg.seq = frame.seq;
  msg.epoch = frame.epoch;
  msg.source_id = frame.source_id;
  msg.fx = frame.intrinsics.fx;
  msg.fy = frame.intrinsics.fy;
  msg.cx = frame.intrinsics.cx;
  msg.cy = frame.intrinsics.cy;
  msg.width = frame.intrinsics.width;
  msg.height = frame.intrinsics.height;
  msg.depth_scale = frame.depth_scale;
  msg.depth_encoding = static_cast<int8_t>(options.depth);
  VD_ASSIGN_OR_RETURN(msg.depth_data, EncodeDepth(frame.depth, options.depth));
  // A frame without colour goes out as NONE whatever the options ask for.
  const ColorEncoding color = frame.color.empty() ? ColorEncoding::kNone : options.color;
  msg.color_encoding = static_cast<int8_t>(color);
  VD_ASSIGN_OR_RETURN(msg.color_data, EncodeColor(frame.color, color, options.jpeg_quality));
  const int64_t total = static_cast<int64_t>(msg.depth_data.size()) + static_cast<int64_t>(msg.color_data.size());
  if (total > kMaxPayloadBytes)
    return OutOfRange("encoded frame is " + std::to_string(total) + " bytes, above kMaxPayloadBytes = " +
                      std::to_string(kMaxPayloadBytes) + "; use a compressed encoding");
  msg.depth_size = static_cast<int32_t>(msg.depth_data.size());
  msg.color_size = static_cast<int32_t>(msg.color_data.size());
  msg.auth_size = 0;
  return msg;
}

StatusOr<RgbdFrame> MessageToFrame(const vdeform::rgbd_frame_t& msg) {
  RgbdFrame frame;
  frame.utime = msg.utime;
  frame.seq = msg.seq;
  frame.epoch = msg.epoch;
  if (msg.source_id.size() > kMaxSourceIdLength)
    return InvalidArgument("rgbd_frame_t.source_id has " + std::to_string(msg.source_id.size()) + " characters, limit " +
                           std::to_string(kMaxSourceIdLength));
  frame.source_id = msg.source_id;
  frame.intrinsics.fx = msg.fx;
  frame.intrinsics.fy = msg.fy;
  frame.intrinsics.cx = msg.cx;
  frame.intrinsics.cy = msg.cy;
  frame.intrinsics.width = msg.width;
  frame.intrinsics.height = msg.height;
  VD_RETURN_IF_ERROR(frame.intrinsics.Validate().WithContext("rgbd_frame_t"));
  if (!std::isfinite(msg.depth_scale) || !(msg.depth_scale > 0.f) || !(msg.depth_scale < 1e6f))
    return InvalidArgument("rgbd_frame_t.depth_scale = " + std::to_string(msg.depth_scale) +
                           " violates 0 < depth_scale < 1e6");
  frame.depth_scale = msg.depth_scale;
  if (!IsDepthEncoding(msg.depth_encoding))
    return InvalidArgument("rgbd_frame_t.depth_encoding = " + std::to_string(msg.depth_encoding) + " is unknown");
  if (!IsColorEncoding(msg.color_encoding))
    return InvalidArgument("rgbd_frame_t.color_encoding = " + std::to_string(msg.color_encoding) + " is unknown");
  if (msg.depth_size < 0 || static_cast<size_t>(msg.depth_size) != msg.depth_data.size())
    return InvalidArgument("rgbd_frame_t.depth_size = " + std::to_string(msg.depth_size) + " but depth_data holds " +
                           std::to_string(msg.depth_data.size()) + " bytes");
  if (msg.color_size < 0 || static_cast<size_t>(msg.color_size) != msg.color_data.size())
    return InvalidArgument("rgbd_frame_t.color_size = " + std::to_string(msg.color_size) + " but color_data holds " +
                           std::to_string(msg.color_data.size()) + " bytes");
  const int64_t total = static_cast<int64_t>(msg.depth_size) + msg.color_size;
  if (total > kMaxPayloadBytes)
    return OutOfRange("rgbd_frame_t payload is " + std::to_string(total) + " bytes, above kMaxPayloadBytes = " +
                      std::to_string(kMaxPayloadBytes));
  const auto depth = DecodeDepth(msg.depth_data.data(), msg.depth_data.size(),
                                 static_cast<DepthEncoding>(msg.depth_encoding), msg.width, msg.height);
  if (!depth.ok()) return depth.status().WithContext("rgbd_frame_t depth");
  frame.depth = depth.value();
  const auto color = DecodeColor(msg.color_data.data(), msg.color_data.size(),
                                 static_cast<ColorEncoding>(msg.color_encoding), msg.width, msg.height);
  if (!color.ok()) return color.status().WithContext("rgbd_frame_t colour");
  frame.color = color.value();
  VD_RETURN_IF_ERROR(frame.Validate().WithContext("rgbd_frame_t"));
  return frame;
}

StatusOr<vdeform::mesh_t> MeshToMessage(const TriangleMesh& mesh, int64_t utime, int64_t seq, int8_t kind,
                                        int8_t encoding, const DracoOptions& draco) {
  if (!KnownMeshKind(kind))
    return InvalidArgument("mesh kind " + std::to_string(kind) + " is not LIVE (0), CANONICAL (1) or TRACKED (2)");
  if (encoding != vdeform::mesh_t::ENCODING_DRACO && encoding != vdeform::mesh_t::ENCODING_RAW)
    return InvalidArgument("mesh encoding " + std::to_string(encoding) + " is not DRACO (0) or RAW (1)");
  VD_RETURN_IF_ERROR(draco.Validate());
  VD_RETURN_IF_ERROR(mesh.Validate());
  if (mesh.num_vertices() > static_cast<size_t>(INT32_MAX) || mesh.num_triangles() > static_cast<size_t>(INT32_MAX))
    return InvalidArgument("mesh too large for mesh_t counts");
  vdeform::mesh_t msg;
  msg.utime = utime;
  msg.seq = seq;
  msg.kind = kind;
  msg.encoding = encoding;
  msg.num_vertices = 0;
  msg.num_triangles = 0;
  msg.data_size = 0;
  for (int a = 0; a < 3; ++a) msg.bbox_min[a] = msg.bbox_max[a] = 0.f;
  // The publisher stamps its run and count, and signs (vdeform-server: Node's PublishOutput).
  msg.epoch = 0;
  msg.out_seq = 0;
  msg.auth_size = 0;
  // A mesh with no triangles (for example before the first fused frame) is sent as zero bytes.
  if (mesh.empty()) return msg;
  if (encoding == vdeform::mesh_t::ENCODING_DRACO) {
    VD_ASSIGN_OR_RETURN(msg.data, EncodeMeshDraco(mesh, draco));
  } else {
    VD_ASSIGN_OR_RETURN(msg.data, EncodePly(mesh));
  }
  if (static_cast<int64_t>(msg.data.size()) > kMaxPayloadBytes)
    return OutOfRange("encoded mesh is " + std::to_string(msg.data.size()) + " bytes, above kMaxPayloadBytes = " +
                      std::to_string(kMaxPayloadBytes));
  msg.data_size = static_cast<int32_t>(msg.data.size());
  msg.num_vertices = static_cast<int32_t>(mesh.num_vertices());
  msg.num_triangles = static_cast<int32_t>(mesh.num_triangles());
  mesh.Bounds(msg.bbox_min, msg.bbox_max);
  return msg;
}

StatusOr<TriangleMesh> MessageToMesh(const vdeform::mesh_t& msg) {
  if (!KnownMeshKind(msg.kind)) return InvalidArgument("mesh_t.kind = " + std::to_string(msg.kind) + " is unknown");
  if (msg.encoding != vdeform::mesh_t::ENCODING_DRACO && msg.encoding != vdeform::mesh_t::ENCODING_RAW)
    return InvalidArgument("mesh_t.encoding = " + std::to_string(msg.encoding) + " is unknown");
  if (msg.data_size < 0 || static_cast<size_t>(msg.data_size) != msg.data.size())
    return InvalidArgument("mesh_t.data_size = " + std::to_string(msg.data_size) + " but data holds " +
                           std::to_string(msg.data.size()) + " bytes");
  if (msg.data_size > kMaxPayloadBytes)
    return OutOfRange("mesh_t.data_size = " + std::to_string(msg.data_size) + " above kMaxPayloadBytes");
  if (msg.num_vertices < 0 || msg.num_triangles < 0)
    return InvalidArgument("mesh_t counts are negative (" + std::to_string(msg.num_vertices) + " vertices, " +
                           std::to_string(msg.num_triangles) + " triangles)");
  for (int a = 0; a < 3; ++a)
    if (!std::isfinite(msg.bbox_min[a]) || !std::isfinite(msg.bbox_max[a]) || msg.bbox_min[a] > msg.bbox_max[a])
      return InvalidArgument("mesh_t bounding box is not finite or has min > max");
  if (msg.data_size == 0) {
    if (msg.num_vertices != 0 || msg.num_triangles != 0)
      return InvalidArgument("mesh_t carries no data but declares " + std::to_string(msg.num_vertices) + " vertices, " +
                             std::to_string(msg.num_triangles) + " triangles");
    return TriangleMesh();
  }
  // MeshToMessage sends a mesh without triangles as no data, and Draco cannot hold one; a PLY
  // payload could, so refuse it here for both encodings alike.
  if (msg.num_triangles == 0)
    return InvalidArgument("mesh_t carries " + std::to_string(msg.data_size) +
                           " bytes but declares no triangles (an empty mesh is sent with no data)");
  auto mesh = msg.encoding == vdeform::mesh_t::ENCODING_DRACO ? DecodeMeshDraco(msg.data.data(), msg.data.size())
                                                              : DecodePly(msg.data.data(), msg.data.size());
  if (!mesh.ok()) return mesh.status().WithContext("mesh_t");
  if (mesh->num_vertices() != static_cast<size_t>(msg.num_vertices) ||
      mesh->num_triangles() != static_cast<size_t>(msg.num_triangles))
    return DataLoss("mesh_t declares " + std::to_string(msg.num_vertices) + " vertices, " +
                    std::to_string(msg.num_triangles) + " triangles; its data holds " +
                    std::to_string(mesh->num_vertices()) + ", " + std::to_string(mesh->num_triangles()));
  return mesh;
}

}  // namespace vd
