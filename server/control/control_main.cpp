// vdeform-control: sends one control command (RESET, SAVE_SNAPSHOT, REQUEST_MESH) to a running
// vdeform-server, signed with HMAC-SHA256 when given the server's key file, and reports whether
// the server took it (from its status counters).
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <optional>
#include <string>
#include <thread>

#include <lcm/lcm-cpp.hpp>

#include "vd/common/flags.h"
#include "vd/common/auth.h"
#include "vd/common/lcm_guard.h"
#include "vd/common/messages.h"

namespace {

struct StatusWatch {
  std::optional<vdeform::server_status_t> last;
  void OnStatus(const lcm::ReceiveBuffer* rbuf, const std::string&) {
    auto m = vd::DecodeLcm<vdeform::server_status_t>(rbuf->data, rbuf->data_size);
    if (m.ok()) last = std::move(m).value();
  }
};

int64_t NowUs() {
  return std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// Waits up to `seconds` for a status message newer than `after_us`.
std::optional<vdeform::server_status_t> WaitStatus(lcm::LCM* lcm, StatusWatch* watch, double seconds,
                                                   int64_t after_us) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  watch->last.reset();
  while (std::chrono::steady_clock::now() < end) {
    lcm->handleTimeout(50);
    if (watch->last && watch->last->utime > after_us) return watch->last;
  }
  return std::nullopt;
}

// One key=value per line: easy to read, grep and parse in scripts.
void PrintStatus(const vdeform::server_status_t& st) {
  auto i = [](const char* k, long long v) { std::printf("%s=%lld\n", k, v); };
  std::printf("state=%s\nmessage=%s\n", vd::ServerStateName(st.state).c_str(), st.message.c_str());
  i("frames_received", st.frames_received);
  i("frames_processed", st.frames_processed);
  i("frames_dropped", st.frames_dropped);
  i("frames_rejected", st.frames_rejected);
  for (int k = 0; k < st.num_reject_reasons; ++k)
    std::printf("rejected_%s=%lld\n", st.reject_reason[k].c_str(), (long long)st.reject_count[k]);
  i("frames_duplicate", st.frames_duplicate);
  i("frames_reordered", st.frames_reordered);
  i("frames_lost", st.frames_lost);
  i("frames_foreign", st.frames_foreign);
  i("source_restarts", st.source_restarts);
  i("frames_held", st.frames_held);
  i("sequence_jumps", st.sequence_jumps);
  i("frames_rate_limited", st.frames_rate_limited);
  i("control_rate_limited", st.control_rate_limited);
  i("mesh_requests_merged", st.mesh_requests_merged);
  i("control_refused", st.control_refused);
  i("last_processed_seq", st.last_processed_seq);
  std::printf("last_source_id=%s\n", st.last_source_id.c_str());
  i("last_epoch", st.last_epoch);
  i("model_frames", st.model_frames);
  std::printf("fps=%.2f\n", st.fps);
  std::printf("latency_ms_p50=%.1f\nlatency_ms_p95=%.1f\n", st.latency_ms_p50, st.latency_ms_p95);
  i("active_voxels", st.active_voxels);
  i("dense_correspondences", st.dense_correspondences);
  i("sparse_correspondences", st.sparse_correspondences);
  i("resident_memory_bytes", st.resident_memory_bytes);
  i("checkpoint_utime", st.checkpoint_utime);
  std::printf("checkpoint_message=%s\n", st.checkpoint_message.c_str());
  for (int k = 0; k < st.num_stages; ++k)
    std::printf("stage_ms_mean_%s=%.2f\n", st.stage_name[k].c_str(), st.stage_ms_mean[k]);
}

}  // namespace

