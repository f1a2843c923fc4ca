#include "vd/viewer/web_server.h"

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <future>
#include <mutex>
#include <optional>
#include <set>
#include <sstream>
#include <thread>

#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>

#include "vd/common/log.h"
#include "vd/viewer/web_protocol.h"

namespace vd {
namespace {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;
using Payload = std::shared_ptr<const std::string>;

std::string_view View(beast::string_view text) { return std::string_view(text.data(), text.size()); }

// A request's headers must fit; the page's requests are a few hundred bytes.
constexpr uint32_t kMaxRequestHeaderBytes = 8192;
// An HTTP connection that sends no complete request within this time is closed.
constexpr auto kHttpReadTimeout = std::chrono::seconds(15);
// What Load accepts below the web root: the page and its vendored libraries are ~4 MB.
constexpr uintmax_t kMaxAssetBytes = 64u << 20;

class Hub;

// Holds one of the bounded connection slots for as long as the connection lives (HTTP, then
// WebSocket after an upgrade).
class ConnectionSlot {
 public:
  explicit ConnectionSlot(std::shared_ptr<Hub> hub);
  ~ConnectionSlot();
  ConnectionSlot(const ConnectionSlot&) = delete;
  ConnectionSlot& operator=(const ConnectionSlot&) = delete;

 private:
  std::shared_ptr<Hub> hub_;
};

class WsSession;
class HttpSession;

struct StreamState {
  Payload live, canonical, status;
};

// All state of the server thread: streams, sessions, statistics. Sessions hold it by shared_ptr,
// so it outlives every one of them, also while the io_context destroys pending handlers.
class Hub : public std::enable_shared_from_this<Hub> {
 public:
  Hub(const WebServerOptions& options, WebAssets assets, WebServer::MeshRequest on_request)
      : options_(options), assets_(std::move(assets)), on_request_(std::move(on_request)) {}

  const WebServerOptions& options() const { return options_; }
  const WebAssets& assets() const { return assets_; }

  // Statistics, under the mutex (read from other threads).
  template <typename F>
  void Count(F&& update) {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    update(stats_);
  }
  WebServerStats Stats() const {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    return stats_;
  }

  bool ConnectionAvailable() {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    return stats_.connections < options_.max_clients + kHttpConnectionSlots;
  }
  // Counts pages still in their handshake too, so a burst of upgrades cannot pass the limit.
  bool ClientAvailable() const { return ws_sessions_.size() < static_cast<size_t>(options_.max_clients); }

  void Attach(WsSession* session);
  void Detach(WsSession* session);
  void Select(WsSession* session, const std::string& stream);
  void Request(const std::string& stream) {
    if (on_request_) on_request_(stream);
  }
  void OnMesh(const std::string& stream, bool live, Payload frame);
  void OnStatus(const std::string& stream, Payload json);

  // Every live connection, for CloseAll (a page between its upgrade and Attach included).
  void Register(HttpSession* session) { http_sessions_.insert(session); }
  void Unregister(HttpSession* session) { http_sessions_.erase(session); }
  void Register(WsSession* session) { ws_sessions_.insert(session); }
  void Unregister(WsSession* session) { ws_sessions_.erase(session); }
  // Closes every connection; pending operations complete with errors and the sessions end.
  void CloseAll();

 private:
  // The stream a session shows: its choice, else the first stream heard.
  std::optional<std::string> StreamOf(const WsSession* session) const;
  StreamState* FindOrAdd(const std::string& stream, bool* added);
  void SendStream(WsSession* session);

  WebServerOptions options_;
  WebAssets assets_;
  WebServer::MeshRequest on_request_;
  std::map<std::string, StreamState> streams_;
  std::vector<std::string> stream_order_;
  Payload streams_json_;
  std::set<WsSession*> sessions_;
  std::set<HttpSession*> http_sessions_;
  std::set<WsSession*> ws_sessions_;
  mutable std::mutex stats_mutex_;
  WebServerStats stats_;
};

ConnectionSlot::ConnectionSlot(std::shared_ptr<Hub> hub) : hub_(std::move(hub)) {
  hub_->Count([](WebServerStats& s) { ++s.connections; });
}
ConnectionSlot::~ConnectionSlot() {
  hub_->Count([](WebServerStats& s) { --s.connections; });
}

// One page's socket. Slots hold the next message of each kind; DoWrite sends one at a time.
class WsSession : public std::enable_shared_from_this<WsSession> {
 public:
  enum Slot { kStreams = 0, kStatus, kLive, kCanonical, kNumSlots };

