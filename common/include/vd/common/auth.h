#pragma once
// Authenticated messages: HMAC-SHA256 (OpenSSL) over a fixed byte layout of a message's fields.
// Control commands are signed under the server's control key, frames under their source's frame
// key; the server checks them when it is given the key files. The server's meshes and status are
// signed under its output key; viewers and lockstep capture clients given it check them. LCM
// itself has no authentication. Each kind has its own domain tag: a MAC of one kind never
// verifies as another.
#include <array>
#include <cstdint>
#include <map>
#include <string>

#include <vdeform/control_t.hpp>
#include <vdeform/mesh_t.hpp>
#include <vdeform/rgbd_frame_t.hpp>
#include <vdeform/server_status_t.hpp>

#include "vd/common/status.h"

namespace vd {

using Sha256Digest = std::array<uint8_t, 32>;

// Shortest control key accepted: 128 bits.
inline constexpr size_t kMinControlKeyBytes = 16;
// A frame key is exactly 32 bytes, written as 64 hex digits (`openssl rand -hex 32`): RFC 2104
// asks for at least the digest's length, and one fixed length catches a truncated copy.
inline constexpr size_t kFrameKeyBytes = 32;

// All zeros if OpenSSL fails; the Sign/Verify functions below refuse instead.
Sha256Digest HmacSha256(const std::string& key, const std::string& data);
// SHA-256 of a byte range (checkpoint integrity).
Sha256Digest Sha256(const void* data, size_t size);
std::string ToHex(const Sha256Digest& d);

// The bytes the HMAC covers: a domain tag, utime, command, path and sender, each length-prefixed.
std::string ControlAuthBytes(const vdeform::control_t& msg);
// Fills msg->auth with the HMAC of its other fields.
void SignControl(const std::string& key, vdeform::control_t* msg);
// Ok when msg->auth is the HMAC of its fields under key (constant-time comparison).
Status VerifyControl(const std::string& key, const vdeform::control_t& msg);

// A frame's MAC covers a domain tag and every header field (utime, seq, epoch, source id,
// intrinsics, size, depth scale, encodings, array lengths), then the depth and colour bytes,
// streamed into the HMAC where they lie (no copy of the payload).
// Fills msg->auth with that MAC; every other field must be final. Internal when OpenSSL fails.
Status SignFrame(const std::string& key, vdeform::rgbd_frame_t* msg);
// Ok when msg->auth is the MAC under key (constant-time comparison); PermissionDenied otherwise,
// also for an unsigned frame (auth_size 0, refused without hashing the payload).
Status VerifyFrame(const std::string& key, const vdeform::rgbd_frame_t& msg);
// A mesh's MAC covers a domain tag and every other field (utime, seq, kind, counts, encoding,
// bounding box, epoch, out_seq, data length), then the payload, streamed where it lies.
// Fills msg->auth with that MAC; every other field must be final. Internal when OpenSSL fails.
Status SignMesh(const std::string& key, vdeform::mesh_t* msg);
// Ok when msg->auth is the MAC under key (constant-time comparison); PermissionDenied otherwise,
// also for an unsigned mesh (auth_size 0, refused without hashing the payload).
Status VerifyMesh(const std::string& key, const vdeform::mesh_t& msg);
// A status's MAC covers a domain tag and the status's LCM encoding with auth emptied: every field.
// Fills msg->auth; Internal when OpenSSL fails or an array disagrees with its count.
Status SignStatus(const std::string& key, vdeform::server_status_t* msg);
// As VerifyMesh, for a status.
Status VerifyStatus(const std::string& key, const vdeform::server_status_t& msg);

// A random non-zero epoch for rgbd_frame_t.epoch (OpenSSL's CSPRNG): one per capture process;
// likewise mesh_t.epoch and server_status_t.epoch, one per server process.
int64_t RandomEpoch();

// The bytes of a secret file (a key, a web token): refuses a missing or non-regular file and one
// readable by group or others; `what` names it in the errors ("control key file").
StatusOr<std::string> ReadPrivateFile(const std::string& path, const std::string& what);

// Reads a key file: its bytes with trailing whitespace removed; refuses missing, short, and
// group- or world-readable files (a key others can read authenticates nothing).
StatusOr<std::string> ReadControlKey(const std::string& path);

// The keys of a --frame-key-file: one key for every source, or one key per source id.
class FrameKeys {
 public:
  // The key of source_id's frames; nullptr when the file has per-source keys and none for it.
  const std::string* For(const std::string& source_id) const;
  bool empty() const { return all_.empty() && per_source_.empty(); }
  bool per_source() const { return !per_source_.empty(); }
  size_t size() const { return all_.empty() ? per_source_.size() : 1; }

  // The text of a key file (`path` names it in errors, `what` says what it is). Lines: blank,
  // `# comment`, and either one line `KEY` (every source) or lines `SOURCE_ID KEY`; KEY is
  // kFrameKeyBytes as hex digits. Errors name the file and the line.
  static StatusOr<FrameKeys> Parse(const std::string& text, const std::string& path,
                                   const std::string& what = "frame key file");

 private:
  std::string all_;
  std::map<std::string, std::string> per_source_;
};

// Reads and parses a frame key file, with ReadControlKey's checks on the file (exists, regular,
// private to its owner).
StatusOr<FrameKeys> ReadFrameKeys(const std::string& path);

// The server's output key (--output-key-file on vdeform-server, -capture, -viewer, -web): a frame
// key file's format with its single line KEY; SOURCE_ID KEY lines are refused (the output has no
// source), naming the file.
StatusOr<std::string> ParseOutputKey(const std::string& text, const std::string& path);
// Reads and parses it, with ReadFrameKeys' checks on the file.
StatusOr<std::string> ReadOutputKey(const std::string& path);
// The key a program's output key flag names: ReadOutputKey(path), or no key (empty) without one.
StatusOr<std::string> OutputKeyFromFlag(const std::string& path);

}  // namespace vd
