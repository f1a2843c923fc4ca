#include "vd/viewer/web_protocol.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "vd/common/messages.h"

namespace vd {
namespace {

// Length of the valid UTF-8 sequence at text[i], 0 when it is not one.
size_t Utf8SequenceLength(std::string_view text, size_t i) {
  const auto byte = [&](size_t k) { return static_cast<unsigned char>(text[k]); };
  const unsigned char c = byte(i);
  size_t n = 0;
  uint32_t code = 0;
  if (c < 0x80) return 1;
  if (c >= 0xC2 && c <= 0xDF) n = 2, code = c & 0x1F;
  else if (c >= 0xE0 && c <= 0xEF) n = 3, code = c & 0x0F;
  else if (c >= 0xF0 && c <= 0xF4) n = 4, code = c & 0x07;
  else return 0;
  if (i + n > text.size()) return 0;
  for (size_t k = 1; k < n; ++k) {
    if ((byte(i + k) & 0xC0) != 0x80) return 0;
    code = (code << 6) | (byte(i + k) & 0x3F);
  }
  // Overlong forms, UTF-16 surrogates and code points beyond U+10FFFF are not valid UTF-8.
  if ((n == 3 && code < 0x800) || (n == 4 && (code < 0x10000 || code > 0x10FFFF)) ||
      (code >= 0xD800 && code <= 0xDFFF))
    return 0;
  return n;
}

int HexValue(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

std::optional<std::string> PercentDecode(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (size_t i = 0; i < text.size(); ++i) {
    if (text[i] == '+') {
      out += ' ';
    } else if (text[i] == '%') {
      if (i + 2 >= text.size()) return std::nullopt;
      const int hi = HexValue(text[i + 1]), lo = HexValue(text[i + 2]);
      if (hi < 0 || lo < 0) return std::nullopt;
      out += static_cast<char>(hi * 16 + lo);
      i += 2;
    } else {
      out += text[i];
    }
  }
  return out;
}

// Key/value with `name` in a list split by `separator` (query "&", cookies ";"), spaces trimmed.
std::optional<std::string_view> FindPair(std::string_view list, char separator, std::string_view name) {
  while (!list.empty()) {
    const size_t end = std::min(list.find(separator), list.size());
    std::string_view item = list.substr(0, end);
    list.remove_prefix(std::min(end + 1, list.size()));
    while (!item.empty() && item.front() == ' ') item.remove_prefix(1);
    const size_t eq = item.find('=');
    if (eq != std::string_view::npos && item.substr(0, eq) == name) return item.substr(eq + 1);
  }
  return std::nullopt;
}

std::string_view Trim(std::string_view text) {
  while (!text.empty() && (text.front() == ' ' || text.front() == '\t')) text.remove_prefix(1);
  while (!text.empty() && (text.back() == ' ' || text.back() == '\t' || text.back() == '\r' || text.back() == '\n'))
    text.remove_suffix(1);
  return text;
}

}  // namespace

std::string JsonString(std::string_view text) {
  std::string out = "\"";
  out.reserve(text.size() + 2);
  for (size_t i = 0; i < text.size();) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    const size_t n = Utf8SequenceLength(text, i);
    if (n == 0) {
      out += "\\ufffd";
      ++i;
      continue;
    }
    if (n > 1) {
      out.append(text.substr(i, n));
      i += n;
      continue;
    }
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\r': out += "\\r"; break;
      case '\t': out += "\\t"; break;
      default:
        if (c < 0x20 || c == 0x7F) {
          char escaped[8];
          std::snprintf(escaped, sizeof escaped, "\\u%04x", c);
          out += escaped;
        } else {
          out += static_cast<char>(c);
        }
    }
    ++i;
  }
  out += '"';
  return out;
}

std::string JsonNumber(double value) {
  if (!std::isfinite(value)) return "null";
  char text[32];
  std::snprintf(text, sizeof text, "%.9g", value);
  return text;
}

