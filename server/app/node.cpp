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
                 "vdeform-server: cannot open LCM at '%s' %s\n",
                 url.c_str(), kLcmRouteHint);
    return 1;
  }
  auto gate = options.ToGateOptions();
  if (!gate.ok()) {
    std::fprintf(stderr, "vdeform-server: %s\n", gate.status().message().c_str());
    return 2;
  }
  auto engine = Engine::Create(options.engine, options.device);
  if (!engine.ok()) {
    std::fprintf(stderr, "vdeform-server: %s\n", engine.status().ToString().c_str());
    return 1;
  }
  VD_LOG_INFO << "vdeform-server on " << (*engine)->DeviceDescription() << ", LCM " << url;
  if (!gate->control_key.empty()) VD_LOG_INFO << "control commands RESET and SAVE_SNAPSHOT need an HMAC";
  if (!gate->accept_sources.empty()) VD_LOG_INFO << "accepting frames only from: " << options.accept_sources;
  Node node(options, &lcm, std::move(engine).value(), std::move(gate).value());
  // A refused checkpoint is reported (log and status) and the server starts a new model.
  if (options.resume) node.Resume();
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
  node.MaybeCheckpoint(true);
  node.PrintSummary();
  return 0;
}

}  // namespace vd
