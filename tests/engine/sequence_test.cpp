// SourceSequence: a source's sequence numbers with exact counts. Losses are only numbers skipped
// within max_jump and not received since; a jump beyond max_jump is held until confirm_frames
// frames in a row confirm it; a new epoch (or seq 0 with a newer time) is a restart; with
// authenticated frames an earlier epoch is a replay.
#include <gtest/gtest.h>

#include "sequence.h"

namespace vd {
namespace {

using V = SequenceVerdict;

// Feeds frames of one epoch, committing every decision (as the gate does for valid frames), and
// sums the lost-frame changes.
class Feed {
 public:
  explicit Feed(SequenceParams params = {}, bool authenticated = false) : seq_(params, authenticated) {}
  V Send(int64_t seq, int64_t epoch = 1, int64_t utime = -1) {
    if (utime < 0) utime = 1000 + seq;
    const SequenceDecision d = seq_.Classify(epoch, seq, utime);
    seq_.Commit(d, epoch, seq, utime);
    lost_ += d.lost_delta;
    ++count_[int(d.verdict)];
    return d.verdict;
  }
  int64_t lost() const { return lost_; }
  int count(V v) const { return count_[int(v)]; }
  const SourceSequence& sequence() const { return seq_; }

 private:
  SourceSequence seq_;
  int64_t lost_ = 0;
  int count_[8] = {};
};

TEST(SequenceTest, LossesAreNumbersSkippedAndNotReceivedSince) {
  Feed f;
  EXPECT_EQ(f.Send(0), V::kFirst);
  EXPECT_EQ(f.Send(1), V::kNext);
  EXPECT_EQ(f.Send(5), V::kNext);
  EXPECT_EQ(f.lost(), 3) << "2, 3, 4 skipped";
  EXPECT_EQ(f.Send(3), V::kLate);
  EXPECT_EQ(f.lost(), 2) << "3 arrived after all";
  EXPECT_EQ(f.Send(3), V::kDuplicate) << "and a second copy of it is a duplicate";
  EXPECT_EQ(f.Send(5), V::kDuplicate);
  EXPECT_EQ(f.Send(1), V::kDuplicate);
  EXPECT_EQ(f.Send(2), V::kLate);
  EXPECT_EQ(f.Send(6), V::kNext);
  EXPECT_EQ(f.lost(), 1) << "only 4 never came";
  EXPECT_EQ(f.count(V::kLate), 2);
  EXPECT_EQ(f.count(V::kDuplicate), 3);
  EXPECT_EQ(f.sequence().seq(), 6);
}

TEST(SequenceTest, NumbersBelowTheFirstFrameWereNeverLost) {
  Feed f;
  EXPECT_EQ(f.Send(10), V::kFirst);
  EXPECT_EQ(f.Send(8), V::kLate);
  EXPECT_EQ(f.Send(8), V::kDuplicate);
  EXPECT_EQ(f.lost(), 0);
}

// The attack: one forged frame numbered near 2^62 under the real source's id and epoch
// made every later real frame "reordered" and the loss counter jump by ~5e8.
TEST(SequenceTest, OneHugeNumberNeitherStallsTheStreamNorCountsLosses) {
  Feed f;
  for (int64_t s = 0; s < 5; ++s) EXPECT_EQ(f.Send(s), s == 0 ? V::kFirst : V::kNext);
  EXPECT_EQ(f.Send(int64_t(1) << 62), V::kJumpHeld);
  for (int64_t s = 5; s < 10; ++s) EXPECT_EQ(f.Send(s), V::kNext) << s;
  EXPECT_EQ(f.lost(), 0);
  EXPECT_EQ(f.sequence().seq(), 9);
  EXPECT_FALSE(f.sequence().holding_jump()) << "the old stream went on: the jump is dropped";
  // Repeating the same huge number never confirms it.
  for (int k = 0; k < 10; ++k) EXPECT_EQ(f.Send(int64_t(1) << 62), V::kJumpHeld);
  EXPECT_EQ(f.Send(10), V::kNext);
  EXPECT_EQ(f.count(V::kJumpHeld), 11);
  EXPECT_EQ(f.count(V::kJumpAdopted), 0);
}

TEST(SequenceTest, AJumpIsAdoptedWhenConfirmedByTheFramesAfterIt) {
  Feed f;  // max_jump 300, confirm_frames 3
  EXPECT_EQ(f.Send(0), V::kFirst);
  EXPECT_EQ(f.Send(300), V::kNext) << "exactly max_jump ahead is taken";
  EXPECT_EQ(f.lost(), 299);
  EXPECT_EQ(f.Send(601), V::kJumpHeld) << "301 ahead";
  EXPECT_EQ(f.Send(603), V::kJumpHeld) << "a loss inside the confirming run is allowed";
  EXPECT_EQ(f.Send(604), V::kJumpAdopted);
  EXPECT_EQ(f.sequence().seq(), 604);
  EXPECT_EQ(f.lost(), 299) << "an adopted jump counts no loss";
  EXPECT_EQ(f.Send(605), V::kNext);
  EXPECT_EQ(f.Send(601), V::kLate) << "held frames are below the new baseline";
  EXPECT_EQ(f.Send(300), V::kLate);
  EXPECT_EQ(f.lost(), 299);
}

TEST(SequenceTest, AFrameOfTheOldStreamCancelsAHeldJump) {
  Feed f;
  f.Send(0);
  EXPECT_EQ(f.Send(1000), V::kJumpHeld);
  EXPECT_EQ(f.Send(1001), V::kJumpHeld);
  EXPECT_EQ(f.Send(1), V::kNext);
  EXPECT_EQ(f.Send(1002), V::kJumpHeld) << "counting starts again";
  EXPECT_EQ(f.Send(1003), V::kJumpHeld);
  EXPECT_EQ(f.Send(1004), V::kJumpAdopted);
  // Not in a row: a second held run far from the first starts over.
  Feed g;
  g.Send(0);
  EXPECT_EQ(g.Send(1000), V::kJumpHeld);
  EXPECT_EQ(g.Send(5000), V::kJumpHeld);
  EXPECT_EQ(g.Send(5001), V::kJumpHeld);
  EXPECT_EQ(g.Send(5002), V::kJumpAdopted);
}

TEST(SequenceTest, ConfirmFramesOneTakesEveryJump) {
  SequenceParams p;
  p.confirm_frames = 1;
  Feed f(p);
  f.Send(0);
  EXPECT_EQ(f.Send(int64_t(1) << 62), V::kJumpAdopted);
  EXPECT_EQ(f.lost(), 0);
}

TEST(SequenceTest, RestartsAreANewEpochOrSeqZeroWithANewerTime) {
  Feed f;
  f.Send(0, 7, 100);
  f.Send(1, 7, 200);
  f.Send(2, 7, 300);
  EXPECT_EQ(f.Send(0, 7, 300), V::kDuplicate) << "a re-send of frame 0 carries its old time";
  EXPECT_EQ(f.Send(0, 7, 400), V::kRestart) << "a sender that keeps its epoch";
  EXPECT_EQ(f.Send(1, 7, 500), V::kNext);
  EXPECT_EQ(f.Send(0, 9, 50), V::kRestart) << "unauthenticated: a new epoch is a restart whatever its time";
  EXPECT_EQ(f.Send(1, 9, 60), V::kNext);
  EXPECT_EQ(f.Send(500, 9, 70), V::kJumpHeld) << "a restarted run has its own jump rule";
  EXPECT_EQ(f.count(V::kRestart), 2);
  EXPECT_EQ(f.lost(), 0);
}

TEST(SequenceTest, AuthenticatedEarlierRunsAreReplays) {
  Feed f(SequenceParams{}, true);
  f.Send(0, 7, 1000);
  f.Send(1, 7, 1033);
  EXPECT_EQ(f.Send(0, 8, 2000), V::kRestart);
  EXPECT_EQ(f.Send(1, 8, 2033), V::kNext);
  EXPECT_EQ(f.Send(1, 7, 1033), V::kReplayed) << "the first run played back";
  EXPECT_EQ(f.Send(5, 7, 1100), V::kReplayed);
  EXPECT_EQ(f.Send(0, 9, 2033), V::kReplayed) << "an epoch whose time is not after the last frame";
  EXPECT_EQ(f.Send(0, 9, 2034), V::kRestart);
  EXPECT_EQ(f.sequence().epoch(), 9);
  EXPECT_EQ(f.count(V::kReplayed), 3);
}

TEST(SequenceTest, NumbersOlderThanTheWindowAreLateWithoutTouchingLosses) {
  SequenceParams p;
  p.max_jump = 64;  // a window of 128 numbers either side of the baseline
  Feed f(p);
  f.Send(0);
  f.Send(60);   // 1..59 lost
  f.Send(120);  // 61..119 lost
  f.Send(180);  // 121..179 lost
  EXPECT_EQ(f.lost(), 59 * 3);
  EXPECT_EQ(f.Send(30), V::kLate) << "150 below the baseline: outside the window";
  EXPECT_EQ(f.Send(30), V::kLate) << "not remembered either";
  EXPECT_EQ(f.lost(), 59 * 3);
  EXPECT_EQ(f.Send(150), V::kLate);
  EXPECT_EQ(f.lost(), 59 * 3 - 1);
  EXPECT_EQ(f.Send(120), V::kDuplicate);
}

// The gate drops frames above their source's rate before decoding them: they were received, so
// their numbers are not lost, and a copy of one later is a duplicate.
TEST(SequenceTest, DroppedFramesAreReceivedNotLost) {
  SourceSequence s(SequenceParams{}, false);
  auto send = [&](int64_t seq, bool drop) {
    const SequenceDecision d = s.Classify(1, seq, 1000 + seq);
    if (drop) s.NoteDropped(d, seq);
    else s.Commit(d, 1, seq, 1000 + seq);
    return d;
  };
  send(0, false);
  EXPECT_EQ(send(1, true).verdict, V::kNext);
  EXPECT_EQ(send(2, true).verdict, V::kNext);
  const SequenceDecision three = send(3, false);
  EXPECT_EQ(three.verdict, V::kNext);
  EXPECT_EQ(three.lost_delta, 0) << "1 and 2 arrived (and were dropped)";
  EXPECT_EQ(send(5, false).lost_delta, 1) << "4 never arrived";
  EXPECT_EQ(send(2, false).verdict, V::kDuplicate);
  // A dropped held jump leaves nothing behind.
  EXPECT_EQ(send(100000, true).verdict, V::kJumpHeld);
  EXPECT_FALSE(s.holding_jump());
}

TEST(SequenceTest, ParamsAreValidatedWithTheirFlags) {
  SequenceParams p;
  EXPECT_TRUE(p.Validate().ok());
  p.max_jump = 0;
  EXPECT_NE(p.Validate().message().find("max_jump"), std::string::npos);
  EXPECT_NE(p.Validate().message().find("--max-seq-jump"), std::string::npos);
  p.max_jump = 100001;
  EXPECT_FALSE(p.Validate().ok());
  p.max_jump = 100000;
  EXPECT_TRUE(p.Validate().ok());
  p.confirm_frames = 0;
  EXPECT_NE(p.Validate().message().find("--seq-jump-confirm"), std::string::npos);
  p.confirm_frames = 101;
  EXPECT_FALSE(p.Validate().ok());
}

}  // namespace
}  // namespace vd
