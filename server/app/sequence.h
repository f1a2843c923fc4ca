#pragma once
// A source's sequence numbers as the gate sees them: the next frame, a duplicate, a late one, a
// restart of the client, a replay of an earlier run, or a jump too far ahead to believe until the
// frames after it confirm it. Pure (no clock, no strings); the gate keeps one per source, and
// SequenceTest and the fuzz target drive it directly.
#include <cstdint>
#include <vector>

#include "vd/common/status.h"

namespace vd {

struct SequenceParams {
  // A forward jump of more than this many frames (10 s at 30 Hz) is held, not adopted as the
  // source's baseline: one forged or corrupt sequence number near 2^62 would otherwise make every
  // later real frame look old.
  int64_t max_jump = 300;
  // Frames in a row, each newer than the last and at most max_jump after it, that confirm a jump
  // (the held frame included). A frame of the old stream in between cancels it.
  int confirm_frames = 3;
  Status Validate() const;
};

enum class SequenceVerdict {
  // The source's first frame: its baseline.
  kFirst,
  // Newer than the baseline by at most max_jump: taken; the numbers skipped count as lost.
  kNext,
  // A new epoch, or seq back to 0 with a newer capture time: the client restarted.
  kRestart,
  // More than max_jump ahead: held back until confirm_frames frames confirm it.
  kJumpHeld,
  // The frame that confirms a held jump: the new baseline (nothing counted as lost).
  kJumpAdopted,
  // A sequence number of this run already received (a re-send, or a recorded frame played back).
  kDuplicate,
  // Older than the baseline and not received before: it arrived late (reordered).
  kLate,
  // With authenticated frames: another epoch whose capture time is not after the source's last
  // frame, i.e. an earlier run played back (epochs are random, only the signed time orders them).
  kReplayed,
};

struct SequenceDecision {
  SequenceVerdict verdict = SequenceVerdict::kFirst;
  // Change of the source's lost-frame count: the numbers kNext skipped, or -1 when kLate brings
  // one of them after all.
  int64_t lost_delta = 0;
};

// Whether a verdict hands the frame on (to the engine): the others are not newer than what the
// model holds, or not yet believed.
bool Takes(SequenceVerdict v);

class SourceSequence {
 public:
  // authenticated: epoch, seq and utime are signed (kReplayed is possible).
  SourceSequence(const SequenceParams& params, bool authenticated);

  // What the frame (epoch, seq >= 0, utime) is to this source; changes nothing.
  SequenceDecision Classify(int64_t epoch, int64_t seq, int64_t utime) const;
  // Applies Classify's decision for the same frame (the gate commits only frames that validated,
  // so garbage cannot move the sequence; duplicates and late frames it commits undecoded).
  void Commit(const SequenceDecision& d, int64_t epoch, int64_t seq, int64_t utime);
  // A frame Classify called kNext that the gate dropped (above its source's rate): the number is
  // received, so it is never counted as lost, and a copy of it later is a duplicate.
  void NoteDropped(const SequenceDecision& d, int64_t seq);

  // The baseline: the newest taken sequence number (-1 before the first frame).
  int64_t seq() const { return seq_; }
  int64_t epoch() const { return epoch_; }
  bool holding_jump() const { return held_count_ > 0; }

 private:
  // Whether `seq` would extend the held jump.
  bool ExtendsHeld(int64_t seq) const;
  // The window: the numbers less than window_half() from the baseline, either side (more than
  // max_jump, so every kNext, the numbers it skips and frames dropped before it lie inside).
  int64_t window_half() const { return int64_t(received_.size()) * 32; }
  bool Received(int64_t seq) const;
  void SetReceived(int64_t seq, bool received);
  void StartRun(int64_t epoch, int64_t seq, int64_t utime);

  SequenceParams params_;
  bool authenticated_;
  int64_t epoch_ = 0;
  int64_t seq_ = -1;
  // Newest capture time taken from this source (orders epochs for kReplayed, restarts at 0).
  int64_t utime_ = 0;
  // The baseline a run, restart or adopted jump began at: numbers at or below it were never counted
  // as lost, so a late one there takes nothing back.
  int64_t floor_ = 0;
  // A ring of one bit per sequence number of the window, received or not; every other bit is 0.
  std::vector<uint64_t> received_;
  // The held jump: its newest number and how many frames in a row it has.
  int64_t held_seq_ = 0;
  int held_count_ = 0;
};

}  // namespace vd
