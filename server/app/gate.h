#pragma once
// What the node accepts from the network, decided without the engine: frames (decoding,
// signature, source filter, sequence numbers, validation) and control commands (decoding, HMAC,
// replay). Everything here is deterministic and allocation-bounded, so the fuzz target drives it
// directly.
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "rate_limit.h"
#include "sequence.h"
#include "vd/common/auth.h"
#include "vd/common/flags.h"
#include "vd/common/frame.h"
#include "vd/common/messages.h"
#include "vd/common/status.h"

namespace vd {

// The gate's limits, bound to vdeform-server's flags (Bind) and checked once (Validate).
struct GateParams {
  // Frames declaring more pixels are refused before decoding (a 16-byte RVL stream can declare an
  // 8192 x 8192 image: 128 MB of depth). 0 = no limit beyond the decoders' 8192 x 8192.
  int64_t max_frame_pixels = 2048 * 2048;
  // Forward jumps of a source's sequence numbers and how they are confirmed.
  SequenceParams sequence;
  // Frames per second taken from one source, and control messages per second from one sender, in
  // bursts of up to a second's worth; the rest are counted and dropped before they are decoded.
  // 100 Hz covers any RGB-D sensor with room for a re-send; 10 Hz is far above what a person or a
  // script sends.
  double max_frame_rate = 100.0;
  double max_control_rate = 10.0;
  // Sources (and control senders) with state of their own: sequence, rate. A frame of one more
  // source is refused ("too_many_sources"); one more sender shares one rate with all the others.
  int64_t max_sources = 64;

  void Bind(FlagParser* flags);
  Status Validate() const;
};

struct GateOptions {
  GateParams params;
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
  // The rate limits' clock; empty = SteadyMicros.
  MonotonicClock clock;
};

// REQUEST_MESH makes the server multicast its meshes (a 50-byte datagram for several hundred KB):
// it serves at most one per this interval, whoever asks; requests in between are merged into one
// served when the interval ends.
inline constexpr int64_t kMeshRequestIntervalUs = 1'000'000;

// Per-frame outcome.
enum class FrameVerdict {
  kAccept,
  // Refused by decoding, signature or validation (status + reason say why).
  kRejected,
  // A duplicate or an older frame of a source that already sent a newer one.
  kStale,
  // From a source id not in accept_sources.
  kForeign,
  // Its sequence number jumped further ahead than GateParams::sequence.max_jump: held back until
  // the frames after it confirm the jump.
  kHeld,
  // Above GateParams::max_frame_rate for its source: dropped undecoded.
  kRateLimited,
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
  // Duplicates (a number received before) and reordered frames (an older number arriving late).
  int64_t duplicates = 0;
  int64_t reordered = 0;
  // Sequence numbers skipped between taken frames of a source and not received since (a late
  // frame takes its number back out). At most max_jump - 1 per taken frame: a confirmed jump
  // counts none, so no sequence number can inflate it beyond what the traffic carried.
  int64_t lost = 0;
  // A source that came back with a new epoch, or its seq back to 0 with a newer capture time: its
  // client restarted.
  int64_t source_restarts = 0;
  // Frames held back because their number jumped too far ahead, and jumps adopted after the
  // following frames confirmed them.
  int64_t held = 0;
  int64_t jumps = 0;
  int64_t foreign = 0;
  // Frames above their source's rate.
  int64_t rate_limited = 0;
  int64_t control_accepted = 0;
  // Control messages refused, of which control_rate_limited for the sender's rate.
  int64_t control_refused = 0;
  int64_t control_rate_limited = 0;
  // REQUEST_MESH: republications made, and requests merged into one already waiting.
  int64_t mesh_requests_served = 0;
  int64_t mesh_requests_merged = 0;
};

class FrameGate {
 public:
  explicit FrameGate(GateOptions options);

  FrameDecision OnFrame(const void* data, size_t size);
  // now_us: the server's clock (microseconds since the epoch), for the signed commands' skew.
  ControlDecision OnControl(const void* data, size_t size, int64_t now_us);
  // Whether the meshes should be republished now: a REQUEST_MESH is waiting and none was served in
  // the last kMeshRequestIntervalUs. The node asks on every tick.
  bool TakeMeshRequest();

  const GateCounters& counters() const { return counters_; }
  bool authenticated_control() const { return !options_.control_key.empty(); }
  bool authenticated_frames() const { return !options_.frame_keys.empty(); }

 private:
  // Refuses a frame that is not signed under its source's key: "no_frame_key", "unsigned" or
  // "bad_signature" in d; true when it may go on.
  bool Authenticate(const vdeform::rgbd_frame_t& msg, FrameDecision* d);
  // Counts a refusal with its reason.
  FrameDecision Reject(Status status, std::string reason);

  GateOptions options_;
  GateCounters counters_;
  // At most params.max_sources entries: created for a source's first valid frame.
  std::map<std::string, SourceSequence> sources_;
  KeyedRateLimiter frame_rate_;
  KeyedRateLimiter control_rate_;
  int64_t last_control_utime_ = 0;
  bool mesh_request_waiting_ = false;
  std::optional<int64_t> last_mesh_served_us_;
};

// Short reason names for the status message's rejection breakdown.
std::string RejectReason(const Status& s);

}  // namespace vd