  WsSession(tcp::socket socket, std::shared_ptr<Hub> hub, std::unique_ptr<ConnectionSlot> slot)
      : ws_(std::move(socket)), write_timer_(ws_.get_executor()), hub_(std::move(hub)), slot_(std::move(slot)) {
    hub_->Register(this);
  }
  ~WsSession() {
    Detach();
    hub_->Unregister(this);
  }

  void Run(http::request<http::empty_body> request) {
    if (std::optional<std::string> stream = QueryParameter(View(request.target()), "stream");
        stream && ValidateStreamName(*stream).ok()) {
      chosen_stream_ = *stream;
    }
    ws_.set_option(websocket::stream_base::timeout::suggested(beast::role_type::server));
    ws_.read_message_max(kMaxClientMessageBytes);
    ws_.async_accept(request, [self = shared_from_this()](beast::error_code ec) { self->OnAccept(ec); });
  }

  const std::optional<std::string>& chosen_stream() const { return chosen_stream_; }
  void Choose(const std::string& stream) { chosen_stream_ = stream; }

  void Enqueue(Slot slot, Payload payload) {
    if (closed_ || !payload) return;
    if (slots_[slot]) {
      if (slot == kLive || slot == kCanonical) hub_->Count([](WebServerStats& s) { ++s.meshes_replaced; });
    } else {
      hub_->Count([](WebServerStats& s) { ++s.queued_messages; });
    }
    slots_[slot] = std::move(payload);
    DoWrite();
  }

  void Close() {
    beast::error_code ignored;
    beast::get_lowest_layer(ws_).socket().close(ignored);
  }

 private:
  void OnAccept(beast::error_code ec) {
    if (ec) {
      Detach();
      return;
    }
    attached_ = true;
    hub_->Attach(this);
    DoRead();
  }

  void DoRead() {
    ws_.async_read(read_buffer_, [self = shared_from_this()](beast::error_code ec, size_t) { self->OnRead(ec); });
  }

  void OnRead(beast::error_code ec) {
    if (ec) {
      // A clean close, our own close or a vanished peer is no bad input; anything else
      // (message_too_big, protocol violations) is, and Beast has already failed the connection.
      const bool bad = ec != websocket::error::closed && ec != net::error::operation_aborted &&
                       ec != http::error::end_of_stream && ec != net::error::eof &&
                       ec != net::error::connection_reset && ec != beast::error::timeout &&
                       ec != net::error::bad_descriptor;
      if (bad) {
        hub_->Count([](WebServerStats& s) { ++s.closed_bad_input; });
        VD_LOG_DEBUG << "closed a page's connection: " << ec.message();
      }
      Detach();
      return;
    }
    if (!ws_.got_text()) return FailBadInput(websocket::close_code::unknown_data, "binary messages are not accepted");
    const std::string text = beast::buffers_to_string(read_buffer_.data());
    read_buffer_.consume(read_buffer_.size());
    StatusOr<ClientCommand> command = ParseClientCommand(text);
    if (!command.ok()) return FailBadInput(websocket::close_code::policy_error, command.status().message());
    if (command->kind == ClientCommand::Kind::kRequestMesh) {
      const std::optional<std::string>& stream = chosen_stream_;
      hub_->Request(stream.value_or(""));
    } else {
      hub_->Select(this, command->stream);
    }
    DoRead();
  }

  void FailBadInput(websocket::close_code code, const std::string& reason) {
    hub_->Count([](WebServerStats& s) { ++s.closed_bad_input; });
    Detach();
    // A message frame of ours still going out would interleave with a close frame: just hang up.
    if (writing_) return Close();
    // Otherwise say why (the reason is limited to 123 bytes), and hang up if the peer does not
    // answer the close within a second.
    ws_.async_close(websocket::close_reason(code, reason.substr(0, 120)),
                    [self = shared_from_this()](beast::error_code) { self->Close(); });
    write_timer_.expires_after(std::chrono::seconds(1));
    write_timer_.async_wait([self = shared_from_this()](beast::error_code ec) {
      if (!ec) self->Close();
    });
  }

