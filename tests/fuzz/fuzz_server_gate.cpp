// The server's message handlers (server/app/gate.cpp: what Node::OnFrame and Node::OnControl run
// before anything reaches the engine) over a sequence of messages. The input is a series of
// records [kind byte][u16 length][bytes]: kind even = a VDEFORM_FRAMES message, odd = a
// VDEFORM_CONTROL message. Two gates take the same records: one open (source filter and control
// key only), one that also requires frames signed under per-source keys (capture-a, capture-b).
// The gates' clock moves 10 ms per message, so their rate limits (frames per source, control
// messages per sender, one REQUEST_MESH served per second) depend on the input alone.
// Invariants: every frame is counted exactly once (accepted, rejected, stale, foreign, held or
// rate-limited); at most max_sources sources are ever accepted; REQUEST_MESH is served at most once
// per simulated second; an
// accepted frame is valid, from an accepted source, and its seq is newer than the source's last
// accepted one unless the gate counted a restart; a held frame is more than max_jump ahead of it;
// the lost count stays within [0, (max_jump - 1) x accepted frames] whatever the numbers; with frame
// keys an accepted frame verifies under its source's key; a state-changing control command is
// accepted only with a valid HMAC and a utime newer than any accepted before.
#include <map>
#include <optional>

#include "fuzz_util.h"
#include "gate.h"

namespace {

constexpr const char* kKey = "fuzz-control-key-0123456789";
constexpr int64_t kNowUs = 1764633600000000;
// The frame keys make_seeds.cpp signs the seeds with: 32 bytes of 'a' for capture-a, 'b' for capture-b.
const char* const kFrameKeyFile =
    "capture-a 6161616161616161616161616161616161616161616161616161616161616161\n"
    "capture-b 6262626262626262626262626262626262626262626262626262626262626262\n";

int64_t g_clock_us = 0;
int64_t Tick() { return g_clock_us += 10'000; }

void RunGate(vd::FrameGate* gate, const uint8_t* data, size_t size) {
  g_clock_us = 0;
  const int64_t max_jump = vd::SequenceParams().max_jump;
  int64_t frames = 0, accepted = 0, stale = 0, foreign = 0, rejected = 0, held = 0, limited = 0;
  std::optional<int64_t> last_served_us;
  std::map<std::string, int64_t> last_seq;
  int64_t last_control_utime = 0;
  size_t pos = 0;
  while (pos + 3 <= size) {
    const uint8_t kind = data[pos];
    const size_t len = std::min<size_t>(size_t(data[pos + 1]) | size_t(data[pos + 2]) << 8, size - pos - 3);
    const uint8_t* msg = data + pos + 3;
    pos += 3 + len;
    if (kind % 2 == 0) {
      ++frames;
      const int64_t restarts = gate->counters().source_restarts;
      vd::FrameDecision d = gate->OnFrame(msg, len);
      switch (d.verdict) {
        case vd::FrameVerdict::kAccept: {
          ++accepted;
          VD_FUZZ_CHECK(d.frame.has_value() && d.frame->Validate().ok());
          const std::string& id = d.frame->source_id;
          VD_FUZZ_CHECK(id == "capture-a" || id == "capture-b" || id.empty());
          if (gate->authenticated_frames()) {
            VD_FUZZ_CHECK(id != "");
            auto wire = vd::DecodeLcm<vdeform::rgbd_frame_t>(msg, len);
            VD_FUZZ_CHECK(wire.ok());
            const std::string key(32, id == "capture-a" ? 'a' : 'b');
            VD_FUZZ_CHECK(vd::VerifyFrame(key, *wire).ok());
          }
          auto it = last_seq.find(id);
          if (it != last_seq.end() && d.frame->seq <= it->second)
            VD_FUZZ_CHECK(gate->counters().source_restarts == restarts + 1);
          last_seq[id] = d.frame->seq;
          break;
        }
        case vd::FrameVerdict::kRejected:
          ++rejected;
          VD_FUZZ_CHECK(!d.frame && !d.status.ok() && !d.reason.empty());
          break;
        case vd::FrameVerdict::kStale:
          ++stale;
          VD_FUZZ_CHECK(!d.frame);
          break;
        case vd::FrameVerdict::kForeign:
          ++foreign;
          VD_FUZZ_CHECK(!d.frame);
          break;
        case vd::FrameVerdict::kRateLimited:
          ++limited;
          VD_FUZZ_CHECK(!d.frame);
          break;
        case vd::FrameVerdict::kHeld: {
          ++held;
          VD_FUZZ_CHECK(!d.frame);
          auto wire = vd::DecodeLcm<vdeform::rgbd_frame_t>(msg, len);
          VD_FUZZ_CHECK(wire.ok());
          auto it = last_seq.find(wire->source_id);
          VD_FUZZ_CHECK(it != last_seq.end() && wire->seq - it->second > max_jump);
          break;
        }
      }
      VD_FUZZ_CHECK(gate->counters().lost >= 0 && gate->counters().lost <= (max_jump - 1) * accepted);
    } else {
      vd::ControlDecision d = gate->OnControl(msg, len, kNowUs);
      if (gate->TakeMeshRequest()) {
        VD_FUZZ_CHECK(!last_served_us || g_clock_us - *last_served_us >= vd::kMeshRequestIntervalUs);
        last_served_us = g_clock_us;
      }
      if (!d.status.ok()) continue;
      const int8_t c = d.msg.command;
      VD_FUZZ_CHECK(c == vdeform::control_t::COMMAND_RESET || c == vdeform::control_t::COMMAND_SAVE_SNAPSHOT ||
                    c == vdeform::control_t::COMMAND_REQUEST_MESH);
      if (c != vdeform::control_t::COMMAND_REQUEST_MESH) {
        VD_FUZZ_CHECK(vd::VerifyControl(kKey, d.msg).ok());
        VD_FUZZ_CHECK(d.msg.utime > last_control_utime);
        last_control_utime = d.msg.utime;
      }
    }
  }
  const vd::GateCounters& c = gate->counters();
  VD_FUZZ_CHECK(c.received == frames);
  VD_FUZZ_CHECK(c.rejected == rejected && c.foreign == foreign && c.duplicates + c.reordered == stale);
  VD_FUZZ_CHECK(c.held == held && c.rate_limited == limited);
  VD_FUZZ_CHECK(accepted + rejected + stale + foreign + held + limited == frames);
  VD_FUZZ_CHECK(int64_t(last_seq.size()) <= vd::GateParams().max_sources);
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  vd::fuzz::Quiet();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  vd::GateOptions options;
  options.clock = Tick;
  options.control_key = kKey;
  options.accept_sources = {"capture-a", "capture-b", ""};
  vd::FrameGate open(options);
  RunGate(&open, data, size);
  static const vd::FrameKeys keys = *vd::FrameKeys::Parse(kFrameKeyFile, "fuzz");
  options.frame_keys = keys;
  vd::FrameGate keyed(options);
  RunGate(&keyed, data, size);
  return 0;
}
