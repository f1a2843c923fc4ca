#pragma once
// When the node writes a checkpoint, decided without the engine or the disk: from --checkpoint,
// --checkpoint-interval, whether the model changed since the last checkpoint, and what asks (the
// worker between frames, a SAVE_SNAPSHOT command, a clean stop).
#include <chrono>

namespace vd {

enum class CheckpointTrigger {
  // The worker between frames: due once the interval has passed.
  kInterval,
  // A SAVE_SNAPSHOT command: due now.
  kSnapshot,
  // A clean stop: due now.
  kShutdown,
};

class CheckpointScheduler {
 public:
  using Clock = std::chrono::steady_clock;

  // enabled: --checkpoint DIR was given. interval_s: --checkpoint-interval (<= 0: only on
  // SAVE_SNAPSHOT and at shutdown). The first periodic checkpoint is due interval_s after start.
  CheckpointScheduler(bool enabled, double interval_s, Clock::time_point start)
      : enabled_(enabled), interval_s_(interval_s), last_attempt_(start) {}

  // A frame was fused into the model.
  void ModelChanged() { changed_ = true; }
  // Whether to write a checkpoint now: enabled, a model exists and changed since the last
  // checkpoint written, and the trigger is SAVE_SNAPSHOT or shutdown, or the interval has passed
  // since the last attempt.
  bool Due(CheckpointTrigger trigger, bool has_model, Clock::time_point now) const;
  // Records an attempt at `now`: a written checkpoint clears the change; a failed one leaves it, so
  // it is tried again after the interval, on SAVE_SNAPSHOT or at shutdown.
  void Attempted(Clock::time_point now, bool written);

 private:
  // Without --checkpoint nothing is ever due.
  bool enabled_;
  // Periodic checkpoints are this far apart; <= 0 turns them off.
  double interval_s_;
  // An unchanged model is not written again (a stopped stream costs no disk writes).
  bool changed_ = false;
  // Periodic checkpoints are spaced from the last attempt, so a failing disk is retried once per
  // interval, not after every frame.
  Clock::time_point last_attempt_;
};

}  // namespace vd