  void DoWrite() {
    if (writing_ || closed_) return;
    int next = -1;
    for (int slot = 0; slot < kNumSlots && next < 0; ++slot)
      if (slots_[slot]) next = slot;
    if (next < 0) return;
    in_flight_ = std::move(slots_[next]);
    slots_[next].reset();
    hub_->Count([](WebServerStats& s) { --s.queued_messages; });
    writing_ = true;
    const bool mesh = next == kLive || next == kCanonical;
    ws_.binary(mesh);
    write_timer_.expires_after(std::chrono::duration_cast<std::chrono::steady_clock::duration>(
        std::chrono::duration<double>(hub_->options().write_timeout_s)));
    write_timer_.async_wait([self = shared_from_this()](beast::error_code ec) {
      if (ec || !self->writing_) return;
      self->hub_->Count([](WebServerStats& s) { ++s.closed_stalled; });
      self->Detach();
      self->Close();
    });
    ws_.async_write(net::buffer(*in_flight_), [self = shared_from_this(), mesh](beast::error_code ec, size_t bytes) {
      self->OnWrite(ec, bytes, mesh);
    });
  }

  void OnWrite(beast::error_code ec, size_t bytes, bool mesh) {
    writing_ = false;
    write_timer_.cancel();
    in_flight_.reset();
    if (ec) {
      Detach();
      return;
    }
    hub_->Count([&](WebServerStats& s) {
      s.bytes_sent += static_cast<int64_t>(bytes);
      if (mesh) ++s.meshes_sent;
      else ++s.status_sent;
    });
    DoWrite();
  }

  // Leaves the hub once: no more messages are queued for this page.
  void Detach() {
    if (closed_) return;
    closed_ = true;
    int64_t waiting = 0;
    for (Payload& p : slots_) {
      if (p) ++waiting;
      p.reset();
    }
    hub_->Count([waiting](WebServerStats& s) { s.queued_messages -= waiting; });
    if (attached_) hub_->Detach(this);
    attached_ = false;
  }

  websocket::stream<beast::tcp_stream> ws_;
  beast::flat_buffer read_buffer_;
  net::steady_timer write_timer_;
  std::shared_ptr<Hub> hub_;
  std::unique_ptr<ConnectionSlot> slot_;
  std::optional<std::string> chosen_stream_;
  Payload slots_[kNumSlots];
  Payload in_flight_;
  bool writing_ = false;
  bool closed_ = false;
  bool attached_ = false;
};

std::optional<std::string> Hub::StreamOf(const WsSession* session) const {
  if (session->chosen_stream()) return session->chosen_stream();
  if (stream_order_.empty()) return std::nullopt;
  return stream_order_.front();
}

void Hub::SendStream(WsSession* session) {
  const std::optional<std::string> stream = StreamOf(session);
  bool have_live = false;
  if (stream) {
    auto it = streams_.find(*stream);
    if (it != streams_.end()) {
      session->Enqueue(WsSession::kStatus, it->second.status);
      session->Enqueue(WsSession::kCanonical, it->second.canonical);
      session->Enqueue(WsSession::kLive, it->second.live);
      have_live = it->second.live != nullptr;
    }
  }
  // Nothing held for it yet: ask the server (through the bridge's rate limit).
  if (!have_live) Request(stream.value_or(""));
}

void Hub::Attach(WsSession* session) {
  sessions_.insert(session);
  Count([](WebServerStats& s) {
    ++s.clients;
    s.clients_peak = std::max(s.clients_peak, s.clients);
  });
  session->Enqueue(WsSession::kStreams, streams_json_ ? streams_json_
                                                      : std::make_shared<const std::string>(StreamsJson({})));
  SendStream(session);
}

void Hub::Detach(WsSession* session) {
  if (sessions_.erase(session)) Count([](WebServerStats& s) { --s.clients; });
}

void Hub::Select(WsSession* session, const std::string& stream) {
  session->Choose(stream);
  SendStream(session);
}

StreamState* Hub::FindOrAdd(const std::string& stream, bool* added) {
  *added = false;
  auto it = streams_.find(stream);
  if (it != streams_.end()) return &it->second;
  if (streams_.size() >= kMaxStreams) {
    Count([](WebServerStats& s) { ++s.streams_refused; });
    return nullptr;
  }
  *added = true;
  stream_order_.push_back(stream);
  streams_json_ = std::make_shared<const std::string>(StreamsJson(stream_order_));
  return &streams_[stream];
}

void Hub::OnMesh(const std::string& stream, bool live, Payload frame) {
  bool added = false;
  StreamState* state = FindOrAdd(stream, &added);
  if (!state) return;
  (live ? state->live : state->canonical) = frame;
  for (WsSession* session : sessions_) {
    if (added) session->Enqueue(WsSession::kStreams, streams_json_);
    if (StreamOf(session) == stream) session->Enqueue(live ? WsSession::kLive : WsSession::kCanonical, frame);
  }
}

void Hub::OnStatus(const std::string& stream, Payload json) {
  bool added = false;
  StreamState* state = FindOrAdd(stream, &added);
  if (!state) return;
  state->status = json;
  for (WsSession* session : sessions_) {
    if (added) session->Enqueue(WsSession::kStreams, streams_json_);
    if (StreamOf(session) == stream) session->Enqueue(WsSession::kStatus, json);
  }
}

// One plain HTTP connection: the page and its files, or the upgrade to a WebSocket.
class HttpSession : public std::enable_shared_from_this<HttpSession> {
 public:
  HttpSession(tcp::socket socket, std::shared_ptr<Hub> hub)
      : stream_(std::move(socket)), hub_(std::move(hub)), slot_(std::make_unique<ConnectionSlot>(hub_)) {
    hub_->Register(this);
  }
  ~HttpSession() { hub_->Unregister(this); }

