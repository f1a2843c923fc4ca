#include "vd/common/auth.h"

#include <sys/stat.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <fstream>
#include <initializer_list>
#include <memory>
#include <optional>
#include <sstream>
#include <vector>

#include <openssl/core_names.h>
#include <openssl/crypto.h>
#include <openssl/evp.h>
#include <openssl/rand.h>

namespace vd {
namespace {

constexpr size_t kMacBytes = Sha256Digest().size();

void AppendU64(std::string* s, uint64_t v) {
  for (int i = 0; i < 8; ++i) s->push_back(char((v >> (8 * i)) & 0xff));
}
void AppendString(std::string* s, const std::string& v) {
  AppendU64(s, v.size());
  s->append(v);
}
void AppendFloat(std::string* s, float v) {
  uint32_t bits = 0;
  std::memcpy(&bits, &v, sizeof bits);
  AppendU64(s, bits);
}

// HMAC-SHA256 fed in pieces (OpenSSL 3's EVP_MAC), so a frame's payload is hashed where it lies.
// Final() is empty when OpenSSL failed (no provider for HMAC): callers refuse rather than compare.
class HmacStream {
 public:
  explicit HmacStream(const std::string& key) {
    static EVP_MAC* const mac = EVP_MAC_fetch(nullptr, OSSL_MAC_NAME_HMAC, nullptr);
    ctx_.reset(mac ? EVP_MAC_CTX_new(mac) : nullptr);
    char digest[] = OSSL_DIGEST_NAME_SHA2_256;
    const OSSL_PARAM params[] = {OSSL_PARAM_construct_utf8_string(OSSL_MAC_PARAM_DIGEST, digest, 0),
                                 OSSL_PARAM_construct_end()};
    ok_ = ctx_ && EVP_MAC_init(ctx_.get(), reinterpret_cast<const unsigned char*>(key.data()), key.size(), params) == 1;
  }
  void Update(const void* data, size_t size) {
    if (ok_ && size > 0) ok_ = EVP_MAC_update(ctx_.get(), static_cast<const unsigned char*>(data), size) == 1;
  }
  std::optional<Sha256Digest> Final() {
    Sha256Digest out{};
    size_t len = 0;
    if (!ok_ || EVP_MAC_final(ctx_.get(), out.data(), &len, out.size()) != 1 || len != out.size()) return std::nullopt;
    return out;
  }

