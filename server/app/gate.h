#pragma once
// What the node accepts from the network, decided without the engine: frames (decoding,
// validation, source filter, sequence numbers) and control commands (decoding, HMAC, replay).
// Everything here is deterministic and allocation-bounded, so the fuzz target drives it directly.
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "vd/common/auth.h"
#include "vd/common/frame.h"
#include "vd/common/messages.h"
#include "vd/common/status.h"

namespace vd {

struct GateOptions {
  // Frames from other source ids are ignored (counted); empty = any source.
  std::vector<std::string> accept_sources;
  // HMAC key for control commands; empty = control is not authenticated (LCM has no auth).
  std::string control_key;
  // Keys frames must be signed with (one for every source, or per source); empty = frames are
  // not authenticated.
  FrameKeys frame_keys;
  // Authenticated commands older or newer than this (vs the server's clock) are refused, which
  // with the strictly increasing utime check stops replays.
  int64_t control_max_skew_us = 30'000'000;
  // Frames declaring more pixels are refused before decoding (a 16-byte RVL stream can declare an
  // 8192 x 8192 image: 128 MB of depth). 0 = no limit beyond the decoders' 8192 x 8192.
  int64_t max_frame_pixels = 2048 * 2048;
};

// Per-frame outcome.
enum class FrameVerdict {
  kAccept,
  // Refused by decoding or validation (status + reason say why).
  kRejected,
  // A duplicate or an older frame of a source that already sent a newer one.
  kStale,
  // From a source id not in accept_sources.
  kForeign,
};

struct FrameDecision {
  FrameVerdict verdict = FrameVerdict::kRejected;
  Status status;
  // Short reason for the status breakdown (kRejected).
  std::string reason;
  std::optional<RgbdFrame> frame;
};

struct ControlDecision {
  Status status;  // not ok: refused
  vdeform::control_t msg;
};

struct GateCounters {
  int64_t received = 0;
  int64_t rejected = 0;
  // Duplicates (same seq again) and reordered frames (an older seq after a newer one).
  int64_t duplicates = 0;
  int64_t reordered = 0;
  // Sequence numbers skipped between accepted frames of a source (frames lost on the way).
  int64_t lost = 0;
  // A source that came back with a new epoch, or its seq back with a newer capture time: its
  // client restarted.
  int64_t source_restarts = 0;
  int64_t foreign = 0;
  int64_t control_accepted = 0;
  int64_t control_refused = 0;
};

class FrameGate {
 public:
  explicit FrameGate(GateOptions options) : options_(std::move(options)) {}

  FrameDecision OnFrame(const void* data, size_t size);
  // now_us: the server's clock (microseconds since the epoch).
  ControlDecision OnControl(const void* data, size_t size, int64_t now_us);
  // Forgets the sequence state (a reset model accepts any source's next frame).
  void ForgetSequences() { sources_.clear(); }

  const GateCounters& counters() const { return counters_; }
  bool authenticated_control() const { return !options_.control_key.empty(); }
  bool authenticated_frames() const { return !options_.frame_keys.empty(); }

 private:
  struct SourceState {
    int64_t epoch = 0;
    int64_t seq = -1;
    int64_t utime = 0;
  };
  // Refuses a frame that is not signed under its source's key: "no_frame_key", "unsigned" or
  // "bad_signature" in d; true when it may go on.
  bool Authenticate(const vdeform::rgbd_frame_t& msg, FrameDecision* d);
  GateOptions options_;
  GateCounters counters_;
  std::map<std::string, SourceState> sources_;
  int64_t last_control_utime_ = 0;
};

// Short reason names for the status message's rejection breakdown.
std::string RejectReason(const Status& s);

}  // namespace vd