StatusOr<std::string> MeshFrame(const vdeform::mesh_t& msg, const std::string& stream) {
  if (msg.encoding != vdeform::mesh_t::ENCODING_DRACO)
    return InvalidArgument("mesh seq " + std::to_string(msg.seq) + " has encoding " + std::to_string(msg.encoding) +
                           "; the page decodes Draco only");
  if (msg.kind != vdeform::mesh_t::KIND_LIVE && msg.kind != vdeform::mesh_t::KIND_CANONICAL)
    return InvalidArgument("mesh seq " + std::to_string(msg.seq) + " has kind " + std::to_string(msg.kind));
  if (msg.num_vertices < 0 || msg.num_triangles < 0 || msg.data_size < 0 ||
      static_cast<size_t>(msg.data_size) != msg.data.size())
    return InvalidArgument("mesh seq " + std::to_string(msg.seq) + " has inconsistent sizes (vertices " +
                           std::to_string(msg.num_vertices) + ", triangles " + std::to_string(msg.num_triangles) +
                           ", data_size " + std::to_string(msg.data_size) + ", " + std::to_string(msg.data.size()) +
                           " bytes)");
  std::string header = "{\"type\":\"mesh\",\"stream\":" + JsonString(stream) + ",\"kind\":\"" +
                       (msg.kind == vdeform::mesh_t::KIND_LIVE ? "live" : "canonical") +
                       "\",\"seq\":" + std::to_string(msg.seq) + ",\"utime\":" + std::to_string(msg.utime) +
                       ",\"vertices\":" + std::to_string(msg.num_vertices) +
                       ",\"triangles\":" + std::to_string(msg.num_triangles) + ",\"bbox\":[";
  for (int i = 0; i < 6; ++i) {
    if (i) header += ',';
    header += JsonNumber(i < 3 ? msg.bbox_min[i] : msg.bbox_max[i - 3]);
  }
  header += "]}";
  const uint32_t length = static_cast<uint32_t>(header.size());
  std::string frame;
  frame.reserve(8 + header.size() + msg.data.size());
  frame.append(kMeshFrameMagic, 4);
  for (int shift = 0; shift < 32; shift += 8) frame += static_cast<char>((length >> shift) & 0xFF);
  frame += header;
  frame.append(reinterpret_cast<const char*>(msg.data.data()), msg.data.size());
  return frame;
}

std::string StatusJson(const vdeform::server_status_t& s, const std::string& stream) {
  std::string out = "{\"type\":\"status\",\"stream\":" + JsonString(stream);
  const auto field = [&out](const char* name, const std::string& value) {
    out += ",\"";
    out += name;
    out += "\":";
    out += value;
  };
  const auto integer = [&field](const char* name, int64_t value) { field(name, std::to_string(value)); };
  field("state", JsonString(ServerStateName(s.state)));
  field("message", JsonString(s.message));
  integer("utime", s.utime);
  integer("frames_received", s.frames_received);
  integer("frames_processed", s.frames_processed);
  integer("frames_dropped", s.frames_dropped);
  integer("frames_rejected", s.frames_rejected);
  integer("frames_lost", s.frames_lost);
  integer("frames_duplicate", s.frames_duplicate);
  integer("frames_reordered", s.frames_reordered);
  integer("frames_rate_limited", s.frames_rate_limited);
  integer("control_refused", s.control_refused);
  integer("last_processed_seq", s.last_processed_seq);
  integer("active_voxels", s.active_voxels);
  integer("resident_memory_bytes", s.resident_memory_bytes);
  integer("model_frames", s.model_frames);
  field("fps", JsonNumber(s.fps));
  field("latency_ms_last", JsonNumber(s.latency_ms_last));
  field("latency_ms_p50", JsonNumber(s.latency_ms_p50));
  field("latency_ms_p95", JsonNumber(s.latency_ms_p95));
  // Arrays bounded by their count and by what was decoded, whichever is shorter.
  const size_t reasons = std::min({static_cast<size_t>(std::max(s.num_reject_reasons, 0)), s.reject_reason.size(),
                                   s.reject_count.size()});
  out += ",\"reject_reasons\":{";
  for (size_t i = 0; i < reasons; ++i) {
    if (i) out += ',';
    out += JsonString(s.reject_reason[i]) + ":" + std::to_string(s.reject_count[i]);
  }
  out += "}";
  const size_t stages = std::min({static_cast<size_t>(std::max(s.num_stages, 0)), s.stage_name.size(),
                                  s.stage_ms_last.size(), s.stage_ms_mean.size()});
  out += ",\"stages\":[";
  for (size_t i = 0; i < stages; ++i) {
    if (i) out += ',';
    out += "{\"name\":" + JsonString(s.stage_name[i]) + ",\"last_ms\":" + JsonNumber(s.stage_ms_last[i]) +
           ",\"mean_ms\":" + JsonNumber(s.stage_ms_mean[i]) + "}";
  }
  out += "]}";
  return out;
}

