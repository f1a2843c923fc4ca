#pragma once
// Whether the LCM node starts feature detection for a frame the moment it arrives, decided without
// the engine: from when the worker began its current frame, how long frames take, and how often
// they arrive.
//
// The mailbox keeps only the newest frame. When the sensor is faster than the worker, most frames
// are replaced before the worker takes them, and detection started for each of them is wasted:
// at 30 Hz with ~15 ms of SIFT per frame that was half a core of a 2-core machine, taken from the
// solve. So a frame is prefetched only when it is likely to be the one the worker takes next: no
// newer frame is expected before the worker's current frame ends. A wrong guess costs little: an
// unprefetched frame that is taken is detected beside its own preprocessing (Engine::Process), and
// a prefetched frame that is replaced wastes one detection.
#include <chrono>

namespace vd {

class PrefetchPolicy {
 public:
  using Clock = std::chrono::steady_clock;

  // The worker starts a frame at `now`.
  void WorkerStarted(Clock::time_point now) {
    busy_ = true;
    started_ = now;
  }
  // The worker finished its frame at `now`: the frame's duration enters the running mean.
  void WorkerFinished(Clock::time_point now) {
    busy_ = false;
    Mix(&frame_s_, std::chrono::duration<double>(now - started_).count());
  }
  // A frame arrived at `now` and went to the mailbox; true: start its detection now.
  bool OnArrival(Clock::time_point now) {
    const bool first = !have_arrival_;
    if (!first) Mix(&interval_s_, std::chrono::duration<double>(now - last_arrival_).count());
    last_arrival_ = now;
    have_arrival_ = true;
    // An idle worker takes it at once and detects it beside preprocessing; with no history yet
    // there is nothing to predict from.
    if (!busy_ || first || frame_s_ < 0 || interval_s_ < 0) return busy_;
    const double remaining = frame_s_ - std::chrono::duration<double>(now - started_).count();
    return remaining < interval_s_;
  }

 private:
  // Running means (exponential, weight kMix for the newest), negative until the first sample.
  static constexpr double kMix = 0.25;
  static void Mix(double* mean, double sample) { *mean = *mean < 0 ? sample : (1 - kMix) * *mean + kMix * sample; }

  // Whether the worker is inside a frame, and since when.
  bool busy_ = false;
  Clock::time_point started_{};
  // Seconds per frame of the worker, and between arrivals.
  double frame_s_ = -1, interval_s_ = -1;
  // The previous arrival, for the interval.
  bool have_arrival_ = false;
  Clock::time_point last_arrival_{};
};

}  // namespace vd
