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
  f->Add("max-frame-rate", &max_frame_rate,
         "Frames per second taken from one source (bursts of up to a second's worth); more are counted "
         "(frames_rate_limited) and dropped undecoded",
         "HZ");
  f->Add("max-control-rate", &max_control_rate,
         "Control messages per second taken from one sender (REQUEST_MESH is served at most once a second in "
         "all); more are counted (control_rate_limited) and refused",
         "HZ");
  f->Add("max-sources", &max_sources,
         "Sources whose sequence and rate the server tracks; a frame of one more source is refused "
         "(rejected_too_many_sources), one more control sender shares one rate with all the others",
         "N");
}

Status GateParams::Validate() const {
  if (max_frame_pixels < 0)
    return ParamOutOfBounds("GateParams", "max_frame_pixels", double(max_frame_pixels), ">= 0 (--max-frame-pixels)");
  if (!(max_frame_rate > 0.0 && max_frame_rate <= 10000.0))
    return ParamOutOfBounds("GateParams", "max_frame_rate", max_frame_rate,
                            "0 < max_frame_rate <= 10000 Hz (--max-frame-rate)");
  if (!(max_control_rate > 0.0 && max_control_rate <= 10000.0))
    return ParamOutOfBounds("GateParams", "max_control_rate", max_control_rate,
                            "0 < max_control_rate <= 10000 Hz (--max-control-rate)");
  if (max_sources < 1 || max_sources > 4096)
    return ParamOutOfBounds("GateParams", "max_sources", double(max_sources),
                            "1 <= max_sources <= 4096 (--max-sources)");
  return sequence.Validate();
}

FrameGate::FrameGate(GateOptions options)
    : options_(std::move(options)),
      frame_rate_(options_.params.max_frame_rate, size_t(options_.params.max_sources)),
      control_rate_(options_.params.max_control_rate, size_t(options_.params.max_sources)) {
  if (!options_.clock) options_.clock = SteadyMicros;
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
  const GateParams& p = options_.params;
  if (it == sources_.end() && sources_.size() >= size_t(p.max_sources))
    return Reject(Unavailable("source '" + msg->source_id + "' would be source " + std::to_string(p.max_sources + 1) +
                              "; the server tracks at most " + std::to_string(p.max_sources) + " (--max-sources)"),
                  "too_many_sources");
  // Before decoding: the rate bounds what the decoders spend on one source.
  if (!frame_rate_.Allow(msg->source_id, options_.clock())) {
    // Received, though not taken: its number is not lost.
    if (it != sources_.end()) it->second.NoteDropped(seq, msg->seq);
    ++counters_.rate_limited;
    d.verdict = FrameVerdict::kRateLimited;
    d.status = Unavailable(what + " is above the source's rate of " + std::to_string(p.max_frame_rate) +
                           " Hz (--max-frame-rate)");
    return d;
  }
  auto frame = MessageToFrame(*msg);
  if (!frame.ok()) return Reject(frame.status(), RejectReason(frame.status()));
  // Only valid frames move a source's sequence: garbage cannot.
  if (it == sources_.end()) {
    it = sources_.emplace(msg->source_id, SourceSequence(p.sequence, authenticated_frames())).first;
    frame_rate_.Track(msg->source_id);
  }
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
  auto refuse = [&](Status status) {
    ++counters_.control_refused;
    d.status = std::move(status);
    return d;
  };
  auto msg = DecodeLcm<vdeform::control_t>(data, size);
  if (!msg.ok()) return refuse(msg.status());
  d.msg = std::move(msg).value();
  const int8_t cmd = d.msg.command;
  if (cmd != vdeform::control_t::COMMAND_RESET && cmd != vdeform::control_t::COMMAND_SAVE_SNAPSHOT &&
      cmd != vdeform::control_t::COMMAND_REQUEST_MESH)
    return refuse(InvalidArgument("unknown control command " + std::to_string(int(cmd))));
  // REQUEST_MESH only republishes what viewers already receive: viewers stay read-only and
  // need no key. Commands that change or write state need the HMAC when a key is configured.
  const bool signed_command = authenticated_control() && cmd != vdeform::control_t::COMMAND_REQUEST_MESH;
  if (signed_command) {
    Status verified = VerifyControl(options_.control_key, d.msg);
    if (!verified.ok()) return refuse(std::move(verified));
    // |utime - now| without overflow for any int64 values.
    const uint64_t skew = d.msg.utime >= now_us ? uint64_t(d.msg.utime) - uint64_t(now_us)
                                                 : uint64_t(now_us) - uint64_t(d.msg.utime);
    if (skew > uint64_t(options_.control_max_skew_us))
      return refuse(PermissionDenied("control message time is " + std::to_string(skew / 1000) +
                                     " ms off the server's clock"));
    if (d.msg.utime <= last_control_utime_) return refuse(PermissionDenied("control message replayed"));
  }
  // After the HMAC: a forger's flood under a real sender's name does not spend that sender's rate.
  if (!control_rate_.Allow(d.msg.sender, options_.clock())) {
    ++counters_.control_rate_limited;
    return refuse(Unavailable("control messages from '" + d.msg.sender + "' above " +
                              std::to_string(options_.params.max_control_rate) + " Hz (--max-control-rate)"));
  }
  control_rate_.Track(d.msg.sender);
  if (signed_command) last_control_utime_ = d.msg.utime;
  if (cmd == vdeform::control_t::COMMAND_REQUEST_MESH) {
    if (mesh_request_waiting_) ++counters_.mesh_requests_merged;
    mesh_request_waiting_ = true;
  }
  ++counters_.control_accepted;
  d.status = Status::Ok();
  return d;
}

bool FrameGate::TakeMeshRequest() {
  if (!mesh_request_waiting_) return false;
  const int64_t now = options_.clock();
  if (last_mesh_served_us_ && now - *last_mesh_served_us_ < kMeshRequestIntervalUs) return false;
  mesh_request_waiting_ = false;
  last_mesh_served_us_ = now;
  ++counters_.mesh_requests_served;
  return true;
}

}  // namespace vd
