#include "vd/capture/pacing.h"

#include <cmath>
#include <sstream>
#include <thread>

#include "vd/common/log.h"
#include "vd/common/messages.h"

namespace vd {

using Clock = std::chrono::steady_clock;

namespace {
// Waits are cut into slices of this length so a stop request is seen promptly.
constexpr auto kWaitSlice = std::chrono::milliseconds(50);
// How many frame periods the schedule may lag before it restarts from now.
constexpr int kMaxLagPeriods = 3;
}  // namespace

Status PacingOptions::Validate() const {
  auto bad = [](const char* field, const std::string& value, const char* bound) {
    return InvalidArgument(std::string("pacing option ") + field + " = " + value + " violates " + bound);
  };
  if (!std::isfinite(fps) || fps < 0.0 || fps > 10000.0)
    return bad("fps", std::to_string(fps), "0 <= fps <= 10000 (0: no pacing)");
  if (!std::isfinite(lockstep_timeout_s) || lockstep_timeout_s <= 0.0 || lockstep_timeout_s > 3600.0)
    return bad("lockstep_timeout_s", std::to_string(lockstep_timeout_s), "0 < lockstep_timeout_s <= 3600");
  if (lockstep_retries < 0 || lockstep_retries > 1000)
    return bad("lockstep_retries", std::to_string(lockstep_retries), "0 <= lockstep_retries <= 1000");
  if (source_id.empty()) return bad("source_id", "''", "a non-empty id");
  return Status::Ok();
}

StatusOr<std::unique_ptr<FramePacer>> FramePacer::Create(lcm::LCM* lcm, const PacingOptions& options,
                                                         const std::atomic<bool>* stop) {
  VD_RETURN_IF_ERROR(options.Validate());
  if (!lcm || !lcm->good()) return Unavailable("FramePacer needs an initialised LCM instance");
  std::unique_ptr<FramePacer> pacer(new FramePacer(lcm, options, stop));
  if (options.lockstep) {
    pacer->subscription_ = lcm->subscribe(options.channels.status, &FramePacer::OnStatus, pacer.get());
    if (!pacer->subscription_) return Unavailable("cannot subscribe to " + options.channels.status);
  }
  return pacer;
}

FramePacer::FramePacer(lcm::LCM* lcm, const PacingOptions& options, const std::atomic<bool>* stop)
    : lcm_(lcm), options_(options), stop_(stop) {
  if (!options_.output_key.empty()) verifier_.emplace(options_.output_key);
}

FramePacer::~FramePacer() {
  if (subscription_) lcm_->unsubscribe(subscription_);
}

void FramePacer::OnStatus(const lcm::ReceiveBuffer* buffer, const std::string&) {
  // Decoded here rather than by LCM's typed handler so a malformed message is counted, not thrown.
  StatusOr<vdeform::server_status_t> msg = DecodeLcm<vdeform::server_status_t>(buffer->data, buffer->data_size);
  if (!msg.ok()) {
    if (stats_.bad_status_messages++ == 0) {
      VD_LOG_WARNING << "ignoring malformed " << options_.channels.status << " messages: " << msg.status().ToString();
    }
    return;
  }
  if (verifier_) {
    const OutputCheck check = verifier_->Check(*msg);
    stats_.status_refused = verifier_->status_refused();
    if (!check.ok()) {
      if (logged_refusals_.insert(check.verdict).second)
        VD_LOG_WARNING << "lockstep: ignoring status messages not signed by the server ("
                       << OutputVerdictName(check.verdict) << "; counted, further ones not logged): "
                       << check.status.message();
      return;
    }
  }
  if (msg->last_source_id != options_.source_id || !epoch_ || msg->last_epoch != *epoch_) return;
  if (msg->last_processed_seq > stats_.last_acked_seq) stats_.last_acked_seq = msg->last_processed_seq;
}

void FramePacer::SleepUntil(Clock::time_point until) const {
  while (!Stopped()) {
    const auto now = Clock::now();
    if (now >= until) return;
    std::this_thread::sleep_for(std::min<Clock::duration>(until - now, kWaitSlice));
  }
}

StatusOr<bool> FramePacer::WaitForAck(int64_t seq, Clock::time_point until) {
  while (stats_.last_acked_seq < seq) {
    if (Stopped()) return false;
    const auto now = Clock::now();
    if (now >= until) return false;
    const auto slice = std::min<Clock::duration>(until - now, kWaitSlice);
    const int ms = std::max(1, static_cast<int>(std::chrono::duration_cast<std::chrono::milliseconds>(slice).count()));
    if (lcm_->handleTimeout(ms) < 0) return Unavailable("LCM failed while waiting for the server's status");
  }
  return true;
}

Status FramePacer::Send(const vdeform::rgbd_frame_t& msg) {
  if (epoch_ != msg.epoch) {
    epoch_ = msg.epoch;
    stats_.last_acked_seq = -1;
  }
  if (options_.fps > 0.0) {
    const auto period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / options_.fps));
    const auto now = Clock::now();
    // A frame that is a little late goes out at once and the schedule keeps its phase, so short
    // stalls (a slow read, a busy CPU) do not lower the mean rate; falling further behind restarts
    // the schedule instead of sending a burst.
    if (!scheduled_ || now - next_slot_ > kMaxLagPeriods * period) next_slot_ = now;
    SleepUntil(next_slot_);
    next_slot_ += period;
    scheduled_ = true;
    if (Stopped()) return Status::Ok();
  }
  const int attempts = options_.lockstep ? options_.lockstep_retries + 1 : 1;
  for (int attempt = 0; attempt < attempts; ++attempt) {
    if (lcm_->publish(options_.channels.frames, &msg) != 0)
      return Unavailable("cannot publish frame " + std::to_string(msg.seq) + " on " + options_.channels.frames);
    ++stats_.published;
    if (attempt > 0) ++stats_.resends;
    if (!options_.lockstep) return Status::Ok();
    const auto deadline =
        Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(options_.lockstep_timeout_s));
    VD_ASSIGN_OR_RETURN(bool acked, WaitForAck(msg.seq, deadline));
    if (acked || Stopped()) return Status::Ok();
    if (attempt + 1 < attempts) {
      VD_LOG_WARNING << "lockstep: no acknowledgement of frame " << msg.seq << " within " << options_.lockstep_timeout_s
                     << " s; re-sending (" << attempt + 1 << " of " << options_.lockstep_retries << ")";
    }
  }
  std::ostringstream os;
  os << "lockstep: the server did not report frame " << msg.seq << " of source '" << options_.source_id
     << "' processed after " << attempts << " sends " << options_.lockstep_timeout_s << " s apart (last acknowledged: "
     << stats_.last_acked_seq << "); is vdeform-server running on the same LCM URL?";
  return DeadlineExceeded(os.str());
}

}  // namespace vd