int main(int argc, char** argv) {
  std::string command, path, key_file, lcm_url, sender, stream;
  double wait = 3.0;
  vd::FlagParser flags(
      "vdeform-control: send a control command to a running vdeform-server.\n"
      "  vdeform-control --command reset|snapshot|request-mesh [--path NAME] [--key-file FILE]\n"
      "  vdeform-control --command status     print the server's status as key=value lines (monitoring)\n"
      "Exit status: 0 taken, 1 refused by the server or no server answered within --wait, 2 usage error.");
  flags.Add("command", &command, "status (print the server's status), reset (drop the model), snapshot (write meshes, the model as a checkpoint file, and a checkpoint), "
                                       "request-mesh (republish the current meshes)");
  flags.Add("path", &path, "snapshot: a name relative to the server's --snapshot-dir");
  flags.Add("key-file", &key_file, "The server's --control-key-file: signs the command with HMAC-SHA256");
  flags.Add("sender", &sender, "Who sends it, for the server's log (default vdeform-control@HOSTNAME)");
  flags.Add("lcm-url", &lcm_url, "LCM URL (default: $LCM_DEFAULT_URL, else host-only multicast)");
  flags.Add("stream", &stream, "The server's --stream: channels VDEFORM_<NAME>_STATUS and _CONTROL (empty = "
                               "VDEFORM_STATUS, VDEFORM_CONTROL)", "NAME");
  flags.Add("wait", &wait, "Seconds to wait for the server's status to confirm (0 = send and exit)");
  if (auto exit_code = flags.ParseCommandLine(argc, argv, "vdeform-control",
                                              [&] { return vd::ValidateStreamName(stream).WithContext("--stream"); }))
    return *exit_code;
  const vd::StreamChannels channels = *vd::ChannelsOfStream(stream);
  vdeform::control_t msg{};
  if (command == "reset") {
    msg.command = vdeform::control_t::COMMAND_RESET;
  } else if (command == "snapshot") {
    msg.command = vdeform::control_t::COMMAND_SAVE_SNAPSHOT;
    if (path.empty()) {
      std::fprintf(stderr, "vdeform-control: snapshot needs --path NAME\n");
      return 2;
    }
  } else if (command == "request-mesh") {
    msg.command = vdeform::control_t::COMMAND_REQUEST_MESH;
  } else if (command != "status") {
    std::fprintf(stderr, "vdeform-control: --command must be status, reset, snapshot or request-mesh (got '%s')\n",
                 command.c_str());
    return 2;
  }
  if (sender.empty()) {
    char host[256] = {0};
    gethostname(host, sizeof(host) - 1);
    sender = std::string("vdeform-control@") + host;
  }
  msg.path = path;
  msg.sender = sender;
  msg.utime = NowUs();
  msg.auth_size = 0;
  if (!key_file.empty()) {
    auto key = vd::ReadControlKey(key_file);
    if (!key.ok()) {
      std::fprintf(stderr, "vdeform-control: %s\n", key.status().message().c_str());
      return 2;
    }
    vd::SignControl(*key, &msg);
  }
  const std::string url = vd::ResolveLcmUrl(lcm_url);
  lcm::LCM lcm(url);
  if (!lcm.good()) {
    std::fprintf(stderr, "vdeform-control: cannot open LCM at '%s'\n", url.c_str());
    return 1;
  }
  StatusWatch watch;
  lcm.subscribe(channels.status, &StatusWatch::OnStatus, &watch);
  vd::GuardLcmOrWarn(url, "vdeform-control");
  std::optional<vdeform::server_status_t> before;
  if (wait > 0) {
    before = WaitStatus(&lcm, &watch, wait, 0);
    if (!before) {
      std::fprintf(stderr, "vdeform-control: no server status on '%s' within %.1f s; is vdeform-server running?\n",
                   url.c_str(), wait);
      return 1;
    }
  }
  if (command == "status") {
    if (!before) before = WaitStatus(&lcm, &watch, 3.0, 0);
    if (!before) {
      std::fprintf(stderr, "vdeform-control: no server status on '%s'\n", url.c_str());
      return 1;
    }
    PrintStatus(*before);
    return 0;
  }
  const int64_t sent_us = NowUs();
  if (lcm.publish(channels.control, &msg) != 0) {
    std::fprintf(stderr, "vdeform-control: publish failed\n");
    return 1;
  }
  if (wait <= 0) {
    std::printf("vdeform-control: sent %s\n", command.c_str());
    return 0;
  }
  // The server publishes status twice a second: the first one after sending (plus one more, so a
  // status already in flight does not hide the refusal) tells whether its refusal counter moved.
  std::optional<vdeform::server_status_t> after = WaitStatus(&lcm, &watch, wait, sent_us);
  if (after) after = WaitStatus(&lcm, &watch, wait, after->utime);
  if (!after) {
    std::fprintf(stderr, "vdeform-control: sent %s, but the server's status stopped\n", command.c_str());
    return 1;
  }
  if (after->control_refused > before->control_refused) {
    std::fprintf(stderr, "vdeform-control: the server refused %s (%s; see its log)\n", command.c_str(),
                 key_file.empty() ? "it may need --key-file" : "wrong key or clock skew");
    return 1;
  }
  std::printf("vdeform-control: %s taken; server %s, %lld frames in the model%s%s\n", command.c_str(),
              after->message.c_str(), (long long)after->model_frames,
              after->checkpoint_message.empty() ? "" : ", ", after->checkpoint_message.c_str());
  return 0;
}
