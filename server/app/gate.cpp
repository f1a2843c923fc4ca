#include "gate.h"

#include <algorithm>
#include <cstdlib>

namespace vd {

void GateParams::Bind(FlagParser* f) {
  f->Add("max-frame-pixels", &max_frame_pixels,
         "Frames declaring more pixels (width x height) are refused before decoding (0 = up to 8192 x 8192)");
  f->Add("max-seq-jump", &sequence.max_jump,
         "A frame numbered more than N after its source's newest one is held, not taken, until "
         "--seq-jump-confirm frames in a row follow it (300 = 10 s at 30 Hz); numbers skipped within N "
         "count as lost",
         "N");
  f->Add("seq-jump-confirm", &sequence.confirm_frames,
         "Frames in a row (the first included, each newer and within --max-seq-jump of the last) that confirm "
         "a jump; a frame of the old sequence in between cancels it (1 = take every jump)",
         "N");
}

Status GateParams::Validate() const {
  if (max_frame_pixels < 0)
    return ParamOutOfBounds("GateParams", "max_frame_pixels", double(max_frame_pixels), ">= 0 (--max-frame-pixels)");
  return sequence.Validate();
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

FrameDecision FrameGate::Reject(Status status, std::string reason) {
  ++counters_.rejected;
  FrameDecision d;
  d.status = std::move(status);
  d.reason = std::move(reason);
  return d;
}

FrameDecision FrameGate::OnFrame(const void* data, size_t size) {
  ++counters_.received;
  auto msg = DecodeLcm<vdeform::rgbd_frame_t>(data, size);
  if (!msg.ok()) return Reject(msg.status(), "malformed_message");
  FrameDecision d;
  if (!options_.accept_sources.empty() &&
      std::find(options_.accept_sources.begin(), options_.accept_sources.end(), msg->source_id) ==
          options_.accept_sources.end()) {
    ++counters_.foreign;
    d.verdict = FrameVerdict::kForeign;
    d.status = PermissionDenied("source '" + msg->source_id + "' is not accepted");
    return d;
  }
  const int64_t max_pixels = options_.params.max_frame_pixels;
  if (max_pixels > 0 && int64_t(msg->width) * int64_t(msg->height) > max_pixels)
    return Reject(OutOfRange("frame of " + std::to_string(msg->width) + "x" + std::to_string(msg->height) +
                             " exceeds the server's limit of " + std::to_string(max_pixels) + " pixels"),
                  "oversized");
  if (msg->seq < 0 || msg->utime < 0)
    return Reject(InvalidArgument("frame has a negative sequence number or capture time"), "invalid_frame");
  if (!Authenticate(*msg, &d)) return d;

  auto it = sources_.find(msg->source_id);
  const SequenceDecision seq =
      it == sources_.end() ? SequenceDecision{} : it->second.Classify(msg->epoch, msg->seq, msg->utime);
  const std::string what = "frame " + std::to_string(msg->seq) + " of '" + msg->source_id + "'";
  switch (seq.verdict) {
    case SequenceVerdict::kDuplicate:
    case SequenceVerdict::kLate:
      // Not decoded: an older view of the scene than the model holds. Marked received, so a late
      // frame is counted once and takes its number out of the lost ones.
      it->second.Commit(seq, msg->epoch, msg->seq, msg->utime);
      ++(seq.verdict == SequenceVerdict::kDuplicate ? counters_.duplicates : counters_.reordered);
      counters_.lost += seq.lost_delta;
      d.verdict = FrameVerdict::kStale;
      d.status = OutOfRange(what + " after " + std::to_string(it->second.seq()));
      return d;
    case SequenceVerdict::kReplayed:
      return Reject(PermissionDenied(what + " is from an earlier run (epoch " + std::to_string(msg->epoch) +
                                     ", capture time not after the source's last frame)"),
                    "replayed");
    default:
      break;
  }
  auto frame = MessageToFrame(*msg);
  if (!frame.ok()) return Reject(frame.status(), RejectReason(frame.status()));
  // Only valid frames move a source's sequence: garbage cannot.
  if (it == sources_.end())
    it = sources_.emplace(msg->source_id, SourceSequence(options_.params.sequence, authenticated_frames())).first;
  const int64_t before = it->second.seq();
  it->second.Commit(seq, msg->epoch, msg->seq, msg->utime);
  counters_.lost += seq.lost_delta;
  if (seq.verdict == SequenceVerdict::kRestart) ++counters_.source_restarts;
  if (seq.verdict == SequenceVerdict::kJumpAdopted) ++counters_.jumps;
  if (seq.verdict == SequenceVerdict::kJumpHeld) {
    ++counters_.held;
    d.verdict = FrameVerdict::kHeld;
    d.status = OutOfRange(what + " jumps " + std::to_string(msg->seq - before) + " ahead of " +
                          std::to_string(before) + " (more than " + std::to_string(options_.params.sequence.max_jump) +
                          "): held until confirmed");
    return d;
  }
  d.verdict = FrameVerdict::kAccept;
  d.frame = std::move(frame).value();
  return d;
}

bool FrameGate::Authenticate(const vdeform::rgbd_frame_t& msg, FrameDecision* d) {
  if (!authenticated_frames()) return true;
  const std::string* key = options_.frame_keys.For(msg.source_id);
  Status s = key ? VerifyFrame(*key, msg) : PermissionDenied("no frame key for source '" + msg.source_id + "'");
  if (s.ok()) return true;
  *d = Reject(s, !key ? "no_frame_key" : msg.auth_size == 0 ? "unsigned" : "bad_signature");
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
