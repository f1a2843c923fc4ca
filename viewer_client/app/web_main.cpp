// vdeform-web: the web viewer's bridge. Subscribes to the server's meshes and status over LCM and
// forwards them to browsers (HTTP for the page, a WebSocket for the data). See --help.
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <lcm/lcm-cpp.hpp>
#include <vdeform/control_t.hpp>

#include "vd/common/auth.h"
#include "vd/common/log.h"
#include "vd/common/lcm_guard.h"
#include "vd/common/messages.h"
#include "vd/common/output_auth.h"
#include "vd/common/stop_signal.h"
#include "vd/viewer/status_text.h"
#include "vd/viewer/web_options.h"
#include "vd/viewer/web_protocol.h"
#include "vd/viewer/web_server.h"

namespace {

std::string ExecutableDir() {
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  return ec ? std::string(".") : exe.parent_path().string();
}

// REQUEST_MESH on the server's control channel, at most one a second in all, whatever the pages
// ask: requests in between are merged into the next one.
class MeshRequester {
 public:
  MeshRequester(lcm::LCM* lcm, std::string sender) : lcm_(lcm), sender_(std::move(sender)) {}
  // Thread-safe (the web server's thread calls it).
  void Ask(const std::string& stream) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++asked_;
    wanted_.insert(stream);
  }
  // On the LCM thread: publishes one waiting request when a second has passed since the last.
  void Tick() {
    const auto now = std::chrono::steady_clock::now();
    if (sent_ > 0 && now - last_ < std::chrono::seconds(1)) return;
    std::string stream;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (wanted_.empty()) return;
      stream = *wanted_.begin();
      wanted_.erase(wanted_.begin());
    }
    vdeform::control_t msg;
    msg.utime = std::chrono::duration_cast<std::chrono::microseconds>(
                    std::chrono::system_clock::now().time_since_epoch())
                    .count();
    msg.command = vdeform::control_t::COMMAND_REQUEST_MESH;
    msg.sender = sender_;
    msg.auth_size = 0;
    last_ = now;
    ++sent_;
    const std::string channel = vd::ChannelsOfStream(stream).value().control;
    if (lcm_->publish(channel, &msg) != 0) VD_LOG_WARNING << "cannot publish REQUEST_MESH on " << channel;
  }
  int64_t sent() const { return sent_; }
  int64_t asked() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return asked_;
  }

 private:
  lcm::LCM* lcm_;
  std::string sender_;
  mutable std::mutex mutex_;
  std::set<std::string> wanted_;
  int64_t asked_ = 0;
  int64_t sent_ = 0;
  std::chrono::steady_clock::time_point last_{};
};

// The LCM side: decodes what arrives just enough to check it, and hands it to the web server.
class Forwarder {
 public:
  // `output_key` (--key-file): only meshes and status signed under it are forwarded; empty: all.
  Forwarder(vd::WebServer* server, MeshRequester* requester, std::string output_key)
      : server_(server), requester_(requester), output_key_(std::move(output_key)) {}

  void OnMesh(const lcm::ReceiveBuffer* buffer, const std::string& channel) {
    const std::optional<std::string> stream = vd::StreamOfChannel(channel, "MESH");
    // Without a key a stream is admitted by its name; with one, by its first signed message.
    if (!stream || (output_key_.empty() && !Known(*stream))) return;
    vd::StatusOr<vdeform::mesh_t> msg = vd::DecodeLcm<vdeform::mesh_t>(buffer->data, buffer->data_size);
    if (!msg.ok()) return Refuse("malformed mesh_t", msg.status(), &meshes_refused_);
    if (!output_key_.empty() && !(Signed(*stream, *msg, "mesh", &meshes_unsigned_) && Known(*stream))) return;
    // The page shows the live and canonical meshes; a --track-mesh server's tracked ones stay on LCM.
    if (msg->kind == vdeform::mesh_t::KIND_TRACKED) return;
    vd::StatusOr<std::string> frame = vd::MeshFrame(*msg, *stream);
    if (!frame.ok()) return Refuse("unusable mesh", frame.status(), &meshes_refused_);
    bytes_ += static_cast<int64_t>(frame->size());
    ++meshes_;
    if (msg->kind == vdeform::mesh_t::KIND_LIVE) {
      last_seq_ = msg->seq;
      last_vertices_ = msg->num_vertices;
    }
    server_->PublishMesh(*stream, msg->kind == vdeform::mesh_t::KIND_LIVE, std::move(frame).value());
  }

  void OnStatus(const lcm::ReceiveBuffer* buffer, const std::string& channel) {
    const std::optional<std::string> stream = vd::StreamOfChannel(channel, "STATUS");
    if (!stream || (output_key_.empty() && !Known(*stream))) return;
    vd::StatusOr<vdeform::server_status_t> msg =
        vd::DecodeLcm<vdeform::server_status_t>(buffer->data, buffer->data_size);
    if (!msg.ok()) return Refuse("malformed server_status_t", msg.status(), &status_refused_);
    if (!output_key_.empty() && !(Signed(*stream, *msg, "status", &status_unsigned_) && Known(*stream))) return;
    ++status_;
    state_ = vd::ServerStateName(msg->state);
    fps_ = msg->fps;
    server_->PublishStatus(*stream, vd::StatusJson(*msg, *stream));
  }