  void Run() { DoRead(); }
  void Close() {
    beast::error_code ignored;
    stream_.socket().close(ignored);
  }

 private:
  void DoRead() {
    parser_.emplace();
    parser_->header_limit(kMaxRequestHeaderBytes);
    parser_->body_limit(0);
    stream_.expires_after(kHttpReadTimeout);
    http::async_read(stream_, buffer_, *parser_,
                     [self = shared_from_this()](beast::error_code ec, size_t) { self->OnRead(ec); });
  }

  void OnRead(beast::error_code ec) {
    if (ec) {
      Close();
      return;
    }
    http::request<http::empty_body> request = parser_->release();
    hub_->Count([](WebServerStats& s) { ++s.http_requests; });
    const WebServerOptions& options = hub_->options();
    const std::string target(request.target());
    if (!options.token.empty()) {
      const std::optional<std::string> token =
          RequestToken(target, View(request[http::field::authorization]), View(request[http::field::cookie]));
      if (!token || !TokenMatches(options.token, *token)) {
        hub_->Count([](WebServerStats& s) { ++s.forbidden; });
        return Respond(request, http::status::forbidden, "text/plain; charset=utf-8",
                       "403 forbidden: this vdeform-web needs its token (?token=...)\n", false);
      }
    }
    const std::string path(TargetPath(target));
    if (websocket::is_upgrade(request)) {
      if (path != "/ws") return Respond(request, http::status::not_found, "text/plain", "no socket here\n", false);
      if (!hub_->ClientAvailable()) {
        hub_->Count([](WebServerStats& s) { ++s.refused_full; });
        return Respond(request, http::status::service_unavailable, "text/plain; charset=utf-8",
                       "503: " + std::to_string(options.max_clients) + " clients already (--max-clients)\n", false);
      }
      stream_.expires_never();
      auto session = std::make_shared<WsSession>(stream_.release_socket(), hub_, std::move(slot_));
      session->Run(std::move(request));
      return;
    }
    if (request.method() != http::verb::get && request.method() != http::verb::head)
      return Respond(request, http::status::method_not_allowed, "text/plain", "only GET and HEAD\n", false);
    const std::string* body = hub_->assets().Find(path == "/" ? "/index.html" : path);
    if (!body) return Respond(request, http::status::not_found, "text/plain", "404 not found\n", true);
    // A token given in the URL becomes a cookie, so the page's scripts and socket carry it.
    const bool set_cookie = !options.token.empty() && QueryParameter(target, "token").has_value();
    Respond(request, http::status::ok, MimeType(path == "/" ? "/index.html" : path), *body, true, set_cookie);
  }

