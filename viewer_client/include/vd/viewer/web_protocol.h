#pragma once
// What vdeform-web says to browsers and what it accepts from them: pure functions, no sockets, so
// the bridge's rules are unit-tested on their own (tests/viewer/web_protocol_test.cpp).
//
// Bridge -> page, over one WebSocket:
//   binary: a mesh, "VDM1" | header length (uint32, little-endian) | JSON header | Draco bytes as
//           the server sent them (undecoded). Header: {"type":"mesh","stream","kind":"live"|
//           "canonical","seq","utime","vertices","triangles","bbox":[6 floats]}.
//   text:   {"type":"status",...} (the server's status) and {"type":"streams",...} (streams heard).
// Page -> bridge (read-only: nothing else is accepted, anything else closes the connection):
//   "request_mesh"   ask the server for its current meshes (rate-limited by the bridge)
//   "stream NAME"    show another stream ("stream " alone: the default stream)
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <vdeform/mesh_t.hpp>
#include <vdeform/server_status_t.hpp>

#include "vd/common/messages.h"
#include "vd/common/status.h"

namespace vd {

inline constexpr char kMeshFrameMagic[] = "VDM1";
// Longest message a page may send; its commands are a few bytes, a stream name at most 64.
inline constexpr size_t kMaxClientMessageBytes = 256;
// The cookie the page's response sets, so its scripts and socket carry the token by themselves.
inline constexpr const char* kTokenCookie = "vdeform_token";

// A JSON string literal: quotes, backslashes and control characters escaped, bytes that are not
// valid UTF-8 replaced by U+FFFD (status messages come from the network).
std::string JsonString(std::string_view text);
// A JSON number; NaN and infinities (which JSON lacks) become null.
std::string JsonNumber(double value);

// The binary message of a Draco mesh. Refuses what a page cannot use: another encoding, an
// invalid kind, negative counts, data_size disagreeing with the bytes.
StatusOr<std::string> MeshFrame(const vdeform::mesh_t& msg, const std::string& stream);
// The status as JSON (state name, counters, reject reasons, fps, latency, stages, memory).
std::string StatusJson(const vdeform::server_status_t& status, const std::string& stream);
// {"type":"streams","streams":[...]} in the order given.
std::string StreamsJson(const std::vector<std::string>& streams);

struct ClientCommand {
  enum class Kind { kRequestMesh, kSelectStream };
  Kind kind = Kind::kRequestMesh;
  std::string stream;
};
// Parses a page's text message; InvalidArgument for anything else (the bridge closes on it).
StatusOr<ClientCommand> ParseClientCommand(std::string_view text);

// The path of a request target without its query ("/a/b?x=1" -> "/a/b").
std::string_view TargetPath(std::string_view target);
// A query parameter of a request target, percent-decoded; nullopt when absent or malformed.
std::optional<std::string> QueryParameter(std::string_view target, std::string_view name);
// A cookie from a Cookie header ("a=1; b=2"); nullopt when absent.
std::optional<std::string> CookieValue(std::string_view cookie_header, std::string_view name);
// The token a request carries: ?token=, then "Authorization: Bearer T", then the cookie.
std::optional<std::string> RequestToken(std::string_view target, std::string_view authorization,
                                        std::string_view cookie);
// Compares in time independent of where they differ (the token is a secret).
bool TokenMatches(std::string_view expected, std::string_view given);
// A token fit for a URL, a header and a cookie: 16..256 characters of [A-Za-z0-9._~-].
Status ValidateToken(std::string_view token);

// Content-Type of a served file by its extension (application/octet-stream when unknown).
const char* MimeType(std::string_view path);

}  // namespace vd