std::string StreamsJson(const std::vector<std::string>& streams) {
  std::string out = "{\"type\":\"streams\",\"streams\":[";
  for (size_t i = 0; i < streams.size(); ++i) {
    if (i) out += ',';
    out += JsonString(streams[i]);
  }
  return out + "]}";
}

StatusOr<ClientCommand> ParseClientCommand(std::string_view text) {
  if (text.size() > kMaxClientMessageBytes)
    return InvalidArgument("a command of " + std::to_string(text.size()) + " bytes (at most " +
                           std::to_string(kMaxClientMessageBytes) + ")");
  ClientCommand command;
  if (text == "request_mesh") return command;
  constexpr std::string_view kStream = "stream ";
  if (text.substr(0, kStream.size()) == kStream) {
    command.kind = ClientCommand::Kind::kSelectStream;
    command.stream = std::string(text.substr(kStream.size()));
    VD_RETURN_IF_ERROR(ValidateStreamName(command.stream));
    return command;
  }
  std::string shown(text.substr(0, 32));
  for (char& c : shown)
    if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) >= 0x7F) c = '?';
  return InvalidArgument("unknown command '" + shown + "' (the page may send request_mesh or stream NAME)");
}

std::string_view TargetPath(std::string_view target) { return target.substr(0, target.find('?')); }

std::optional<std::string> QueryParameter(std::string_view target, std::string_view name) {
  const size_t q = target.find('?');
  if (q == std::string_view::npos) return std::nullopt;
  std::string_view query = target.substr(q + 1);
  query = query.substr(0, query.find('#'));
  const std::optional<std::string_view> value = FindPair(query, '&', name);
  if (!value) return std::nullopt;
  return PercentDecode(*value);
}

std::optional<std::string> CookieValue(std::string_view cookie_header, std::string_view name) {
  const std::optional<std::string_view> value = FindPair(cookie_header, ';', name);
  if (!value) return std::nullopt;
  return std::string(Trim(*value));
}

std::optional<std::string> RequestToken(std::string_view target, std::string_view authorization,
                                        std::string_view cookie) {
  if (std::optional<std::string> query = QueryParameter(target, "token")) return query;
  constexpr std::string_view kBearer = "Bearer ";
  authorization = Trim(authorization);
  if (authorization.size() > kBearer.size() && authorization.substr(0, kBearer.size()) == kBearer)
    return std::string(Trim(authorization.substr(kBearer.size())));
  return CookieValue(cookie, kTokenCookie);
}

bool TokenMatches(std::string_view expected, std::string_view given) {
  // The length is not secret (ValidateToken bounds it); the bytes are compared without an early exit.
  if (expected.empty() || expected.size() != given.size()) return false;
  unsigned char diff = 0;
  for (size_t i = 0; i < expected.size(); ++i)
    diff |= static_cast<unsigned char>(expected[i]) ^ static_cast<unsigned char>(given[i]);
  return diff == 0;
}

Status ValidateToken(std::string_view token) {
  if (token.size() < 16 || token.size() > 256)
    return InvalidArgument("the token has " + std::to_string(token.size()) +
                           " characters; 16 to 256 are required (e.g. openssl rand -hex 32)");
  for (char c : token) {
    const bool ok = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '.' ||
                    c == '_' || c == '~' || c == '-';
    if (!ok) return InvalidArgument("the token may hold only A-Z a-z 0-9 . _ ~ - (it travels in URLs and cookies)");
  }
  return Status::Ok();
}

const char* MimeType(std::string_view path) {
  const size_t dot = path.rfind('.');
  const std::string_view ext = dot == std::string_view::npos ? std::string_view() : path.substr(dot + 1);
  if (ext == "html") return "text/html; charset=utf-8";
  if (ext == "js" || ext == "mjs") return "text/javascript; charset=utf-8";
  if (ext == "css") return "text/css; charset=utf-8";
  if (ext == "wasm") return "application/wasm";
  if (ext == "json") return "application/json";
  if (ext == "png") return "image/png";
  if (ext == "svg") return "image/svg+xml";
  if (ext == "txt" || ext == "md") return "text/plain; charset=utf-8";
  return "application/octet-stream";
}

}  // namespace vd
