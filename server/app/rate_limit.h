#pragma once
// Rate limits of the gate: how many frames per source and control messages per sender it takes
// per second, with a monotonic clock the caller passes in (tests inject theirs, nothing sleeps).
#include <cstdint>
#include <functional>
#include <map>
#include <string>

namespace vd {

// Microseconds of a monotonic clock.
using MonotonicClock = std::function<int64_t()>;
// std::chrono::steady_clock in microseconds: the clock the server runs on.
int64_t SteadyMicros();

// `rate_hz` events per second on average, and bursts of up to one second's worth (at least 1):
// the generic cell rate algorithm, exact in integer microseconds.
class RateLimiter {
 public:
  explicit RateLimiter(double rate_hz);
  // Takes one event at now_us when the rate allows it; a refused event costs nothing.
  bool Allow(int64_t now_us);

 private:
  int64_t interval_us_;
  // How far ahead of now the theoretical arrival time may run: burst - 1 intervals.
  int64_t tolerance_us_;
  int64_t next_us_ = INT64_MIN;
};

// One RateLimiter per key (source id, sender) for up to max_keys keys that sent something the gate
// accepted; every other key shares one more, so a sender rotating names gets no more than one
// key's rate, and memory stays bounded whatever the names.
class KeyedRateLimiter {
 public:
  KeyedRateLimiter(double rate_hz, size_t max_keys);
  bool Allow(const std::string& key, int64_t now_us);
  // Gives `key` its own limiter; false when max_keys keys have one already.
  bool Track(const std::string& key);
  bool tracked(const std::string& key) const { return own_.count(key) > 0; }
  size_t size() const { return own_.size(); }

 private:
  double rate_hz_;
  size_t max_keys_;
  std::map<std::string, RateLimiter> own_;
  RateLimiter shared_;
};

}  // namespace vd
