#include "prefetch_policy.h"

#include <gtest/gtest.h>

namespace vd {
namespace {

using Clock = PrefetchPolicy::Clock;
using std::chrono::milliseconds;

// A worker taking 100 ms a frame, a sensor at 30 Hz: of the three frames arriving during a frame,
// only the one arriving in the frame's last 33 ms (no newer frame expected before the worker is
// free) is prefetched.
TEST(PrefetchPolicyTest, OnlyTheFrameLikelyToBeTakenNextIsPrefetched) {
  PrefetchPolicy p;
  const Clock::time_point t0{};
  auto at = [&](int ms) { return t0 + milliseconds(ms); };
  // Nothing known yet: an idle worker detects beside preprocessing; a busy one prefetches.
  EXPECT_FALSE(p.OnArrival(at(0)));
  p.WorkerStarted(at(0));
  EXPECT_TRUE(p.OnArrival(at(33)));
  // Frames every 33 ms; frames take 100 ms, each starting when the previous one ends.
  int prefetched = 0, arrivals = 0, next = 66;
  for (int frame = 0; frame < 10; ++frame) {
    const int start = 100 * frame, end = start + 100;
    if (frame > 0) p.WorkerStarted(at(start));
    for (; next < end; next += 33, ++arrivals) {
      const bool fetched = p.OnArrival(at(next));
      prefetched += fetched;
      // Only an arrival in the frame's last ~33 ms can be the frame taken next.
      if (frame >= 2) EXPECT_EQ(fetched, end - next < 33) << "arrival at " << next << " ms";
    }
    p.WorkerFinished(at(end));
  }
  EXPECT_EQ(arrivals, 29);
  EXPECT_LE(prefetched, 11);
  p.WorkerFinished(at(1000));
  EXPECT_FALSE(p.OnArrival(at(1001)));  // idle: taken at once
}

// A worker faster than the sensor: every frame arrives to an idle worker, none is prefetched; a
// frame arriving while a short frame is being finished is.
TEST(PrefetchPolicyTest, AFastWorkerIsNeverSentPrefetches) {
  PrefetchPolicy p;
  Clock::time_point t{};
  for (int i = 0; i < 10; ++i) {
    EXPECT_FALSE(p.OnArrival(t));
    p.WorkerStarted(t);
    p.WorkerFinished(t + milliseconds(10));
    t += milliseconds(33);
  }
  p.WorkerStarted(t);
  EXPECT_TRUE(p.OnArrival(t + milliseconds(5)));
}

// The means follow a change of pace: after the worker slows to 300 ms, a frame arriving 100 ms into
// a frame is no longer prefetched.
TEST(PrefetchPolicyTest, TheMeansFollowTheWorkersPace) {
  PrefetchPolicy p;
  Clock::time_point t{};
  for (int i = 0; i < 20; ++i) {
    p.WorkerStarted(t);
    p.OnArrival(t + milliseconds(50));
    p.WorkerFinished(t + milliseconds(60));
    t += milliseconds(100);
  }
  p.WorkerStarted(t);
  EXPECT_TRUE(p.OnArrival(t + milliseconds(40)));  // 20 ms left of ~60, arrivals ~100 ms apart
  p.WorkerFinished(t + milliseconds(300));
  t += milliseconds(300);
  for (int i = 0; i < 20; ++i) {
    p.WorkerStarted(t);
    for (int ms : {0, 100, 200}) p.OnArrival(t + milliseconds(ms));
    p.WorkerFinished(t + milliseconds(300));
    t += milliseconds(300);
  }
  p.WorkerStarted(t);
  EXPECT_FALSE(p.OnArrival(t + milliseconds(100)));  // ~200 ms left, arrivals ~100 ms apart
}

}  // namespace
}  // namespace vd
