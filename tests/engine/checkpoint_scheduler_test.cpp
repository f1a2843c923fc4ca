// When the node writes a checkpoint: never without --checkpoint or a model, never for an
// unchanged model, periodically once the interval has passed (not at all with interval 0), at
// once on SAVE_SNAPSHOT and at shutdown; a failed write is retried, a written one is not repeated.
#include <gtest/gtest.h>

#include "checkpoint_scheduler.h"

namespace vd {
namespace {

using Clock = CheckpointScheduler::Clock;
using std::chrono::milliseconds;
using std::chrono::seconds;
constexpr CheckpointTrigger kInterval = CheckpointTrigger::kInterval;
constexpr CheckpointTrigger kSnapshot = CheckpointTrigger::kSnapshot;
constexpr CheckpointTrigger kShutdown = CheckpointTrigger::kShutdown;

TEST(CheckpointSchedulerTest, NothingIsDueWithoutADirectoryAModelOrAChange) {
  const Clock::time_point t0{};
  CheckpointScheduler off(false, 30.0, t0);
  off.ModelChanged();
  for (CheckpointTrigger t : {kInterval, kSnapshot, kShutdown}) EXPECT_FALSE(off.Due(t, true, t0 + seconds(60)));

  CheckpointScheduler on(true, 30.0, t0);
  for (CheckpointTrigger t : {kInterval, kSnapshot, kShutdown}) {
    EXPECT_FALSE(on.Due(t, true, t0 + seconds(60))) << "the model has not changed";
  }
  on.ModelChanged();
  for (CheckpointTrigger t : {kInterval, kSnapshot, kShutdown}) {
    EXPECT_FALSE(on.Due(t, false, t0 + seconds(60))) << "no model (before the first frame, after RESET)";
    EXPECT_TRUE(on.Due(t, true, t0 + seconds(60)));
  }
}

TEST(CheckpointSchedulerTest, PeriodicCheckpointsWaitForTheIntervalSnapshotAndShutdownDoNot) {
  const Clock::time_point t0{};
  CheckpointScheduler s(true, 30.0, t0);
  s.ModelChanged();
  EXPECT_FALSE(s.Due(kInterval, true, t0 + milliseconds(29999)));
  EXPECT_TRUE(s.Due(kInterval, true, t0 + seconds(30)));
  EXPECT_TRUE(s.Due(kSnapshot, true, t0 + seconds(1)));
  EXPECT_TRUE(s.Due(kShutdown, true, t0 + seconds(1)));

  // Written at 1 s (SAVE_SNAPSHOT): nothing is due until the model changes again, and the next
  // periodic one is an interval after that write.
  s.Attempted(t0 + seconds(1), true);
  for (CheckpointTrigger t : {kInterval, kSnapshot, kShutdown}) EXPECT_FALSE(s.Due(t, true, t0 + seconds(100)));
  s.ModelChanged();
  EXPECT_FALSE(s.Due(kInterval, true, t0 + seconds(30)));
  EXPECT_TRUE(s.Due(kInterval, true, t0 + seconds(31)));
}

TEST(CheckpointSchedulerTest, IntervalZeroMeansOnlySnapshotAndShutdown) {
  const Clock::time_point t0{};
  for (double interval : {0.0, -1.0}) {
    CheckpointScheduler s(true, interval, t0);
    s.ModelChanged();
    EXPECT_FALSE(s.Due(kInterval, true, t0 + seconds(3600))) << interval;
    EXPECT_TRUE(s.Due(kSnapshot, true, t0)) << interval;
    EXPECT_TRUE(s.Due(kShutdown, true, t0)) << interval;
  }
}

TEST(CheckpointSchedulerTest, AFailedWriteIsRetriedAfterTheIntervalOrAtShutdown) {
  const Clock::time_point t0{};
  CheckpointScheduler s(true, 10.0, t0);
  s.ModelChanged();
  ASSERT_TRUE(s.Due(kInterval, true, t0 + seconds(10)));
  s.Attempted(t0 + seconds(10), false);
  EXPECT_FALSE(s.Due(kInterval, true, t0 + seconds(15))) << "a failing disk is not retried after every frame";
  EXPECT_TRUE(s.Due(kInterval, true, t0 + seconds(20)));
  EXPECT_TRUE(s.Due(kShutdown, true, t0 + seconds(15))) << "the model is still unsaved";
}

}  // namespace
}  // namespace vd
