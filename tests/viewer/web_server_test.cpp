// vdeform-web's server in-process on a free loopback port, with real HTTP and WebSocket clients:
// the page, tokens, client limits, the newest mesh for late and slow pages, bounded memory with a
// page that never reads, and bad input (oversized, malformed, unknown, binary) closing only the
// connection that sent it.
#include "vd/viewer/web_server.h"

#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <gtest/gtest.h>

namespace vd {
namespace {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;

constexpr const char* kToken = "0123456789abcdef0123";

// Resident memory of this process, bytes.
int64_t ResidentBytes() {
  std::ifstream statm("/proc/self/statm");
  int64_t pages = 0, resident = 0;
  statm >> pages >> resident;
  return resident * sysconf(_SC_PAGESIZE);
}

template <typename F>
bool WaitFor(F condition, double seconds = 5.0) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < end) {
    if (condition()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return condition();
}

void SetReceiveTimeout(int fd, int seconds) {
  timeval tv{seconds, 0};
  setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
}

// A raw TCP client that completed the WebSocket handshake (or -1), for frames Beast would refuse to
// send; `receive_buffer` > 0 shrinks its receive window; *status gets the HTTP status.
int RawUpgrade(int port, int receive_buffer = 0, const std::string& target = "/ws", int* status = nullptr) {
  int fd = socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) return -1;
  if (receive_buffer > 0) setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &receive_buffer, sizeof receive_buffer);
  SetReceiveTimeout(fd, 5);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<uint16_t>(port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  const std::string upgrade =
      "GET " + target + " HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
      "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n";
  char response[12];
  const bool answered = connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0 &&
                        send(fd, upgrade.data(), upgrade.size(), 0) == static_cast<ssize_t>(upgrade.size()) &&
                        recv(fd, response, sizeof response, MSG_WAITALL) == 12;
  if (status) *status = answered ? std::atoi(std::string(response + 9, 3).c_str()) : 0;
  if (!answered || std::string(response, 12) != "HTTP/1.1 101") {
    close(fd);
    return -1;
  }
  return fd;
}

// A client frame: FIN + `first` (opcode and RSV bits), masked unless told otherwise.
std::string Frame(uint8_t first, const std::string& payload, bool masked = true) {
  std::string frame(1, static_cast<char>(0x80 | first));
  const uint8_t mask_bit = masked ? 0x80 : 0;
  if (payload.size() < 126) {
    frame += static_cast<char>(mask_bit | payload.size());
  } else {
    frame += static_cast<char>(mask_bit | 126);
    frame += static_cast<char>(payload.size() >> 8);
    frame += static_cast<char>(payload.size() & 0xFF);
  }
  const char key[4] = {0x12, 0x34, 0x56, 0x78};
  if (masked) frame.append(key, 4);
  for (size_t i = 0; i < payload.size(); ++i) frame += static_cast<char>(payload[i] ^ (masked ? key[i % 4] : 0));
  return frame;
}

// Whether the server ends the connection within the receive time-out (EOF or reset).
bool ServerCloses(int fd) {
  char buffer[4096];
  for (;;) {
    const ssize_t n = recv(fd, buffer, sizeof buffer, 0);
    if (n == 0) return true;
    if (n < 0) return errno == ECONNRESET;
  }
}

class WebServerTest : public ::testing::Test {
 protected:
  void Start(WebServerOptions options = {}) {
    options.bind = "127.0.0.1";
    options.port = 0;
    StatusOr<std::unique_ptr<WebServer>> started = WebServer::Start(
        options, WebAssets::FromFiles({{"/index.html", "<html>vdeform</html>"}, {"/app.js", "// js"}}),
        [this](const std::string& stream) {
          std::lock_guard<std::mutex> lock(mutex_);
          requests_.push_back(stream);
        });
    ASSERT_TRUE(started.ok()) << started.status().ToString();
    server_ = std::move(started).value();
  }