 private:
  struct Free {
    void operator()(EVP_MAC_CTX* c) const { EVP_MAC_CTX_free(c); }
  };
  std::unique_ptr<EVP_MAC_CTX, Free> ctx_;
  bool ok_ = false;
};

// A contiguous range of bytes a MAC streams after its header.
struct ByteRange {
  const void* data;
  size_t size;
};

// The HMAC of `header` followed by `payloads`, each hashed where it lies (no copy).
std::optional<Sha256Digest> StreamedHmac(const std::string& key, const std::string& header,
                                         std::initializer_list<ByteRange> payloads = {}) {
  HmacStream mac(key);
  mac.Update(header.data(), header.size());
  for (const ByteRange& p : payloads) mac.Update(p.data, p.size);
  return mac.Final();
}

std::optional<Sha256Digest> Hmac(const std::string& key, const std::string& data) { return StreamedHmac(key, data); }

// Each kind of message starts its MAC with its own domain tag (no tag is a prefix of another), so
// a MAC of one kind never verifies as another, whatever the key.
std::optional<Sha256Digest> Mac(const std::string& key, const vdeform::rgbd_frame_t& msg) {
  std::string header = "vdeform-frame-v1";
  AppendU64(&header, uint64_t(msg.utime));
  AppendU64(&header, uint64_t(msg.seq));
  AppendU64(&header, uint64_t(msg.epoch));
  AppendString(&header, msg.source_id);
  for (float v : {msg.fx, msg.fy, msg.cx, msg.cy, msg.depth_scale}) AppendFloat(&header, v);
  AppendU64(&header, uint32_t(msg.width));
  AppendU64(&header, uint32_t(msg.height));
  header.push_back(char(msg.depth_encoding));
  header.push_back(char(msg.color_encoding));
  // The arrays' lengths go first, so no byte can move between depth and colour unnoticed.
  AppendU64(&header, msg.depth_data.size());
  AppendU64(&header, msg.color_data.size());
  return StreamedHmac(key, header,
                      {{msg.depth_data.data(), msg.depth_data.size()}, {msg.color_data.data(), msg.color_data.size()}});
}

std::optional<Sha256Digest> Mac(const std::string& key, const vdeform::mesh_t& msg) {
  std::string header = "vdeform-mesh-v1";
  AppendU64(&header, uint64_t(msg.utime));
  AppendU64(&header, uint64_t(msg.seq));
  header.push_back(char(msg.kind));
  AppendU64(&header, uint32_t(msg.num_vertices));
  AppendU64(&header, uint32_t(msg.num_triangles));
  header.push_back(char(msg.encoding));
  for (float v : msg.bbox_min) AppendFloat(&header, v);
  for (float v : msg.bbox_max) AppendFloat(&header, v);
  AppendU64(&header, uint64_t(msg.epoch));
  AppendU64(&header, uint64_t(msg.out_seq));
  AppendU64(&header, uint32_t(msg.data_size));
  AppendU64(&header, msg.data.size());
  return StreamedHmac(key, header, {{msg.data.data(), msg.data.size()}});
}

// The status's own LCM encoding with auth emptied: every field by construction (its ~45 fields
// listed by hand would drift as fields are added), and small (under 1 KB), so the copy is cheap.
// Empty when an array disagrees with its count: lcm-gen's encode would read past the vector (a
// decoded message always agrees; one the node fills must too).
std::optional<Sha256Digest> Mac(const std::string& key, const vdeform::server_status_t& msg) {
  const size_t reasons = size_t(std::max(msg.num_reject_reasons, 0)), stages = size_t(std::max(msg.num_stages, 0));
  if (msg.num_reject_reasons < 0 || msg.reject_reason.size() != reasons || msg.reject_count.size() != reasons ||
      msg.num_stages < 0 || msg.stage_name.size() != stages || msg.stage_ms_last.size() != stages ||
      msg.stage_ms_mean.size() != stages)
    return std::nullopt;
  vdeform::server_status_t copy = msg;
  copy.auth_size = 0;
  copy.auth.clear();
  const std::string tag = "vdeform-status-v1";
  std::string header(tag.size() + size_t(copy.getEncodedSize()), '\0');
  std::memcpy(header.data(), tag.data(), tag.size());
  if (copy.encode(header.data() + tag.size(), 0, int(header.size() - tag.size())) < 0) return std::nullopt;
  return StreamedHmac(key, header);
}

// The MAC in a message's auth field against the expected one, in constant time.
Status CheckMac(const std::optional<Sha256Digest>& expected, int32_t auth_size, const std::vector<uint8_t>& auth,
                const char* what) {
  if (auth_size != int32_t(kMacBytes) || auth.size() != kMacBytes)
    return PermissionDenied(std::string(what) + " carries no HMAC-SHA256 (auth_size " + std::to_string(auth_size) +
                            ")");
  if (!expected) return Internal(std::string("could not compute the HMAC of a ") + what);
  if (CRYPTO_memcmp(expected->data(), auth.data(), kMacBytes) != 0)
    return PermissionDenied(std::string(what) + " HMAC does not match the key");
  return Status::Ok();
}

// Writes the MAC into a message's auth field; leaves it unsigned (auth_size 0) if OpenSSL failed.
bool SetMac(const std::optional<Sha256Digest>& mac, int32_t* auth_size, std::vector<uint8_t>* auth) {
  auth->clear();
  if (mac) auth->assign(mac->begin(), mac->end());
  *auth_size = int32_t(auth->size());
  return mac.has_value();
}

// Fills msg->auth with the MAC of its other fields; Internal (and msg left unsigned) when OpenSSL
// failed. Shared by frames, meshes and status.
template <typename Msg>
Status SignMessage(const std::string& key, Msg* msg, const char* what) {
  if (!SetMac(Mac(key, *msg), &msg->auth_size, &msg->auth))
    return Internal(std::string("could not compute the HMAC of a ") + what);
  return Status::Ok();
}

// Ok when msg->auth is the MAC under key; an unsigned message is refused without hashing its
// payload.
template <typename Msg>
Status VerifyMessage(const std::string& key, const Msg& msg, const char* what) {
  if (msg.auth_size == 0) return PermissionDenied(std::string(what) + " carries no HMAC-SHA256 (auth_size 0)");
  return CheckMac(Mac(key, msg), msg.auth_size, msg.auth, what);
}

int HexDigit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

}  // namespace

// The contents of a secret file, after checking it is a regular file only its owner can read.
StatusOr<std::string> ReadPrivateFile(const std::string& path, const std::string& what) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return NotFound(what + " '" + path + "': " + std::strerror(errno));
  if (!S_ISREG(st.st_mode)) return InvalidArgument(what + " '" + path + "' is not a regular file");
  if (st.st_mode & (S_IRWXG | S_IRWXO))
    return PermissionDenied(what + " '" + path + "' is readable by group or others (chmod 600 it)");
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  if (!in) return Unavailable("cannot read " + what + " '" + path + "'");
  return ss.str();
}

