// Rate limits with an injected clock (no sleeps): exact counts of what RateLimiter and
// KeyedRateLimiter take, and the bounds of the gate's rate parameters. The gate's limits on frames,
// control messages and REQUEST_MESH: gate_test.cpp (GateTest, GateControlTest).
#include <gtest/gtest.h>

#include "gate.h"
#include "rate_limit.h"

namespace vd {
namespace {

int Allowed(RateLimiter* r, int64_t now_us, int attempts) {
  int n = 0;
  for (int i = 0; i < attempts; ++i) n += r->Allow(now_us) ? 1 : 0;
  return n;
}

TEST(RateLimiterTest, ABurstOfOneSecondThenTheRate) {
  RateLimiter r(100.0);
  EXPECT_EQ(Allowed(&r, 0, 150), 100) << "a second's worth at once";
  EXPECT_EQ(Allowed(&r, 5'000, 10), 0);
  EXPECT_EQ(Allowed(&r, 10'000, 10), 1) << "one more per 10 ms";
  EXPECT_EQ(Allowed(&r, 29'999, 10), 1);
  EXPECT_EQ(Allowed(&r, 30'000, 10), 1);
  // Idle for two seconds: the whole burst again, no more.
  EXPECT_EQ(Allowed(&r, 2'030'000, 150), 100);
  // One attempt per ms for 10 s from a full burst: the burst, then one per 10 ms (999 more in
  // the 9.999 s after the first attempt); then, with the burst spent, exactly 100 per second.
  int n = 0;
  for (int64_t t = 4'000'000; t < 14'000'000; t += 1'000) n += r.Allow(t) ? 1 : 0;
  EXPECT_EQ(n, 1099);
  n = 0;
  for (int64_t t = 14'000'000; t < 15'000'000; t += 1'000) n += r.Allow(t) ? 1 : 0;
  EXPECT_EQ(n, 100);
}

TEST(RateLimiterTest, SlowRatesAllowOneAtATime) {
  RateLimiter r(0.5);
  EXPECT_EQ(Allowed(&r, 0, 5), 1);
  EXPECT_EQ(Allowed(&r, 1'999'999, 5), 0);
  EXPECT_EQ(Allowed(&r, 2'000'000, 5), 1);
}

TEST(RateLimiterTest, KeysOfTheirOwnUpToTheBoundTheRestShareOne) {
  KeyedRateLimiter k(2.0, 2);
  // Untracked keys share one limiter: a burst of 2 between them.
  EXPECT_TRUE(k.Allow("a", 0));
  EXPECT_TRUE(k.Allow("b", 0));
  EXPECT_FALSE(k.Allow("c", 0));
  EXPECT_TRUE(k.Track("a"));
  EXPECT_TRUE(k.Track("b"));
  EXPECT_TRUE(k.Track("a")) << "already tracked";
  EXPECT_FALSE(k.Track("c")) << "the bound";
  EXPECT_EQ(k.size(), 2u);
  EXPECT_TRUE(k.tracked("a"));
  EXPECT_FALSE(k.tracked("c"));
  // Each tracked key has its own burst of 2; the shared one is still spent.
  int a = 0, b = 0, other = 0;
  for (int i = 0; i < 5; ++i) {
    a += k.Allow("a", 0);
    b += k.Allow("b", 0);
    other += k.Allow("name-" + std::to_string(i), 0);
  }
  EXPECT_EQ(a, 2);
  EXPECT_EQ(b, 2);
  EXPECT_EQ(other, 0) << "rotating names get no more than one key's rate";
  EXPECT_EQ(k.size(), 2u);
}

TEST(GateParamsRateTest, RatesAndSourcesAreValidatedWithTheirFlags) {
  GateParams p;
  EXPECT_TRUE(p.Validate().ok());
  p.max_frame_rate = 0;
  EXPECT_NE(p.Validate().message().find("--max-frame-rate"), std::string::npos);
  p.max_frame_rate = 30;
  p.max_control_rate = -1;
  EXPECT_NE(p.Validate().message().find("--max-control-rate"), std::string::npos);
  p.max_control_rate = 1;
  p.max_sources = 0;
  EXPECT_NE(p.Validate().message().find("--max-sources"), std::string::npos);
  p.max_sources = 4097;
  EXPECT_FALSE(p.Validate().ok());
}

}  // namespace
}  // namespace vd
