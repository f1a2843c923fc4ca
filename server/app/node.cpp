// The LCM node's entry point and helpers; the Node class is in node.h.
#include "node.h"

#include <csignal>
#include <thread>

namespace vd {
namespace {

std::atomic<bool> g_stop{false};
void OnSignal(int) { g_stop = true; }

}  // namespace

int64_t NowUs() {
  return std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
}

std::string RejectReason(const Status& s) {
  const std::string& m = s.message();
  auto has = [&](const char* w) { return m.find(w) != std::string::npos; };
  if (has("intrinsics")) return "bad_intrinsics";
  if (has("encoding")) return "unknown_encoding";
  if (has("payload") || has("too large") || has("exceeds")) return "oversized";
  if (has("depth_scale")) return "bad_depth_scale";
  if (has("expected") || has("size") || has("width") || has("height") || has("changed from")) return "wrong_size";
  return "invalid_frame";
}

StatusOr<std::filesystem::path> SnapshotPath(const std::string& dir, const std::string& name) {
  if (name.empty()) return InvalidArgument("empty snapshot name");
  const std::filesystem::path rel(name);
  if (rel.is_absolute()) return InvalidArgument("snapshot path '" + name + "' is absolute");
  for (const auto& part : rel)
    if (part == "..") return InvalidArgument("snapshot path '" + name + "' leaves the snapshot directory");
  return std::filesystem::path(dir) / rel;
}

int RunNode(const ServerOptions& options) {
  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  const std::string url = ResolveLcmUrl(options.lcm_url);
  lcm::LCM lcm(url);
  if (!lcm.good()) {
    std::fprintf(stderr,
                 "vdeform-server: cannot open LCM at '%s' (on a host with only loopback: "
                 "ip route add 224.0.0.0/4 dev lo; see README)\n",
                 url.c_str());
    return 1;
  }
  auto params = options.ToEngineParams();
  if (!params.ok()) {
    std::fprintf(stderr, "vdeform-server: %s\n", params.status().message().c_str());
    return 2;
  }
  auto engine = Engine::Create(*params, options.device);
  if (!engine.ok()) {
    std::fprintf(stderr, "vdeform-server: %s\n", engine.status().ToString().c_str());
    return 1;
  }
  VD_LOG_INFO << "vdeform-server on " << (*engine)->DeviceDescription() << ", LCM " << url;
  Node node(options, &lcm, std::move(engine).value());
  lcm.subscribe(kFrameChannel, &Node::OnFrame, &node);
  lcm.subscribe(kControlChannel, &Node::OnControl, &node);
  std::thread worker([&] { node.Work(&g_stop); });
  while (!g_stop) {
    if (lcm.handleTimeout(50) < 0) {
      VD_LOG_ERROR << "LCM receive failed; stopping";
      g_stop = true;
    }
    node.Tick();
  }
  worker.join();
  node.PrintSummary();
  return 0;
}

}  // namespace vd
