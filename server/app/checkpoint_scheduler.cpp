#include "checkpoint_scheduler.h"

namespace vd {

bool CheckpointScheduler::Due(CheckpointTrigger trigger, bool has_model, Clock::time_point now) const {
  if (!enabled_ || !has_model || !changed_) return false;
  if (trigger != CheckpointTrigger::kInterval) return true;
  return interval_s_ > 0 && now - last_attempt_ >= std::chrono::duration<double>(interval_s_);
}

void CheckpointScheduler::Attempted(Clock::time_point now, bool written) {
  last_attempt_ = now;
  if (written) changed_ = false;
}

}  // namespace vd
