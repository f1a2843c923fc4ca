#pragma once
// vdeform-web's HTTP and WebSocket side (Boost.Beast on one Asio thread): serves the page's files
// from memory, and forwards the newest mesh and status of each stream to every connected page.
//
// Bounded by construction: a page holds at most one message in flight and one waiting per kind
// (live mesh, canonical mesh, status, stream list); a newer message replaces the waiting one, so a
// page that reads slowly gets only the newest mesh and costs no memory beyond those slots (the
// payloads are shared between pages). Connections are bounded (max_clients WebSockets, plus
// kHttpConnectionSlots plain HTTP connections); a page's oversized or malformed message closes
// that connection alone.
#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "vd/common/status.h"

namespace vd {

// Plain HTTP connections (loading the page and its scripts) allowed beside the WebSockets.
inline constexpr int kHttpConnectionSlots = 16;
// Streams the bridge keeps state for; meshes of further names are counted and dropped.
inline constexpr size_t kMaxStreams = 32;

// The files the page is made of, read once at start-up: URL path ("/index.html") -> bytes.
class WebAssets {
 public:
  // Every regular file below `root` (the build's web folder: the page and the vendored npm
  // files); fails when index.html is missing or the folder holds more than 64 MB.
  static StatusOr<WebAssets> Load(const std::string& root);
  // For tests: a single page with the given body.
  static WebAssets FromFiles(std::map<std::string, std::string> files);
  const std::string* Find(const std::string& path) const;
  size_t size() const { return files_.size(); }

 private:
  std::map<std::string, std::string> files_;
};

struct WebServerOptions {
  // Address to listen on; a loopback address keeps the page on this host.
  std::string bind = "127.0.0.1";
  // TCP port; 0 picks a free one (tests), see WebServer::port().
  int port = 8080;
  // When non-empty, every request (page, files, socket) must carry it (ValidateToken), else 403.
  std::string token;
  // WebSocket clients at once; one more gets 503.
  int max_clients = 16;
  // A write to a page that has not finished after this many seconds closes it (a stalled reader
  // would hold its slot forever).
  double write_timeout_s = 30.0;
  Status Validate() const;
};

struct WebServerStats {
  int64_t clients = 0;
  int64_t clients_peak = 0;
  int64_t connections = 0;
  int64_t http_requests = 0;
  // Requests refused: 403 (no or wrong token), 503 (max_clients reached) or dropped at accept
  // (all connection slots taken).
  int64_t forbidden = 0;
  int64_t refused_full = 0;
  int64_t refused_connections = 0;
  // Connections closed for bad input: oversized, malformed or unknown WebSocket messages.
  int64_t closed_bad_input = 0;
  // Connections closed because a write stalled beyond write_timeout_s.
  int64_t closed_stalled = 0;
  int64_t meshes_sent = 0;
  // Meshes replaced in a page's slot before it could take them (a slow reader).
  int64_t meshes_replaced = 0;
  int64_t status_sent = 0;
  int64_t bytes_sent = 0;
  // Messages waiting in pages' slots right now (at most 4 per client).
  int64_t queued_messages = 0;
  // Meshes of stream names beyond kMaxStreams, dropped.
  int64_t streams_refused = 0;
};

class WebServer {
 public:
  // Asked from the server's thread when a page wants the current meshes of `stream` (at connect
  // when the bridge holds none, or by its request_mesh command). Must be cheap and thread-safe.
  using MeshRequest = std::function<void(const std::string& stream)>;

  // Binds, listens and starts the server thread.
  static StatusOr<std::unique_ptr<WebServer>> Start(const WebServerOptions& options, WebAssets assets,
                                                    MeshRequest on_request);
  // Stops: closes every connection and joins the thread.
  ~WebServer();
  WebServer(const WebServer&) = delete;
  WebServer& operator=(const WebServer&) = delete;

  // Thread-safe. Hands the newest mesh (a MeshFrame) or status (StatusJson) of `stream` to the
  // pages showing it, and keeps it for pages that connect later.
  void PublishMesh(const std::string& stream, bool live, std::string frame);
  void PublishStatus(const std::string& stream, std::string json);

  // The port actually bound.
  int port() const;
  // A consistent copy, thread-safe.
  WebServerStats stats() const;

  class Impl;

 private:
  explicit WebServer(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// Whether an address is a loopback one (127.0.0.0/8, ::1, "localhost"): binding elsewhere
// without a token exposes the page.
bool IsLoopbackAddress(const std::string& address);

}  // namespace vd
