#pragma once
// Conversion between in-memory types and the vdeform LCM messages, channel names, LCM URL.
#include <cstdint>
#include <exception>
#include <optional>
#include <string>
#include <string_view>

#include <vdeform/control_t.hpp>
#include <vdeform/mesh_t.hpp>
#include <vdeform/rgbd_frame_t.hpp>
#include <vdeform/server_status_t.hpp>

#include "vd/common/codecs.h"
#include "vd/common/frame.h"
#include "vd/common/mesh.h"
#include "vd/common/status.h"

namespace vd {

// Channel names, defined once.
inline constexpr const char* kFrameChannel = "VDEFORM_FRAMES";
inline constexpr const char* kMeshChannel = "VDEFORM_MESH";
inline constexpr const char* kStatusChannel = "VDEFORM_STATUS";
inline constexpr const char* kControlChannel = "VDEFORM_CONTROL";

// The four channels of one stream. Several sensors and servers share one LCM URL by naming their
// streams (--stream NAME on every program): VDEFORM_<NAME>_FRAMES, _MESH, _STATUS and _CONTROL.
// The unnamed stream ("", the default) keeps the names above.
struct StreamChannels {
  std::string frames = kFrameChannel;
  std::string mesh = kMeshChannel;
  std::string status = kStatusChannel;
  std::string control = kControlChannel;
};
// Stream names: at most 64 of A-Z a-z 0-9 _ - (they become part of channel names); "" = unnamed.
Status ValidateStreamName(std::string_view name);
StatusOr<StreamChannels> ChannelsOfStream(const std::string& stream);
// The stream a channel of kind `suffix` ("MESH", "STATUS", ...) belongs to: "VDEFORM_MESH" -> "",
// "VDEFORM_CAM_1_MESH" -> "CAM_1"; nullopt for any other channel (or an invalid name).
std::optional<std::string> StreamOfChannel(const std::string& channel, const std::string& suffix);
// LCM's regular expression for the channels of that kind of every stream.
std::string AllStreamsChannelRegex(const std::string& suffix);

// Largest payload accepted in one message; LCM delivery breaks above ~8 MB (STACK.md).
inline constexpr int64_t kMaxPayloadBytes = 6 * 1024 * 1024;

// Multicast on the host only (ttl=0) with a 4 MB receive buffer: STACK.md measured 71 of 300
// frames arriving with the kernel default buffer and all 300 with this one.
inline constexpr const char* kDefaultLcmUrl = "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=4194304";
// What to check when LCM cannot be opened (appended to the programs' error).
inline constexpr const char* kLcmRouteHint =
    "(no multicast route? one host: ip route add 224.0.0.0/4 dev lo; several hosts: the same on the LAN interface; see deploy/prepare-host.sh --check and docs/OPERATIONS.md)";
// server_status_t.state as text: "IDLE", "TRACKING", "TRACKING_LOST", "ERROR" or "INVALID(n)".
std::string ServerStateName(int8_t state);
// The flag if given, else $LCM_DEFAULT_URL, else kDefaultLcmUrl.
std::string ResolveLcmUrl(const std::string& flag_value);

struct FrameEncodeOptions {
  DepthEncoding depth = DepthEncoding::kRvl;
  ColorEncoding color = ColorEncoding::kJpeg;
  // JPEG quality 1..100.
  int jpeg_quality = 90;
  Status Validate() const;
};

StatusOr<vdeform::rgbd_frame_t> FrameToMessage(const RgbdFrame& frame, const FrameEncodeOptions& options);
// Validates every field (sizes, encodings, intrinsics, payload lengths) before decoding.
StatusOr<RgbdFrame> MessageToFrame(const vdeform::rgbd_frame_t& msg);

// LIVE, CANONICAL or TRACKED (mesh_t.lcm).
inline bool KnownMeshKind(int8_t kind) {
  return kind == vdeform::mesh_t::KIND_LIVE || kind == vdeform::mesh_t::KIND_CANONICAL ||
         kind == vdeform::mesh_t::KIND_TRACKED;
}
StatusOr<vdeform::mesh_t> MeshToMessage(const TriangleMesh& mesh, int64_t utime, int64_t seq, int8_t kind,
                                        int8_t encoding = vdeform::mesh_t::ENCODING_DRACO,
                                        const DracoOptions& draco = {});
StatusOr<TriangleMesh> MessageToMesh(const vdeform::mesh_t& msg);

// lcm-gen's decode() resizes each array to its declared count before checking that the bytes are
// there (a 40-byte message declaring 2^31 bytes allocates 2 GB), and throws std::length_error on a
// negative count or a zero-length string. ValidateLcmWire walks Msg's wire layout without
// allocating and refuses such input; DecodeLcm runs it first. Defined for the four vdeform types.
template <typename Msg>
Status ValidateLcmWire(const void* data, size_t size);
template <>
Status ValidateLcmWire<vdeform::rgbd_frame_t>(const void* data, size_t size);
template <>
Status ValidateLcmWire<vdeform::mesh_t>(const void* data, size_t size);
template <>
Status ValidateLcmWire<vdeform::server_status_t>(const void* data, size_t size);
template <>
Status ValidateLcmWire<vdeform::control_t>(const void* data, size_t size);

// Decodes raw LCM bytes into a message, turning LCM's -1 into a Status (truncated/garbage input).
template <typename Msg>
StatusOr<Msg> DecodeLcm(const void* data, size_t size) {
  if (size > static_cast<size_t>(INT32_MAX)) return InvalidArgument("LCM message too large");
  VD_RETURN_IF_ERROR(ValidateLcmWire<Msg>(data, size));
  Msg msg;
  int used = -1;
  try {
    used = msg.decode(data, 0, static_cast<int>(size));
  } catch (const std::exception& e) {
    return DataLoss(std::string("cannot decode ") + Msg::getTypeName() + ": " + e.what());
  }
  if (used < 0) return DataLoss(std::string("cannot decode ") + Msg::getTypeName() + " (" + std::to_string(size) + " bytes)");
  return msg;
}

}  // namespace vd