  // One HTTP request; returns the response (status 0 when the connection failed).
  http::response<http::string_body> Get(const std::string& target, const std::string& authorization = "",
                                        const std::string& cookie = "", http::verb verb = http::verb::get) {
    net::io_context ioc;
    tcp::socket socket(ioc);
    socket.connect(tcp::endpoint(net::ip::make_address("127.0.0.1"), server_->port()));
    SetReceiveTimeout(socket.native_handle(), 5);
    http::request<http::empty_body> request(verb, target, 11);
    request.set(http::field::host, "127.0.0.1");
    if (!authorization.empty()) request.set(http::field::authorization, authorization);
    if (!cookie.empty()) request.set(http::field::cookie, cookie);
    http::write(socket, request);
    beast::flat_buffer buffer;
    http::response<http::string_body> response;
    beast::error_code ec;
    http::read(socket, buffer, response, ec);
    return response;
  }

  // A WebSocket client (Beast's), or null when the upgrade failed.
  struct Client {
    net::io_context ioc;
    websocket::stream<tcp::socket> ws{ioc};
    beast::flat_buffer buffer;
  };
  std::unique_ptr<Client> Connect(const std::string& target = "/ws") {
    auto client = std::make_unique<Client>();
    client->ws.next_layer().connect(tcp::endpoint(net::ip::make_address("127.0.0.1"), server_->port()));
    SetReceiveTimeout(client->ws.next_layer().native_handle(), 5);
    beast::error_code ec;
    client->ws.handshake("127.0.0.1", target, ec);
    if (ec) return nullptr;
    return client;
  }
  // The next message (text or binary); empty with *error set when the connection ended.
  static std::string Read(Client* client, beast::error_code* error = nullptr) {
    client->buffer.consume(client->buffer.size());
    beast::error_code ec;
    client->ws.read(client->buffer, ec);
    if (error) *error = ec;
    if (ec) return "";
    return beast::buffers_to_string(client->buffer.data());
  }
  // Reads until a message starting with `prefix` arrives (or the connection ends).
  static std::string ReadUntil(Client* client, const std::string& prefix) {
    for (int i = 0; i < 50; ++i) {
      beast::error_code ec;
      std::string message = Read(client, &ec);
      if (ec) return "";
      if (message.rfind(prefix, 0) == 0) return message;
    }
    return "";
  }

  std::vector<std::string> Requests() {
    std::lock_guard<std::mutex> lock(mutex_);
    return requests_;
  }

