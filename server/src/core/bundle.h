#pragma once
// Keyframe non-rigid bundle adjustment of the sparse features (issue 14; docs/NONRIGID.md
// "Keyframe bundle adjustment"). A feature's canonical point is its observation pulled back through
// the field of its frame; a field that has drifted pulls it back to the wrong material point, and
// every later frame that matches it inherits the error. The adjustment re-solves, jointly over a
// window of history frames, a smooth correction field per frame in canonical space such that the
// features that matched each other (the same material point) agree, with the frames outside the
// window (the first frame always: it was lifted before anything could drift) held fixed. The
// corrected points are what later frames match against.
//
// Per free frame f, the correction d_f(x) is trilinear over a coarse canonical grid of spacing
// `cell_voxels` (its nodes D are the unknowns); the energy, linear in D, is
//   sum_links rho(|(p_a + d_f(p_a)) - (p_b + d_g(p_b))|^2)       (matched features agree; Huber)
//   + smoothness * sum_neighbour nodes |D_i - D_j|^2                 (the field bends smoothly)
//   + prior * sum_nodes |D_i|^2                                      (no evidence, no change)
// The three axes decouple, so one sparse Cholesky factorisation serves all three; the Huber weights
// are refreshed by iterated reweighting.
#include <cstdint>
#include <vector>

#include "shared/vd_types.h"
#include "vd/common/status.h"

namespace vd {

class FlagParser;

struct BundleParams {
  // The newest history keyframes whose points the adjustment moves (the first frame's never; older
  // keyframes and the recent frames stay as they are). It runs whenever a frame becomes a keyframe.
  // 0 turns it off. Measured on the bend (150 frames): drift 7.41 mm with 4, 7.64 with 16 (and 5x
  // the time), 8.36 off (with the recent frames free as well).
  int keyframes = 4;
  // Spacing of the correction grid, voxels: a frame's lifting error is smooth over several
  // centimetres (the long bend's drift varies over ~5 cm along the tube). Measured on the bend
  // (150 frames): drift 7.41 mm at 8 voxels, 7.46 at 16, with a quarter of the solve time at 16.
  float cell_voxels = 16.f;
  // Weights relative to one matched pair (per axis): smoothness between neighbouring nodes, and the
  // prior that keeps nodes without evidence where they are.
  float smoothness = 1.f;
  float prior = 0.05f;
  // Huber threshold of a pair's disagreement, voxels: wrong matches (a pair of different material
  // points) count linearly and cannot drag a frame's correction.
  float huber_voxels = 2.f;
  // Reweighting passes (each one factorisation): the second one down-weights the wrong matches.
  int iterations = 2;
  Status Validate() const;
  void Bind(FlagParser* flags);
};

// Two features that matched: feature `feature_a` of frame `frame_a` and `feature_b` of `frame_b`
// (indices into the problem's frames).
struct BundleLink {
  int frame_a = -1, feature_a = -1;
  int frame_b = -1, feature_b = -1;
};

struct BundleStats {
  int free_frames = 0;
  int nodes = 0;
  int links = 0;
  // Links beyond the Huber threshold at the end.
  int outliers = 0;
  // Root mean square disagreement of the links, grid units, before and after.
  double rms_before = 0.0, rms_after = 0.0;
};

// Whether p is a point the adjustment takes: lifted (w > 0) and finite.
bool IsBundlePoint(const vd_float4& p);

// Solves the adjustment in place: `points[f]` are frame f's canonical points (grid units, w > 0 for
// a valid point); those of frames with `free[f]` are corrected. Links naming a frame or feature out
// of range or an invalid point are an InvalidArgument.
Status SolveBundle(const BundleParams& params, const std::vector<char>& free, const std::vector<BundleLink>& links,
                   std::vector<std::vector<vd_float4>>* points, BundleStats* stats);

}  // namespace vd