  std::string Line(const vd::WebServerStats& web, const MeshRequester& requests) const {
    char fps[32];
    std::snprintf(fps, sizeof fps, "%.1f", fps_);
    std::string line = "clients " + std::to_string(web.clients) + " (peak " + std::to_string(web.clients_peak) +
                       ") | meshes " + std::to_string(meshes_) + " in, " + std::to_string(web.meshes_sent) +
                       " out, " + std::to_string(web.meshes_replaced) + " skipped (slow pages)";
    if (meshes_refused_ || status_refused_)
      line += ", refused " + std::to_string(meshes_refused_ + status_refused_);
    if (last_seq_ >= 0) line += " | seq " + std::to_string(last_seq_) + " (" + std::to_string(last_vertices_) + " v)";
    line += " | sent " + vd::FormatBytes(web.bytes_sent) + " | requests " + std::to_string(requests.sent()) + "/" +
            std::to_string(requests.asked());
    if (web.forbidden || web.refused_full || web.refused_connections || web.closed_bad_input || web.closed_stalled)
      line += " | 403 " + std::to_string(web.forbidden) + ", full " +
              std::to_string(web.refused_full + web.refused_connections) + ", bad " +
              std::to_string(web.closed_bad_input) + ", stalled " + std::to_string(web.closed_stalled);
    line += status_ ? " | server " + state_ + " " + fps + " fps" : " | server: no status yet";
    if (streams_.size() > 1) line += " (" + std::to_string(streams_.size()) + " streams)";
    if (streams_refused_) line += " | " + std::to_string(streams_refused_) + " messages of streams beyond " +
                                  std::to_string(vd::kMaxStreams) + " dropped";
    if (meshes_unsigned_.total() || status_unsigned_.total())
      line += " | not signed by the server: meshes " + meshes_unsigned_.ToString() + "; status " +
              status_unsigned_.ToString();
    return line;
  }

 private:
  // Whether the bridge keeps this stream: the first kMaxStreams names heard (anyone on the group
  // can make up names; the web server holds the same bound). A new one gets its meshes asked for.
  bool Known(const std::string& stream) {
    if (streams_.count(stream)) return true;
    if (streams_.size() >= vd::kMaxStreams) {
      ++streams_refused_;
      return false;
    }
    streams_.insert(stream);
    requester_->Ask(stream);
    return true;
  }

  void Refuse(const std::string& kind, const vd::Status& status, int64_t* counter) {
    ++*counter;
    LogOnce(kind, status);
  }

  void LogOnce(const std::string& kind, const vd::Status& status) {
    if (logged_.insert(kind).second)
      VD_LOG_WARNING << kind << " (counted; further ones are not logged): " << status.ToString();
  }

  // With --key-file: whether msg verifies under the key and is newer than the last one taken of
  // its stream (each stream is a server run of its own); refusals are counted in *refused. A
  // stream's verifier is kept from its first message taken on, so forged stream names take
  // neither a slot (Known) nor memory.
  template <typename Msg>
  bool Signed(const std::string& stream, const Msg& msg, const char* what, vd::OutputRefusals* refused) {
    auto it = verifiers_.find(stream);
    vd::OutputVerifier fresh(output_key_);
    const vd::OutputCheck check = (it != verifiers_.end() ? it->second : fresh).Check(msg);
    refused->Add(check.verdict);
    if (!check.ok()) {
      LogOnce(std::string(what) + " refused, " + vd::OutputVerdictName(check.verdict), check.status);
      return false;
    }
    if (it == verifiers_.end() && verifiers_.size() < vd::kMaxStreams) verifiers_.emplace(stream, std::move(fresh));
    return true;
  }

  vd::WebServer* server_;
  MeshRequester* requester_;
  // The server's output key (empty: nothing is verified), and per stream what was taken last.
  std::string output_key_;
  std::map<std::string, vd::OutputVerifier> verifiers_;
  // Meshes and status refused under the key, by reason.
  vd::OutputRefusals meshes_unsigned_, status_unsigned_;
  int64_t meshes_ = 0, meshes_refused_ = 0, status_ = 0, status_refused_ = 0, bytes_ = 0;
  int64_t last_seq_ = -1, last_vertices_ = 0;
  std::string state_;
  float fps_ = 0;
  std::set<std::string> logged_;
  std::set<std::string> streams_;
  int64_t streams_refused_ = 0;
};

