#include "gate.h"

#include <algorithm>
#include <cstdlib>

namespace vd {
namespace {

// Largest gap of sequence numbers counted as lost frames at once.
constexpr int64_t kMaxCountedGap = int64_t(1) << 20;

}  // namespace

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

FrameDecision FrameGate::OnFrame(const void* data, size_t size) {
  FrameDecision d;
  ++counters_.received;
  auto msg = DecodeLcm<vdeform::rgbd_frame_t>(data, size);
  if (!msg.ok()) {
    ++counters_.rejected;
    d.status = msg.status();
    d.reason = "malformed_message";
    return d;
  }
  if (!options_.accept_sources.empty() &&
      std::find(options_.accept_sources.begin(), options_.accept_sources.end(), msg->source_id) ==
          options_.accept_sources.end()) {
    ++counters_.foreign;
    d.verdict = FrameVerdict::kForeign;
    d.status = PermissionDenied("source '" + msg->source_id + "' is not accepted");
    return d;
  }
  if (options_.max_frame_pixels > 0 && int64_t(msg->width) * int64_t(msg->height) > options_.max_frame_pixels) {
    ++counters_.rejected;
    d.status = OutOfRange("frame of " + std::to_string(msg->width) + "x" + std::to_string(msg->height) +
                          " exceeds the server's limit of " + std::to_string(options_.max_frame_pixels) + " pixels");
    d.reason = "oversized";
    return d;
  }
  if (msg->seq < 0 || msg->utime < 0) {
    ++counters_.rejected;
    d.status = InvalidArgument("frame has a negative sequence number or capture time");
    d.reason = "invalid_frame";
    return d;
  }
  if (!Authenticate(*msg, &d)) return d;
  auto it = sources_.find(msg->source_id);
  bool restart = false;
  if (it != sources_.end() && msg->epoch != it->second.epoch) {
    // Epochs are random, so only the capture time orders them: a signed frame of an epoch whose
    // time is not newer than the source's last frame is a recording played back.
    if (authenticated_frames() && msg->utime <= it->second.utime) {
      ++counters_.rejected;
      d.status = PermissionDenied("frame " + std::to_string(msg->seq) + " of '" + msg->source_id +
                                  "' is from an earlier run (epoch " + std::to_string(msg->epoch) + ", capture time " +
                                  std::to_string(msg->utime) + " us, not after " +
                                  std::to_string(it->second.utime) + ")");
      d.reason = "replayed";
      return d;
    }
    restart = true;
  } else if (it != sources_.end() && msg->seq <= it->second.seq) {
    if (msg->utime > it->second.utime) {
      // The sequence started again with a newer capture time: the client restarted.
      restart = true;
    } else {
      if (msg->seq == it->second.seq) ++counters_.duplicates;
      else ++counters_.reordered;
      d.verdict = FrameVerdict::kStale;
      d.status = OutOfRange("frame " + std::to_string(msg->seq) + " of '" + msg->source_id + "' after " +
                            std::to_string(it->second.seq));
      return d;
    }
  }
  auto frame = MessageToFrame(*msg);
  if (!frame.ok()) {
    ++counters_.rejected;
    d.status = frame.status();
    d.reason = RejectReason(frame.status());
    return d;
  }
  // Counted only for valid frames, so garbage cannot move a source's sequence.
  if (restart) ++counters_.source_restarts;
  else if (it != sources_.end() && msg->seq - it->second.seq > 1)
    // Both are >= 0, so the difference cannot overflow; a jump beyond kMaxCountedGap is counted
    // as that many (the counter must not overflow on a hostile sequence number).
    counters_.lost += std::min<int64_t>(msg->seq - it->second.seq - 1, kMaxCountedGap);
  sources_[msg->source_id] = SourceState{msg->epoch, msg->seq, msg->utime};
  d.verdict = FrameVerdict::kAccept;
  d.frame = std::move(frame).value();
  return d;
}

bool FrameGate::Authenticate(const vdeform::rgbd_frame_t& msg, FrameDecision* d) {
  if (!authenticated_frames()) return true;
  const std::string* key = options_.frame_keys.For(msg.source_id);
  Status s = key ? VerifyFrame(*key, msg) : PermissionDenied("no frame key for source '" + msg.source_id + "'");
  if (s.ok()) return true;
  ++counters_.rejected;
  d->reason = !key ? "no_frame_key" : msg.auth_size == 0 ? "unsigned" : "bad_signature";
  d->status = s;
  return false;
}

ControlDecision FrameGate::OnControl(const void* data, size_t size, int64_t now_us) {
  ControlDecision d;
  auto msg = DecodeLcm<vdeform::control_t>(data, size);
  if (!msg.ok()) {
    ++counters_.control_refused;
    d.status = msg.status();
    return d;
  }
  d.msg = std::move(msg).value();
  const int8_t cmd = d.msg.command;
  if (cmd != vdeform::control_t::COMMAND_RESET && cmd != vdeform::control_t::COMMAND_SAVE_SNAPSHOT &&
      cmd != vdeform::control_t::COMMAND_REQUEST_MESH) {
    ++counters_.control_refused;
    d.status = InvalidArgument("unknown control command " + std::to_string(int(cmd)));
    return d;
  }
  // REQUEST_MESH only republishes what viewers already receive: viewers stay read-only and
  // need no key. Commands that change or write state need the HMAC when a key is configured.
  if (authenticated_control() && cmd != vdeform::control_t::COMMAND_REQUEST_MESH) {
    Status s = VerifyControl(options_.control_key, d.msg);
    // |utime - now| without overflow for any int64 values.
    const uint64_t skew = d.msg.utime >= now_us ? uint64_t(d.msg.utime) - uint64_t(now_us)
                                                 : uint64_t(now_us) - uint64_t(d.msg.utime);
    if (s.ok() && skew > uint64_t(options_.control_max_skew_us))
      s = PermissionDenied("control message time is " + std::to_string(skew / 1000) +
                           " ms off the server's clock");
    if (s.ok() && d.msg.utime <= last_control_utime_) s = PermissionDenied("control message replayed");
    if (!s.ok()) {
      ++counters_.control_refused;
      d.status = s;
      return d;
    }
    last_control_utime_ = d.msg.utime;
  }
  ++counters_.control_accepted;
  d.status = Status::Ok();
  return d;
}

}  // namespace vd
