// Rate limits with an injected clock (no sleeps): exact counts of what RateLimiter and
// KeyedRateLimiter take, and the gate's limits on frames per source, control messages per sender
// and REQUEST_MESH republications (at most one a second, in all).
#include <gtest/gtest.h>

#include "gate.h"
#include "rate_limit.h"
#include "vd/capture/synthetic.h"

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

// A clock the test moves.
struct FakeClock {
  int64_t now_us = 1'000'000;
  MonotonicClock fn() {
    return [this] { return now_us; };
  }
};

class GateRateTest : public ::testing::Test {
 protected:
  void SetUp() override {
    SyntheticOptions so;
    so.noise = false;
    so.width = 80;
    so.height = 60;
    auto scene = MakeSyntheticScene("tube", so);
    ASSERT_TRUE(scene.ok()) << scene.status().ToString();
    frame_ = (*scene)->Render(0);
  }
  FrameVerdict Send(FrameGate* g, const std::string& source, int64_t seq) {
    RgbdFrame f = frame_;
    f.source_id = source;
    f.seq = seq;
    f.utime = 1000 + seq;
    auto m = FrameToMessage(f, FrameEncodeOptions());
    EXPECT_TRUE(m.ok());
    std::vector<uint8_t> b(m->getEncodedSize());
    m->encode(b.data(), 0, int(b.size()));
    return g->OnFrame(b.data(), b.size()).verdict;
  }
  static Status Control(FrameGate* g, int8_t command, const std::string& sender) {
    vdeform::control_t m{};
    m.utime = 1;
    m.command = command;
    m.sender = sender;
    m.auth_size = 0;
    std::vector<uint8_t> b(m.getEncodedSize());
    m.encode(b.data(), 0, int(b.size()));
    return g->OnControl(b.data(), b.size(), 0).status;
  }
  RgbdFrame frame_;
  FakeClock clock_;
};

TEST_F(GateRateTest, FramesAboveTheSourceRateAreDroppedAndNotCountedLost) {
  GateOptions o;
  o.params.max_frame_rate = 10.0;
  o.clock = clock_.fn();
  FrameGate g(o);
  // The first frame spends the limiter new sources share; the source then has its own burst of 10.
  int accepted = 0, limited = 0;
  for (int64_t s = 0; s < 15; ++s) {
    const FrameVerdict v = Send(&g, "cam", s);
    accepted += v == FrameVerdict::kAccept;
    limited += v == FrameVerdict::kRateLimited;
  }
  EXPECT_EQ(accepted, 11);
  EXPECT_EQ(limited, 4);
  clock_.now_us += 100'000;  // one more frame's worth
  EXPECT_EQ(Send(&g, "cam", 15), FrameVerdict::kAccept);
  EXPECT_EQ(Send(&g, "cam", 16), FrameVerdict::kRateLimited);
  EXPECT_EQ(Send(&g, "cam", 12), FrameVerdict::kStale) << "dropped for its rate, received all the same";
  const GateCounters& c = g.counters();
  EXPECT_EQ(c.received, 18);
  EXPECT_EQ(c.rate_limited, 5);
  EXPECT_EQ(c.lost, 0) << "11..14 arrived: not lost";
  EXPECT_EQ(c.duplicates, 1);
  // Stale frames spend no rate: they are never decoded.
  clock_.now_us += 100'000;
  EXPECT_EQ(Send(&g, "cam", 17), FrameVerdict::kAccept);
}

TEST_F(GateRateTest, SourcesBeyondTheBoundAreRefused) {
  GateOptions o;
  o.params.max_sources = 2;
  o.clock = clock_.fn();
  FrameGate g(o);
  EXPECT_EQ(Send(&g, "a", 0), FrameVerdict::kAccept);
  EXPECT_EQ(Send(&g, "b", 0), FrameVerdict::kAccept);
  EXPECT_EQ(Send(&g, "c", 0), FrameVerdict::kRejected);
  EXPECT_EQ(Send(&g, "a", 1), FrameVerdict::kAccept) << "known sources go on";
  EXPECT_EQ(g.counters().rejected, 1);
}

TEST_F(GateRateTest, ControlMessagesAboveTheSenderRateAreRefusedAndCounted) {
  GateOptions o;
  o.params.max_control_rate = 2.0;
  o.clock = clock_.fn();
  FrameGate g(o);
  const int8_t reset = vdeform::control_t::COMMAND_RESET;
  // First message of a sender: the shared limiter (burst 2); then the sender's own (burst 2).
  EXPECT_TRUE(Control(&g, reset, "ops").ok());
  EXPECT_TRUE(Control(&g, reset, "ops").ok());
  EXPECT_TRUE(Control(&g, reset, "ops").ok());
  const Status limited = Control(&g, reset, "ops");
  EXPECT_FALSE(limited.ok());
  EXPECT_NE(limited.message().find("--max-control-rate"), std::string::npos) << limited.message();
  EXPECT_TRUE(Control(&g, reset, "viewer").ok()) << "another sender has its own rate";
  clock_.now_us += 500'000;
  EXPECT_TRUE(Control(&g, reset, "ops").ok());
  EXPECT_FALSE(Control(&g, reset, "ops").ok());
  const GateCounters& c = g.counters();
  EXPECT_EQ(c.control_accepted, 5);
  EXPECT_EQ(c.control_refused, 2);
  EXPECT_EQ(c.control_rate_limited, 2);
}

TEST_F(GateRateTest, MeshRequestsAreServedAtMostOnceASecondInAll) {
  GateOptions o;
  o.clock = clock_.fn();
  FrameGate g(o);
  const int8_t request = vdeform::control_t::COMMAND_REQUEST_MESH;
  EXPECT_FALSE(g.TakeMeshRequest()) << "nothing asked";
  EXPECT_TRUE(Control(&g, request, "viewer-1").ok());
  EXPECT_TRUE(g.TakeMeshRequest()) << "the first request is served at once";
  EXPECT_FALSE(g.TakeMeshRequest());
  // 50 requests from 5 viewers within the next second (each within its sender's rate): one
  // republication when the second ends.
  for (int i = 0; i < 50; ++i) EXPECT_TRUE(Control(&g, request, "viewer-" + std::to_string(i % 5)).ok()) << i;
  clock_.now_us += 999'999;
  EXPECT_FALSE(g.TakeMeshRequest());
  clock_.now_us += 1;
  EXPECT_TRUE(g.TakeMeshRequest());
  EXPECT_FALSE(g.TakeMeshRequest());
  clock_.now_us += 10'000'000;
  EXPECT_FALSE(g.TakeMeshRequest()) << "no request waiting";
  const GateCounters& c = g.counters();
  EXPECT_EQ(c.mesh_requests_served, 2);
  EXPECT_EQ(c.control_accepted, 51);
  EXPECT_EQ(c.mesh_requests_merged, 49) << "all but the first of the flood waited for the one served";
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