Sha256Digest HmacSha256(const std::string& key, const std::string& data) {
  return Hmac(key, data).value_or(Sha256Digest{});
}

Sha256Digest Sha256(const void* data, size_t size) {
  Sha256Digest out{};
  unsigned int len = 0;
  EVP_Digest(data, size, out.data(), &len, EVP_sha256(), nullptr);
  return out;
}

std::string ToHex(const Sha256Digest& d) {
  static const char* kHex = "0123456789abcdef";
  std::string s;
  for (uint8_t b : d) {
    s.push_back(kHex[b >> 4]);
    s.push_back(kHex[b & 15]);
  }
  return s;
}

std::string ControlAuthBytes(const vdeform::control_t& msg) {
  std::string s = "vdeform-control-v1";
  AppendU64(&s, uint64_t(msg.utime));
  s.push_back(char(msg.command));
  AppendString(&s, msg.path);
  AppendString(&s, msg.sender);
  return s;
}

void SignControl(const std::string& key, vdeform::control_t* msg) {
  SetMac(Hmac(key, ControlAuthBytes(*msg)), &msg->auth_size, &msg->auth);
}

Status VerifyControl(const std::string& key, const vdeform::control_t& msg) {
  return CheckMac(Hmac(key, ControlAuthBytes(msg)), msg.auth_size, msg.auth, "control message");
}

Status SignFrame(const std::string& key, vdeform::rgbd_frame_t* msg) { return SignMessage(key, msg, "frame"); }

Status VerifyFrame(const std::string& key, const vdeform::rgbd_frame_t& msg) { return VerifyMessage(key, msg, "frame"); }

Status SignMesh(const std::string& key, vdeform::mesh_t* msg) { return SignMessage(key, msg, "mesh"); }

Status VerifyMesh(const std::string& key, const vdeform::mesh_t& msg) { return VerifyMessage(key, msg, "mesh"); }

Status SignStatus(const std::string& key, vdeform::server_status_t* msg) { return SignMessage(key, msg, "status"); }

Status VerifyStatus(const std::string& key, const vdeform::server_status_t& msg) {
  return VerifyMessage(key, msg, "status");
}

int64_t RandomEpoch() {
  int64_t epoch = 0;
  while (epoch == 0) {
    if (RAND_bytes(reinterpret_cast<unsigned char*>(&epoch), sizeof epoch) != 1) {
      // No entropy from OpenSSL: the clock keeps epochs of successive runs apart, which is all a
      // restart needs (a replay is still refused by its older capture time).
      epoch = std::chrono::steady_clock::now().time_since_epoch().count() | 1;
    }
  }
  return epoch;
}