  void Respond(const http::request<http::empty_body>& request, http::status status, const char* type,
               const std::string& body, bool keep_alive, bool set_cookie = false) {
    auto response = std::make_shared<http::response<http::string_body>>(status, request.version());
    response->set(http::field::server, "vdeform-web");
    response->set(http::field::content_type, type);
    response->set(http::field::cache_control, "no-cache");
    response->set("X-Content-Type-Options", "nosniff");
    response->set("Referrer-Policy", "no-referrer");
    if (set_cookie)
      response->set(http::field::set_cookie,
                    std::string(kTokenCookie) + "=" + hub_->options().token + "; Path=/; HttpOnly; SameSite=Strict");
    keep_alive = keep_alive && request.keep_alive();
    response->keep_alive(keep_alive);
    if (request.method() == http::verb::head) {
      response->content_length(body.size());
    } else {
      response->body() = body;
      response->prepare_payload();
    }
    http::async_write(stream_, *response,
                      [self = shared_from_this(), response, keep_alive](beast::error_code ec, size_t) {
                        if (ec || !keep_alive) {
                          beast::error_code ignored;
                          self->stream_.socket().shutdown(tcp::socket::shutdown_send, ignored);
                          self->Close();
                          return;
                        }
                        self->DoRead();
                      });
  }

  beast::tcp_stream stream_;
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::empty_body>> parser_;
  std::shared_ptr<Hub> hub_;
  std::unique_ptr<ConnectionSlot> slot_;
};

void Hub::CloseAll() {
  for (WsSession* session : std::vector<WsSession*>(ws_sessions_.begin(), ws_sessions_.end())) session->Close();
  for (HttpSession* session : std::vector<HttpSession*>(http_sessions_.begin(), http_sessions_.end()))
    session->Close();
}

}  // namespace

StatusOr<WebAssets> WebAssets::Load(const std::string& root) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::is_directory(root, ec))
    return NotFound("web folder '" + root + "' does not exist (build vdeform-web, or give --web-root)");
  WebAssets assets;
  uintmax_t total = 0;
  for (fs::recursive_directory_iterator it(root, ec), end; !ec && it != end; it.increment(ec)) {
    if (!it->is_regular_file(ec)) continue;
    total += it->file_size(ec);
    if (total > kMaxAssetBytes)
      return OutOfRange("web folder '" + root + "' holds more than " + std::to_string(kMaxAssetBytes >> 20) + " MB");
    std::ifstream in(it->path(), std::ios::binary);
    std::ostringstream bytes;
    bytes << in.rdbuf();
    if (!in) return Unavailable("cannot read " + it->path().string());
    assets.files_["/" + fs::relative(it->path(), root).generic_string()] = bytes.str();
  }
  if (ec) return Unavailable("cannot list web folder '" + root + "': " + ec.message());
  if (!assets.Find("/index.html")) return NotFound("web folder '" + root + "' has no index.html");
  return assets;
}

WebAssets WebAssets::FromFiles(std::map<std::string, std::string> files) {
  WebAssets assets;
  assets.files_ = std::move(files);
  return assets;
}

const std::string* WebAssets::Find(const std::string& path) const {
  auto it = files_.find(path);
  return it == files_.end() ? nullptr : &it->second;
}

Status WebServerOptions::Validate() const {
  if (port < 0 || port > 65535)
    return InvalidArgument("WebServerOptions.port = " + std::to_string(port) + " violates 0 <= port <= 65535");
  if (max_clients < 1 || max_clients > 1024)
    return InvalidArgument("WebServerOptions.max_clients = " + std::to_string(max_clients) +
                           " violates 1 <= max_clients <= 1024");
  if (!(write_timeout_s >= 0.1 && write_timeout_s <= 3600))
    return InvalidArgument("WebServerOptions.write_timeout_s = " + std::to_string(write_timeout_s) +
                           " violates 0.1 <= write_timeout_s <= 3600");
  if (!token.empty()) VD_RETURN_IF_ERROR(ValidateToken(token));
  beast::error_code ec;
  net::ip::make_address(bind == "localhost" ? "127.0.0.1" : bind, ec);
  if (ec) return InvalidArgument("WebServerOptions.bind = '" + bind + "' is not an IP address: " + ec.message());
  return Status::Ok();
}