  std::mutex mutex_;
  std::vector<std::string> requests_;
  // Last, so it stops before what its request callback touches goes away.
  std::unique_ptr<WebServer> server_;
};

TEST_F(WebServerTest, ServesThePageAndNothingElse) {
  Start();
  http::response<http::string_body> page = Get("/");
  EXPECT_EQ(page.result_int(), 200);
  EXPECT_EQ(page.body(), "<html>vdeform</html>");
  EXPECT_EQ(page[http::field::content_type], "text/html; charset=utf-8");
  EXPECT_EQ(Get("/app.js").body(), "// js");
  EXPECT_EQ(Get("/../etc/passwd").result_int(), 404);
  EXPECT_EQ(Get("/missing.js").result_int(), 404);
  EXPECT_EQ(Get("/", "", "", http::verb::post).result_int(), 405);
  int status = 0;
  EXPECT_LT(RawUpgrade(server_->port(), 0, "/elsewhere", &status), 0);
  EXPECT_EQ(status, 404);
}

TEST_F(WebServerTest, WithATokenEveryRequestNeedsIt) {
  WebServerOptions options;
  options.token = kToken;
  Start(options);
  EXPECT_EQ(Get("/").result_int(), 403);
  EXPECT_EQ(Get("/?token=0123456789abcdef0124").result_int(), 403);
  EXPECT_EQ(Get("/app.js", "Bearer wrong-wrong-wrong-wrong").result_int(), 403);
  EXPECT_EQ(Get("/app.js", "", "vdeform_token=0123456789abcdef012").result_int(), 403);
  http::response<http::string_body> page = Get(std::string("/?token=") + kToken);
  EXPECT_EQ(page.result_int(), 200);
  EXPECT_EQ(page[http::field::set_cookie],
            std::string("vdeform_token=") + kToken + "; Path=/; HttpOnly; SameSite=Strict");
  EXPECT_EQ(Get("/app.js", std::string("Bearer ") + kToken).result_int(), 200);
  EXPECT_EQ(Get("/app.js", "", std::string("a=b; vdeform_token=") + kToken).result_int(), 200);
  int status = 0;
  EXPECT_LT(RawUpgrade(server_->port(), 0, "/ws", &status), 0);
  EXPECT_EQ(status, 403);
  EXPECT_LT(RawUpgrade(server_->port(), 0, "/ws?token=nope-nope-nope-nope", &status), 0);
  EXPECT_EQ(status, 403);
  EXPECT_NE(Connect(std::string("/ws?token=") + kToken), nullptr);
  EXPECT_EQ(server_->stats().forbidden, 6);
}

TEST_F(WebServerTest, ALateClientGetsTheNewestMeshAndStatusAtOnce) {
  Start();
  server_->PublishMesh("", true, "VDM1 mesh 1");
  server_->PublishMesh("", true, "VDM1 mesh 2");
  server_->PublishMesh("", false, "VDM1 canonical 2");
  server_->PublishStatus("", "{\"type\":\"status\",\"n\":1}");
  // The publications are handed to the server's thread before the client's handshake completes.
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  std::unique_ptr<Client> client = Connect();
  ASSERT_NE(client, nullptr);
  std::vector<std::string> got;
  for (int i = 0; i < 4; ++i) got.push_back(Read(client.get()));
  EXPECT_EQ(got[0], "{\"type\":\"streams\",\"streams\":[\"\"]}");
  EXPECT_EQ(got[1], "{\"type\":\"status\",\"n\":1}");
  EXPECT_EQ(got[2], "VDM1 mesh 2");
  EXPECT_EQ(got[3], "VDM1 canonical 2");
  // It held a mesh for the stream: no need to ask the server.
  EXPECT_TRUE(Requests().empty());
  server_->PublishMesh("", true, "VDM1 mesh 3");
  EXPECT_EQ(Read(client.get()), "VDM1 mesh 3");
  EXPECT_EQ(server_->stats().clients, 1);
}

TEST_F(WebServerTest, AClientWithoutAMeshToShowMakesTheBridgeAskAndMayAskItself) {
  Start();
  std::unique_ptr<Client> client = Connect();
  ASSERT_NE(client, nullptr);
  ASSERT_TRUE(WaitFor([&] { return Requests().size() == 1; }));
  client->ws.write(net::buffer(std::string("request_mesh")));
  ASSERT_TRUE(WaitFor([&] { return Requests().size() == 2; }));
  EXPECT_EQ(Requests()[1], "");
}

TEST_F(WebServerTest, ClientsBeyondTheLimitGet503AndASlotFreesWhenOneLeaves) {
  WebServerOptions options;
  options.max_clients = 2;
  Start(options);
  std::unique_ptr<Client> a = Connect(), b = Connect();
  ASSERT_NE(a, nullptr);
  ASSERT_NE(b, nullptr);
  ASSERT_TRUE(WaitFor([&] { return server_->stats().clients == 2; }));
  int status = 0;
  EXPECT_LT(RawUpgrade(server_->port(), 0, "/ws", &status), 0);
  EXPECT_EQ(status, 503);
  EXPECT_EQ(server_->stats().refused_full, 1);
  a->ws.close(websocket::close_code::normal);
  a.reset();
  ASSERT_TRUE(WaitFor([&] { return server_->stats().clients == 1; }));
  EXPECT_NE(Connect(), nullptr);
  EXPECT_EQ(server_->stats().clients_peak, 2);
}

TEST_F(WebServerTest, BadMessagesCloseOnlyTheirConnection) {
  Start();
  std::unique_ptr<Client> good = Connect();
  ASSERT_NE(good, nullptr);
  ASSERT_EQ(ReadUntil(good.get(), "{\"type\":\"streams\""), "{\"type\":\"streams\",\"streams\":[]}");
  const struct {
    const char* what;
    std::string frame;
  } bad[] = {
      {"oversized message", Frame(0x1, std::string(10000, 'x'))},
      {"unknown command", Frame(0x1, "reset")},
      {"binary message", Frame(0x2, std::string("\x01\x02", 2))},
      {"reserved bits set", Frame(0x1 | 0x70, "request_mesh")},
      {"text that is not UTF-8", Frame(0x1, "stream \xff\xfe")},
      {"control frame over 125 bytes", Frame(0x9, std::string(200, 'p'))},
      {"reserved opcode", Frame(0x3, "x")},
      {"garbage bytes", std::string("\xde\xad\xbe\xef\x00\xff\x13\x37 not a frame at all", 29)},
  };
  int64_t closed = 0;
  for (const auto& b : bad) {
    const int fd = RawUpgrade(server_->port());
    ASSERT_GE(fd, 0) << b.what;
    ASSERT_EQ(send(fd, b.frame.data(), b.frame.size(), MSG_NOSIGNAL), static_cast<ssize_t>(b.frame.size())) << b.what;
    EXPECT_TRUE(ServerCloses(fd)) << b.what;
    close(fd);
    ++closed;
    EXPECT_TRUE(WaitFor([&] { return server_->stats().closed_bad_input == closed; }))
        << b.what << ": closed_bad_input " << server_->stats().closed_bad_input;
    closed = server_->stats().closed_bad_input;
  }
  // The well-behaved page is still served.
  server_->PublishMesh("", true, "VDM1 after the attacks");
  EXPECT_EQ(ReadUntil(good.get(), "VDM1"), "VDM1 after the attacks");
  EXPECT_TRUE(WaitFor([&] { return server_->stats().clients == 1; }));
}

TEST_F(WebServerTest, APageThatNeverReadsGetsOnlyTheNewestMeshAndMemoryStaysFlat) {
  Start();
  // A raw client with a small receive window that completes the handshake and never reads.
  const int fd = RawUpgrade(server_->port(), 4096);
  ASSERT_GE(fd, 0);
  // And a page that reads, to see the newest mesh arrive past the stuck one.
  std::unique_ptr<Client> reader = Connect();
  ASSERT_NE(reader, nullptr);
  ASSERT_TRUE(WaitFor([&] { return server_->stats().clients == 2; }));

  // 200 meshes of 256 KB: 50 MB that a bridge queueing per page would hold for the stuck one.
  constexpr int kMeshes = 200;
  constexpr size_t kMeshBytes = 256 << 10;
  int64_t rss_after_warmup = 0;
  for (int i = 0; i < kMeshes; ++i) {
    std::string mesh(kMeshBytes, static_cast<char>('a' + i % 26));
    mesh.replace(0, 16, "VDM1 mesh " + std::to_string(1000 + i));
    server_->PublishMesh("", true, std::move(mesh));
    if (i == 20) {
      ASSERT_TRUE(WaitFor([&] { return server_->stats().meshes_replaced > 0; }));
      rss_after_warmup = ResidentBytes();
    }
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
  ASSERT_TRUE(WaitFor([&] { return server_->stats().queued_messages <= 2; }));
  const WebServerStats stats = server_->stats();
  const int64_t growth = ResidentBytes() - rss_after_warmup;
  std::printf("never-reading page: %lld meshes replaced in its slot, %lld waiting, RSS %+.1f MB over %d meshes of "
              "%zu KB\n",
              static_cast<long long>(stats.meshes_replaced), static_cast<long long>(stats.queued_messages),
              growth / 1048576.0, kMeshes, kMeshBytes >> 10);
  // The stuck page holds at most one mesh waiting; the kernel's socket buffers took the first few.
  EXPECT_GT(stats.meshes_replaced, kMeshes / 2);
  EXPECT_LE(stats.queued_messages, 2);
  EXPECT_LT(growth, 16 << 20);
  // The reading page ends with the newest mesh.
  const std::string newest = "VDM1 mesh " + std::to_string(1000 + kMeshes - 1);
  bool got_newest = false;
  for (int i = 0; i < kMeshes + 5 && !got_newest; ++i) {
    beast::error_code ec;
    const std::string message = Read(reader.get(), &ec);
    ASSERT_FALSE(ec) << ec.message();
    got_newest = message.rfind(newest, 0) == 0;
  }
  EXPECT_TRUE(got_newest);
  close(fd);
}

TEST_F(WebServerTest, AStalledWriteClosesThePageAfterTheTimeout) {
  WebServerOptions options;
  options.write_timeout_s = 0.3;
  Start(options);
  std::unique_ptr<Client> client = Connect();
  ASSERT_NE(client, nullptr);
  ASSERT_TRUE(WaitFor([&] { return server_->stats().clients == 1; }));
  // Meshes until the kernel's buffers are full and a write stalls.
  for (int i = 0; i < 64 && server_->stats().closed_stalled == 0; ++i) {
    server_->PublishMesh("", true, std::string(1 << 20, 'm'));
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ASSERT_TRUE(WaitFor([&] { return server_->stats().closed_stalled == 1; }));
  EXPECT_TRUE(WaitFor([&] { return server_->stats().clients == 0; }));
}

TEST_F(WebServerTest, StopsPromptlyWithClientsConnected) {
  Start();
  std::unique_ptr<Client> a = Connect(), b = Connect();
  ASSERT_NE(a, nullptr);
  ASSERT_NE(b, nullptr);
  const auto t0 = std::chrono::steady_clock::now();
  server_.reset();
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(1));
  beast::error_code ec;
  for (int i = 0; i < 10 && !ec; ++i) Read(a.get(), &ec);
  EXPECT_TRUE(ec);
}

TEST(WebServerOptionsTest, BoundsAndLoopback) {
  WebServerOptions options;
  EXPECT_TRUE(options.Validate().ok());
  options.max_clients = 0;
  EXPECT_FALSE(options.Validate().ok());
  options = {};
  options.token = "short";
  EXPECT_FALSE(options.Validate().ok());
  options = {};
  options.bind = "example.org";
  EXPECT_FALSE(options.Validate().ok());
  EXPECT_TRUE(IsLoopbackAddress("127.0.0.1"));
  EXPECT_TRUE(IsLoopbackAddress("127.1.2.3"));
  EXPECT_TRUE(IsLoopbackAddress("::1"));
  EXPECT_TRUE(IsLoopbackAddress("localhost"));
  EXPECT_FALSE(IsLoopbackAddress("0.0.0.0"));
  EXPECT_FALSE(IsLoopbackAddress("192.168.1.2"));
}

TEST(WebServerStartTest, APortInUseIsAClearError) {
  WebServerOptions options;
  options.port = 0;
  StatusOr<std::unique_ptr<WebServer>> first = WebServer::Start(options, WebAssets::FromFiles({}), nullptr);
  ASSERT_TRUE(first.ok());
  options.port = (*first)->port();
  StatusOr<std::unique_ptr<WebServer>> second = WebServer::Start(options, WebAssets::FromFiles({}), nullptr);
  ASSERT_FALSE(second.ok());
  EXPECT_NE(second.status().message().find("cannot listen on 127.0.0.1:" + std::to_string(options.port)),
            std::string::npos)
      << second.status().message();
}

}  // namespace
}  // namespace vd
