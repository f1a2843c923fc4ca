#pragma once
// Sends frames on the LCM frame channel at a target rate and, in lockstep mode, only after the
// server reported the previous frame of this source as processed (with time-out and re-sends).
#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <set>
#include <string>

#include <lcm/lcm-cpp.hpp>
#include <vdeform/rgbd_frame_t.hpp>
#include <vdeform/server_status_t.hpp>

#include "vd/common/messages.h"
#include "vd/common/output_auth.h"
#include "vd/common/status.h"

namespace vd {

struct PacingOptions {
  // Frames per second to send at; 0 sends as fast as the source and the link allow (--max-rate).
  double fps = 30.0;
  // Wait for the server to report each frame processed before sending the next one, so an
  // offline run feeds the server exactly as fast as it can work and loses no frame.
  bool lockstep = false;
  // Seconds to wait for the server's acknowledgement before re-sending a frame.
  double lockstep_timeout_s = 10.0;
  // Re-sends of a frame without acknowledgement before giving up (a lost UDP fragment loses the
  // whole frame, so one re-send usually suffices; a dead server should not stall us forever).
  int lockstep_retries = 3;
  // Our source id; only status messages naming it acknowledge our frames.
  std::string source_id;
  // Where frames go and acknowledgements come from (--stream NAME; today's names by default).
  StreamChannels channels;
  // The server's output key (--output-key-file): only status messages that verify under it and
  // are newer than the last one taken acknowledge a frame, so a forged status naming our frame
  // cannot make us send on. Empty: every status counts, as before signing.
  std::string output_key;
  Status Validate() const;
};

struct PacingStats {
  // Messages published, re-sends included.
  int64_t published = 0;
  // Lockstep re-sends after a time-out.
  int64_t resends = 0;
  // Highest last_processed_seq acknowledged for our source id and the epoch of the frames we send
  // (-1: none yet); a status about an earlier run of our id acknowledges nothing.
  int64_t last_acked_seq = -1;
  // Status messages that failed to decode (logged once, then only counted).
  int64_t bad_status_messages = 0;
  // With an output key: status messages ignored because they were unsigned, wrongly signed or
  // replayed (logged once per reason).
  OutputRefusals status_refused;
};

class FramePacer {
 public:
  // `lcm` must outlive the pacer. In lockstep mode the pacer subscribes to the status channel
  // and dispatches incoming messages (all subscriptions of `lcm`) while it waits.
  // `stop` (may be null) ends any wait early when it becomes true (signal handlers set it).
  static StatusOr<std::unique_ptr<FramePacer>> Create(lcm::LCM* lcm, const PacingOptions& options,
                                                      const std::atomic<bool>* stop = nullptr);
  ~FramePacer();
  FramePacer(const FramePacer&) = delete;
  FramePacer& operator=(const FramePacer&) = delete;

  // Waits for the frame's slot in the schedule, publishes it on the frame channel and, in lockstep
  // mode, waits until the server acknowledged msg.seq, re-sending after each time-out. Returns
  // DeadlineExceeded after lockstep_retries unacknowledged re-sends, Unavailable when publishing
  // fails. Returns Ok early, with the frame possibly unacknowledged, when *stop becomes true.
  Status Send(const vdeform::rgbd_frame_t& msg);

  const PacingStats& stats() const { return stats_; }

 private:
  FramePacer(lcm::LCM* lcm, const PacingOptions& options, const std::atomic<bool>* stop);
  void OnStatus(const lcm::ReceiveBuffer* buffer, const std::string& channel);
  bool Stopped() const { return stop_ && stop_->load(); }
  // Sleeps until `until` (steady clock), waking early on stop.
  void SleepUntil(std::chrono::steady_clock::time_point until) const;
  // Dispatches LCM messages until seq is acknowledged or `until`; true when acknowledged.
  StatusOr<bool> WaitForAck(int64_t seq, std::chrono::steady_clock::time_point until);

  lcm::LCM* lcm_;
  PacingOptions options_;
  const std::atomic<bool>* stop_;
  lcm::Subscription* subscription_ = nullptr;
  PacingStats stats_;
  // When the next frame may go out; unset before the first frame.
  std::chrono::steady_clock::time_point next_slot_;
  bool scheduled_ = false;
  // The epoch of the frames being sent (set by the first Send): acknowledgements must name it.
  std::optional<int64_t> epoch_;
  // Checks status messages under options_.output_key; unset without a key.
  std::optional<OutputVerifier> verifier_;
  // Refusal reasons already logged.
  std::set<OutputVerdict> logged_refusals_;
};

}  // namespace vd