class WebServer::Impl {
 public:
  Impl(const WebServerOptions& options, WebAssets assets, MeshRequest on_request)
      : hub_(std::make_shared<Hub>(options, std::move(assets), std::move(on_request))), acceptor_(ioc_) {}

  Status Listen() {
    const WebServerOptions& options = hub_->options();
    beast::error_code ec;
    const auto address = net::ip::make_address(options.bind == "localhost" ? "127.0.0.1" : options.bind, ec);
    const tcp::endpoint endpoint(address, static_cast<unsigned short>(options.port));
    const std::string where = options.bind + ":" + std::to_string(options.port);
    if (!ec) acceptor_.open(endpoint.protocol(), ec);
    if (!ec) acceptor_.set_option(net::socket_base::reuse_address(true), ec);
    if (!ec) acceptor_.bind(endpoint, ec);
    if (!ec) acceptor_.listen(net::socket_base::max_listen_connections, ec);
    if (ec) return Unavailable("cannot listen on " + where + ": " + ec.message());
    port_ = acceptor_.local_endpoint().port();
    DoAccept();
    thread_ = std::thread([this] {
      ioc_.run();
      done_.set_value();
    });
    return Status::Ok();
  }

  ~Impl() {
    if (!thread_.joinable()) return;
    net::post(ioc_, [this] {
      beast::error_code ignored;
      acceptor_.close(ignored);
      hub_->CloseAll();
    });
    // Closing every socket ends every operation; a run that has not ended in 2 s is stopped.
    if (done_future_.wait_for(std::chrono::seconds(2)) != std::future_status::ready) ioc_.stop();
    thread_.join();
  }

  void DoAccept() {
    acceptor_.async_accept([this](beast::error_code ec, tcp::socket socket) {
      if (ec == net::error::operation_aborted || !acceptor_.is_open()) return;
      if (!ec) {
        if (hub_->ConnectionAvailable()) {
          std::make_shared<HttpSession>(std::move(socket), hub_)->Run();
        } else {
          hub_->Count([](WebServerStats& s) { ++s.refused_connections; });
          beast::error_code ignored;
          socket.close(ignored);
        }
      }
      DoAccept();
    });
  }

  net::io_context ioc_{1};
  std::shared_ptr<Hub> hub_;
  tcp::acceptor acceptor_;
  std::thread thread_;
  std::promise<void> done_;
  std::future<void> done_future_ = done_.get_future();
  int port_ = 0;
};

StatusOr<std::unique_ptr<WebServer>> WebServer::Start(const WebServerOptions& options, WebAssets assets,
                                                      MeshRequest on_request) {
  VD_RETURN_IF_ERROR(options.Validate());
  auto impl = std::make_unique<Impl>(options, std::move(assets), std::move(on_request));
  VD_RETURN_IF_ERROR(impl->Listen());
  return std::unique_ptr<WebServer>(new WebServer(std::move(impl)));
}

WebServer::WebServer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
WebServer::~WebServer() = default;

void WebServer::PublishMesh(const std::string& stream, bool live, std::string frame) {
  auto payload = std::make_shared<const std::string>(std::move(frame));
  net::post(impl_->ioc_, [hub = impl_->hub_, stream, live, payload] { hub->OnMesh(stream, live, payload); });
}

void WebServer::PublishStatus(const std::string& stream, std::string json) {
  auto payload = std::make_shared<const std::string>(std::move(json));
  net::post(impl_->ioc_, [hub = impl_->hub_, stream, payload] { hub->OnStatus(stream, payload); });
}

int WebServer::port() const { return impl_->port_; }
WebServerStats WebServer::stats() const { return impl_->hub_->Stats(); }

bool IsLoopbackAddress(const std::string& address) {
  if (address == "localhost") return true;
  beast::error_code ec;
  const net::ip::address parsed = net::ip::make_address(address, ec);
  return !ec && parsed.is_loopback();
}

}  // namespace vd
