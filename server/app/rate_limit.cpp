#include "rate_limit.h"

#include <algorithm>
#include <chrono>
#include <cmath>

namespace vd {

int64_t SteadyMicros() {
  return std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

RateLimiter::RateLimiter(double rate_hz)
    : interval_us_(std::max<int64_t>(1, std::llround(1e6 / rate_hz))),
      tolerance_us_((std::max<int64_t>(1, std::llround(std::ceil(rate_hz))) - 1) * interval_us_) {}

bool RateLimiter::Allow(int64_t now_us) {
  const int64_t next = std::max(next_us_, now_us);
  if (next - now_us > tolerance_us_) return false;
  next_us_ = next + interval_us_;
  return true;
}

KeyedRateLimiter::KeyedRateLimiter(double rate_hz, size_t max_keys)
    : rate_hz_(rate_hz), max_keys_(max_keys), shared_(rate_hz) {}

bool KeyedRateLimiter::Allow(const std::string& key, int64_t now_us) {
  auto it = own_.find(key);
  return it != own_.end() ? it->second.Allow(now_us) : shared_.Allow(now_us);
}

bool KeyedRateLimiter::Track(const std::string& key) {
  if (own_.count(key)) return true;
  if (own_.size() >= max_keys_) return false;
  own_.emplace(key, RateLimiter(rate_hz_));
  return true;
}

}  // namespace vd
