#pragma once
// Authenticated control commands: HMAC-SHA256 (OpenSSL) over a fixed byte layout of a control_t's
// fields, checked by the server when it is given a key file. LCM itself has no authentication.
#include <array>
#include <cstdint>
#include <string>

#include <vdeform/control_t.hpp>

#include "vd/common/status.h"

namespace vd {

using Sha256Digest = std::array<uint8_t, 32>;

// Shortest key accepted: 128 bits.
inline constexpr size_t kMinControlKeyBytes = 16;

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

// Reads a key file: its bytes with trailing whitespace removed; refuses missing, short, and
// group- or world-readable files (a key others can read authenticates nothing).
StatusOr<std::string> ReadControlKey(const std::string& path);

}  // namespace vd