StatusOr<std::string> ReadControlKey(const std::string& path) {
  VD_ASSIGN_OR_RETURN(std::string key, ReadPrivateFile(path, "control key file"));
  while (!key.empty() && std::isspace(static_cast<unsigned char>(key.back()))) key.pop_back();
  if (key.size() < kMinControlKeyBytes)
    return InvalidArgument("control key in '" + path + "' has " + std::to_string(key.size()) + " bytes; at least " +
                           std::to_string(kMinControlKeyBytes) + " are required");
  return key;
}

const std::string* FrameKeys::For(const std::string& source_id) const {
  if (!all_.empty()) return &all_;
  auto it = per_source_.find(source_id);
  return it == per_source_.end() ? nullptr : &it->second;
}

StatusOr<FrameKeys> FrameKeys::Parse(const std::string& text, const std::string& path, const std::string& what) {
  FrameKeys keys;
  std::map<std::string, int> line_of;
  int single_line = 0;
  std::istringstream in(text);
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    const std::string where = what + " '" + path + "' line " + std::to_string(number) + ": ";
    std::istringstream words(line);
    std::vector<std::string> fields;
    for (std::string w; words >> w;) fields.push_back(w);
    if (fields.empty() || fields[0][0] == '#') continue;
    if (fields.size() > 2)
      return InvalidArgument(where + "expected KEY or SOURCE_ID KEY, got " + std::to_string(fields.size()) + " fields");
    const std::string& hex = fields.back();
    if (hex.size() != 2 * kFrameKeyBytes)
      return InvalidArgument(where + "the key has " + std::to_string(hex.size()) + " characters; " +
                             std::to_string(2 * kFrameKeyBytes) + " hex digits (" + std::to_string(kFrameKeyBytes) +
                             " bytes, openssl rand -hex 32) are required");
    std::string key;
    for (size_t i = 0; i < hex.size(); i += 2) {
      const int hi = HexDigit(hex[i]), lo = HexDigit(hex[i + 1]);
      if (hi < 0 || lo < 0)
        return InvalidArgument(where + "the key is not hexadecimal (character " +
                               std::to_string(hi < 0 ? i + 1 : i + 2) + ")");
      key.push_back(char(hi << 4 | lo));
    }
    if (fields.size() == 1) {
      if (single_line != 0)
        return InvalidArgument(where + "a second key for every source (the first is on line " +
                               std::to_string(single_line) + ")");
      if (!line_of.empty())
        return InvalidArgument(where + "a key for every source among SOURCE_ID KEY lines; use one form");
      single_line = number;
      keys.all_ = std::move(key);
      continue;
    }
    if (single_line != 0)
      return InvalidArgument(where + "SOURCE_ID KEY after the key for every source on line " +
                             std::to_string(single_line) + "; use one form");
    auto [it, inserted] = line_of.emplace(fields[0], number);
    if (!inserted)
      return InvalidArgument(where + "source '" + fields[0] + "' already has a key on line " +
                             std::to_string(it->second));
    keys.per_source_[fields[0]] = std::move(key);
  }
  if (keys.empty()) return InvalidArgument(what + " '" + path + "' holds no key");
  return keys;
}

StatusOr<FrameKeys> ReadFrameKeys(const std::string& path) {
  VD_ASSIGN_OR_RETURN(std::string text, ReadPrivateFile(path, "frame key file"));
  return FrameKeys::Parse(text, path);
}

StatusOr<std::string> ParseOutputKey(const std::string& text, const std::string& path) {
  VD_ASSIGN_OR_RETURN(const FrameKeys keys, FrameKeys::Parse(text, path, "output key file"));
  if (keys.per_source())
    return InvalidArgument("output key file '" + path +
                           "' has SOURCE_ID KEY lines; the server's output has no source: give one line KEY (" +
                           std::to_string(2 * kFrameKeyBytes) + " hex digits, openssl rand -hex 32)");
  return *keys.For("");
}

StatusOr<std::string> ReadOutputKey(const std::string& path) {
  VD_ASSIGN_OR_RETURN(std::string text, ReadPrivateFile(path, "output key file"));
  return ParseOutputKey(text, path);
}

StatusOr<std::string> OutputKeyFromFlag(const std::string& path) {
  if (path.empty()) return std::string();
  return ReadOutputKey(path);
}

}  // namespace vd
