#include "sequence.h"

#include <algorithm>
#include <cassert>

#include "vd/common/flags.h"

namespace vd {
namespace {

// Larger windows would cost a source more than a few KB of bits and say nothing about a stream
// at any real frame rate (100000 frames = 55 min at 30 Hz).
constexpr int64_t kMaxJumpBound = 100000;
constexpr int kMaxConfirmFrames = 100;

}  // namespace

Status SequenceParams::Validate() const {
  if (max_jump < 1 || max_jump > kMaxJumpBound)
    return ParamOutOfBounds("SequenceParams", "max_jump", double(max_jump),
                            "1 <= max_jump <= " + std::to_string(kMaxJumpBound) + " (--max-seq-jump)");
  if (confirm_frames < 1 || confirm_frames > kMaxConfirmFrames)
    return ParamOutOfBounds("SequenceParams", "confirm_frames", double(confirm_frames),
                            "1 <= confirm_frames <= " + std::to_string(kMaxConfirmFrames) + " (--seq-jump-confirm)");
  return Status::Ok();
}

bool Takes(SequenceVerdict v) {
  return v == SequenceVerdict::kFirst || v == SequenceVerdict::kNext || v == SequenceVerdict::kRestart ||
         v == SequenceVerdict::kJumpAdopted;
}

SourceSequence::SourceSequence(const SequenceParams& params, bool authenticated)
    : params_(params), authenticated_(authenticated), received_(2 * size_t(params.max_jump / 64 + 1)) {
  assert(params.Validate().ok());
}

bool SourceSequence::ExtendsHeld(int64_t seq) const {
  return held_count_ > 0 && seq > held_seq_ && seq - held_seq_ <= params_.max_jump;
}

bool SourceSequence::Received(int64_t seq) const {
  const uint64_t bit = uint64_t(seq) % (uint64_t(received_.size()) * 64);
  return (received_[bit / 64] >> (bit % 64)) & 1;
}

void SourceSequence::SetReceived(int64_t seq, bool received) {
  const uint64_t bit = uint64_t(seq) % (uint64_t(received_.size()) * 64);
  const uint64_t mask = uint64_t(1) << (bit % 64);
  if (received) received_[bit / 64] |= mask;
  else received_[bit / 64] &= ~mask;
}

void SourceSequence::StartRun(int64_t epoch, int64_t seq, int64_t utime) {
  epoch_ = epoch;
  seq_ = seq;
  floor_ = seq;
  utime_ = std::max(utime_, utime);
  std::fill(received_.begin(), received_.end(), 0);
  SetReceived(seq, true);
  held_count_ = 0;
}

SequenceDecision SourceSequence::Classify(int64_t epoch, int64_t seq, int64_t utime) const {
  assert(seq >= 0);
  using V = SequenceVerdict;
  if (seq_ < 0) return {V::kFirst, 0};
  if (epoch != epoch_) {
    if (authenticated_ && utime <= utime_) return {V::kReplayed, 0};
    return {V::kRestart, 0};
  }
  // A sender that keeps its epoch across restarts: the seq from 0 again with a newer capture time
  // (a re-send of frame 0 carries its old time).
  if (seq == 0 && utime > utime_) return {V::kRestart, 0};
  if (seq > seq_) {
    // Both are >= 0: the difference cannot overflow.
    const int64_t ahead = seq - seq_;
    if (ahead <= params_.max_jump) {
      int64_t skipped = 0;
      for (int64_t s = seq_ + 1; s < seq; ++s) skipped += Received(s) ? 0 : 1;
      return {V::kNext, skipped};
    }
    if (params_.confirm_frames <= 1 || (ExtendsHeld(seq) && held_count_ + 1 >= params_.confirm_frames))
      return {V::kJumpAdopted, 0};
    return {V::kJumpHeld, 0};
  }
  // Older than the window: whether it was received is no longer known; it is late either way.
  if (seq_ - seq >= window_half()) return {V::kLate, 0};
  if (Received(seq)) return {V::kDuplicate, 0};
  return {V::kLate, seq > floor_ ? -1 : 0};
}

void SourceSequence::Commit(const SequenceDecision& d, int64_t epoch, int64_t seq, int64_t utime) {
  using V = SequenceVerdict;
  switch (d.verdict) {
    case V::kFirst:
    case V::kRestart:
    case V::kJumpAdopted:
      StartRun(epoch, seq, utime);
      break;
    case V::kNext:
      // The numbers leaving the window behind free their slots for those entering it ahead.
      for (int64_t s = std::max<int64_t>(0, seq_ - window_half() + 1); s <= seq - window_half(); ++s)
        SetReceived(s, false);
      SetReceived(seq, true);
      seq_ = seq;
      utime_ = std::max(utime_, utime);
      // The old stream goes on: a held jump was not the source's.
      held_count_ = 0;
      break;
    case V::kJumpHeld:
      held_count_ = ExtendsHeld(seq) ? held_count_ + 1 : 1;
      held_seq_ = seq;
      break;
    case V::kLate:
      if (seq_ - seq < window_half()) SetReceived(seq, true);
      break;
    case V::kDuplicate:
    case V::kReplayed:
      break;
  }
}

void SourceSequence::NoteDropped(const SequenceDecision& d, int64_t seq) {
  if (d.verdict == SequenceVerdict::kNext) SetReceived(seq, true);
}

}  // namespace vd