int Main(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  vd::StatusOr<vd::WebOptions> parsed = vd::ParseWebArgs(args);
  if (!parsed.ok()) {
    std::fprintf(stderr, "vdeform-web: %s\n", parsed.status().message().c_str());
    return 2;
  }
  vd::WebOptions options = *parsed;
  if (options.help) {
    std::printf("%s", vd::WebHelpText().c_str());
    return 0;
  }
  if (options.quiet) vd::SetLogLevel(vd::LogLevel::kWarning);
  if (!options.token_file.empty()) {
    vd::StatusOr<std::string> token = vd::ReadPrivateFile(options.token_file, "token file");
    if (token.ok()) {
      std::string text = *token;
      while (!text.empty() && std::isspace(static_cast<unsigned char>(text.back()))) text.pop_back();
      vd::Status valid = vd::ValidateToken(text);
      if (!valid.ok()) token = valid.WithContext("token file '" + options.token_file + "'");
      else options.server.token = text;
    }
    if (!token.ok()) {
      std::fprintf(stderr, "vdeform-web: %s\n", token.status().message().c_str());
      return 2;
    }
  } else if (!vd::IsLoopbackAddress(options.server.bind)) {
    VD_LOG_WARNING << "serving on " << options.server.bind
                   << " without --token-file: anyone who reaches this port sees the reconstruction";
  }
  const vd::StatusOr<std::string> output_key = vd::OutputKeyFromFlag(options.key_file);
  if (!output_key.ok()) {
    std::fprintf(stderr, "vdeform-web: %s\n", output_key.status().message().c_str());
    return 2;
  }
  vd::InstallStopSignalHandlers();
  std::atomic<bool>& g_stop = vd::StopFlag();

  vd::StatusOr<std::string> root = vd::FindWebRoot(options.web_root, ExecutableDir());
  vd::StatusOr<vd::WebAssets> assets = root.ok() ? vd::WebAssets::Load(*root) : root.status();
  if (!assets.ok()) {
    std::fprintf(stderr, "vdeform-web: %s\n", assets.status().message().c_str());
    return 1;
  }

  const std::string url = vd::ResolveLcmUrl(options.lcm_url);
  lcm::LCM lcm(url);
  if (!lcm.good()) {
    std::fprintf(stderr, "vdeform-web: cannot open LCM at '%s' %s\n", url.c_str(), vd::kLcmRouteHint);
    return 1;
  }
  MeshRequester requester(&lcm, "vdeform-web:" + std::to_string(getpid()));
  vd::StatusOr<std::unique_ptr<vd::WebServer>> started = vd::WebServer::Start(
      options.server, std::move(assets).value(), [&requester](const std::string& stream) { requester.Ask(stream); });
  if (!started.ok()) {
    std::fprintf(stderr, "vdeform-web: %s\n", started.status().message().c_str());
    return 1;
  }
  vd::WebServer& server = **started;
  Forwarder forwarder(&server, &requester, *output_key);
  // One stream's channels, or every stream's (LCM subscribes by regular expression).
  const std::string mesh_channels = options.stream ? vd::ChannelsOfStream(*options.stream).value().mesh
                                                   : vd::AllStreamsChannelRegex("MESH");
  const std::string status_channels = options.stream ? vd::ChannelsOfStream(*options.stream).value().status
                                                     : vd::AllStreamsChannelRegex("STATUS");
  lcm::Subscription* mesh_sub = lcm.subscribe(mesh_channels, &Forwarder::OnMesh, &forwarder);
  lcm::Subscription* status_sub = lcm.subscribe(status_channels, &Forwarder::OnStatus, &forwarder);
  if (!mesh_sub || !status_sub) {
    std::fprintf(stderr, "vdeform-web: cannot subscribe to %s and %s\n", mesh_channels.c_str(),
                 status_channels.c_str());
    return 1;
  }
  vd::GuardLcmOrWarn(url, "vdeform-web");
  // Ask at once, so the first page to connect finds the current mesh here.
  requester.Ask(options.stream.value_or(""));
  const std::string host = options.server.bind.find(':') != std::string::npos ? "[" + options.server.bind + "]"
                                                                              : options.server.bind;
  // The URL line is printed even with --quiet: scripts (deploy/demo.sh --web, the tests) read it.
  std::printf("vdeform-web: serving http://%s:%d/%s (LCM %s; %s, %s; pages from %s)\n", host.c_str(), server.port(),
              options.server.token.empty() ? "" : "?token=...", url.c_str(), mesh_channels.c_str(),
              status_channels.c_str(), root->c_str());
  std::fflush(stdout);

  vd::StatusPrinter printer(!options.quiet);
  int exit_code = 0;
  while (!g_stop.load()) {
    errno = 0;
    if (lcm.handleTimeout(100) < 0 && errno != EINTR) {
      std::fprintf(stderr, "vdeform-web: LCM stopped delivering messages\n");
      exit_code = 1;
      break;
    }
    requester.Tick();
    printer.Tick([&] { return forwarder.Line(server.stats(), requester); });
  }
  printer.Finish();
  lcm.unsubscribe(mesh_sub);
  lcm.unsubscribe(status_sub);
  const vd::WebServerStats stats = server.stats();
  started->reset();
  std::printf("vdeform-web: %s\n", forwarder.Line(stats, requester).c_str());
  std::fflush(stdout);
  return exit_code;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return Main(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "vdeform-web: unexpected error: %s\n", e.what());
    return 1;
  }
}
