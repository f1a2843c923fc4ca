#pragma once
// Whether a source's colour is registered to its depth (lies on the same pixel grid), measured
// from the frames themselves. The dense colour term (SolverParams::w_photo) reads the model's
// colour as a property of the surface: colour that is misplaced on the geometry (a second,
// uncalibrated sensor, as 7-Scenes' Kinect v1 recordings) makes it pull the field along the
// surface by the misplacement. On 7-Scenes the term took the room's ATE 26.3 -> 31.6 mm
// (docs/BENCHMARKS.md "Session 28").
//
// The measure: where the depth jumps (or ends), a registered image has an intensity edge at the
// same pixel. Across every depth edge, the intensity step is summed at each offset k = -kReach..
// kReach along the image axis the edge crosses (k > 0 towards the far side). A registered source
// peaks within kPeakReach pixels of the edge; an unregistered one is flat there, its colour edges
// spread over every offset. The verdict is the peak against the larger of the two sides' medians
// (8..kReach pixels out, each side its own texture), per image axis: colour moved along x leaves
// horizontal edges aligned (a horizontal tube moved 10 px along x: 1.56 over both axes together,
// 0.9 across its vertical edges), so the axis that sees it decides. Measured per axis, one or two
// frames at a time (docs/BENCHMARKS.md "Session 29"): the synthetic scenes 1.61-2.61 over their
// 60 frames, KillingFusion's Snoopy (Kinect v1, registered) 1.68, 7-Scenes redkitchen 0.67-1.24
// over 100 of its frames.
#include <array>
#include <cstdint>

#include "vd/common/frame.h"

namespace vd {

struct ColourRegistrationParams {
  // The peak at the depth edges over the sides' level at which colour counts as registered: the
  // geometric middle of the lowest registered source measured (Snoopy, 1.68) and the highest
  // unregistered frame (1.24).
  double min_peak_ratio = 1.45;
  // Edge crossings the verdict waits for: one frame of an object-scale scene holds 1100-3700,
  // a room 6000-11000. Fewer make a single frame's texture decide.
  int64_t min_samples = 2000;
  // Frames after which a source that never gave min_samples (no depth edges: a flat wall, or no
  // colour) counts as unregistered: the term cannot be shown safe there.
  int max_frames = 30;
  // A depth step counts as an edge beyond this fraction of the nearer depth (Kinect-class noise is
  // ~0.3 % at 1 m; a 3 % step is a different surface).
  float edge_jump = 0.03f;
};

class ColourRegistration {
 public:
  // The values are stored in checkpoints (EngineState::colour_registration).
  enum class Verdict : uint8_t { kUndecided = 0, kRegistered = 1, kUnregistered = 2 };
  // Offsets either side of an edge that the profile covers, and the peak's reach within it.
  static constexpr int kReach = 16;
  static constexpr int kPeakReach = 4;
  // Depth outside [min_depth, max_depth] metres is no surface (as the engine's preprocessing).
  ColourRegistration(const ColourRegistrationParams& params, float min_depth, float max_depth)
      : params_(params), min_depth_(min_depth), max_depth_(max_depth) {}

  // Adds one frame's edges while undecided and decides once min_samples are in (or max_frames
  // passed); returns the verdict. Frames without colour add no samples but count.
  Verdict Add(const RgbdFrame& frame);
  Verdict verdict() const { return verdict_; }
  // The peak over the sides' level so far: the lower of the two axes' where each has at least a
  // quarter of min_samples crossings (else both together; 0 before any sample).
  double ratio() const;
  // The crossings so far (both axes), and those of edges crossed along x (0) or y (1).
  int64_t samples() const { return samples_[0] + samples_[1]; }
  int64_t samples(int axis) const { return samples_[axis]; }
  int frames() const { return frames_; }
  const ColourRegistrationParams& params() const { return params_; }
  // Sum of the intensity step (0..1 luma) at offset k (index k + kReach) over every crossing along
  // `axis`.
  using Profile = std::array<double, 2 * kReach + 1>;
  const Profile& profile(int axis) const { return profile_[axis]; }
  void Clear();
  // Starts over with `v` already decided (a model restored from a checkpoint).
  void Restore(Verdict v) {
    Clear();
    verdict_ = v;
  }

 private:
  static double Ratio(const Profile& p);
  ColourRegistrationParams params_;
  float min_depth_, max_depth_;
  std::array<Profile, 2> profile_{};
  std::array<int64_t, 2> samples_{};
  int frames_ = 0;
  Verdict verdict_ = Verdict::kUndecided;
};

const char* VerdictName(ColourRegistration::Verdict v);

}  // namespace vd
