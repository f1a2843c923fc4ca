#include "vd/common/auth.h"

#include <sys/stat.h>

#include <cstring>
#include <fstream>
#include <sstream>

#include <openssl/crypto.h>
#include <openssl/evp.h>
#include <openssl/hmac.h>

namespace vd {
namespace {

void AppendU64(std::string* s, uint64_t v) {
  for (int i = 0; i < 8; ++i) s->push_back(char((v >> (8 * i)) & 0xff));
}
void AppendString(std::string* s, const std::string& v) {
  AppendU64(s, v.size());
  s->append(v);
}

}  // namespace

Sha256Digest HmacSha256(const std::string& key, const std::string& data) {
  Sha256Digest out{};
  unsigned int len = 0;
  HMAC(EVP_sha256(), key.data(), int(key.size()), reinterpret_cast<const unsigned char*>(data.data()), data.size(),
       out.data(), &len);
  return out;
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
  const Sha256Digest mac = HmacSha256(key, ControlAuthBytes(*msg));
  msg->auth.assign(mac.begin(), mac.end());
  msg->auth_size = int32_t(mac.size());
}

Status VerifyControl(const std::string& key, const vdeform::control_t& msg) {
  if (msg.auth_size != 32 || msg.auth.size() != 32)
    return PermissionDenied("control message carries no HMAC-SHA256 (auth_size " + std::to_string(msg.auth_size) + ")");
  const Sha256Digest mac = HmacSha256(key, ControlAuthBytes(msg));
  if (CRYPTO_memcmp(mac.data(), msg.auth.data(), mac.size()) != 0)
    return PermissionDenied("control message HMAC does not match the server's key");
  return Status::Ok();
}

StatusOr<std::string> ReadControlKey(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return NotFound("control key file '" + path + "': " + std::strerror(errno));
  if (!S_ISREG(st.st_mode)) return InvalidArgument("control key file '" + path + "' is not a regular file");
  if (st.st_mode & (S_IRWXG | S_IRWXO))
    return PermissionDenied("control key file '" + path + "' is readable by group or others (chmod 600 it)");
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  if (!in) return Unavailable("cannot read control key file '" + path + "'");
  std::string key = ss.str();
  while (!key.empty() && std::isspace(static_cast<unsigned char>(key.back()))) key.pop_back();
  if (key.size() < kMinControlKeyBytes)
    return InvalidArgument("control key in '" + path + "' has " + std::to_string(key.size()) + " bytes; at least " +
                           std::to_string(kMinControlKeyBytes) + " are required");
  return key;
}

}  // namespace vd
