#pragma once
// Sparse colour features (VolumeDeform section 5.2, docs/NONRIGID.md "Sparse features"): SIFT
// keypoints with valid depth, lifted into the canonical pose and kept as global anchors; every
// frame is matched against earlier frames on the device (kernels/features.cl) and the surviving
// matches become the point-to-point constraints of E_sparse (eq. 3).
#include <cstdint>
#include <deque>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <vector>

#include "core/bundle.h"
#include "ocl/device_ops.h"
#include "shared/features.h"
#include "vd/common/frame.h"
#include "vd/common/status.h"

namespace vd {

class FlagParser;

struct FeatureParams {
  // E_sparse on (the server's --no-sift turns it off for comparisons).
  bool enabled = true;
  // Weight w_s of E_sparse relative to the dense term's w_d (paper eq. 1), per match and axis
  // (a match has ~1/300 of the pixels' count). Measured (docs/BENCHMARKS.md): cloth drift 6.4 /
  // 4.2 / 3.2 / 2.8 mm and tube drift 1.5 / - / 2.2 / 2.9 mm at 8 / 16 / 32 / 64: 32 balances both.
  float w_sparse = 32.f;
  // Detection (section 5.2): DoG scale space of `octaves` x `octave_layers`, at most
  // `max_keypoints` keypoints with valid depth per frame, up to `max_orientations` per location.
  int max_keypoints = 150;
  int octaves = 4;
  // Scale of the image the keypoints are detected and described on (1, 1/2 or 1/4 of the colour
  // image); the keypoints are mapped back to full-resolution pixels. Measured (docs/BENCHMARKS.md
  // "Real time", 60 frames, 4 mm, same machine state): detection 29 / 31 / 41 ms at 1/2 against
  // 57 / 72 / 194 ms at 1 on cloth / tube / rigid, with drift 2.73 / 1.67 / 0.66 mm against
  // 3.17 / 2.22 / 0.58 mm: the finest octave costs three quarters of the time and buys nothing.
  float detect_scale = 0.5f;
  int octave_layers = 3;
  // DoG contrast threshold of Lowe's detector (OpenCV's default 0.04 is tuned for photographs;
  // sensor colour at 640x480 is softer).
  float contrast_threshold = 0.03f;
  int max_orientations = 2;
  // A keypoint is kept only when its 3x3 depth neighbourhood spans less than this (metres): a
  // keypoint on a depth edge has no reliable 3D position.
  float max_depth_spread = 0.02f;
  // Matching (section 5.2): at most `max_pair_matches` mutual matches per frame pair by descriptor
  // distance, of which the best `keep_per_pair` survive pruning.
  int max_pair_matches = 128;
  int keep_per_pair = 64;
  VdMatchPrune prune = {250.f, 0.8f, 60.f, 0.08f};
  // History policy (docs/NONRIGID.md): every frame's features are kept; each frame is matched
  // against the `recent_frames` latest frames and at most `max_keyframes` keyframes spread evenly
  // over the whole history, a keyframe every `keyframe_interval` frames (frame 0 always).
  int recent_frames = 4;
  int keyframe_interval = 5;
  int max_keyframes = 16;
  // Keyframes stored at most (bounds memory on long runs: ~26 KB each): beyond this, every second
  // stored keyframe after the first is dropped, so they stay spread over the whole history.
  // Frames that are neither keyframes nor among the recent ones can never be matched, and are
  // dropped as soon as they leave the recent window.
  int max_stored_keyframes = 256;
  // Huber threshold of a match's residual in the global pose estimate (metres): matches farther
  // off count linearly, so a wrong match cannot drag the pose.
  float pose_huber = 0.01f;
  // Lifting: the rendered surface at the keypoint within this of the observed depth (metres), and
  // Newton on S(g) = f to this residual (metres).
  float lift_max_depth_gap = 0.03f;
  float lift_tolerance = 1e-4f;
  int lift_iterations = 8;
  // The keyframe bundle adjustment of the history's canonical points (core/bundle.h).
  BundleParams bundle;
  Status Validate() const;
  // Registers a flag for every field; the fields' values now are the defaults --help shows.
  void Bind(FlagParser* flags);
};

// One frame's features. Keypoint i: pixel (u, v), its observed point in that frame's camera
// (metres), the 128 descriptor bytes at desc[128 i], and once lifted its canonical position in
// grid units (w = 1 when the lift succeeded).
struct FrameFeatures {
  int64_t seq = -1;
  // Index of the frame in the engine's history (0 = the first frame of the model).
  int64_t frame_index = -1;
  std::vector<float> u, v, size, angle;
  std::vector<vd_float4> camera_points;
  std::vector<uint8_t> desc;
  std::vector<vd_float4> canonical;
  // Milliseconds the detection and description took (on whichever thread ran it).
  double extract_ms = 0.0;
  size_t size_keypoints() const { return u.size(); }
};

// Detection and description on the host (OpenCV's SIFT, section 5.2's layout), keeping only
// keypoints with valid, locally smooth depth in [min_depth, max_depth].
StatusOr<FrameFeatures> ExtractFeatures(const RgbdFrame& frame, const FeatureParams& params, float min_depth,
                                        float max_depth);

// Runs ExtractFeatures off the calling thread: Prefetch(frame k + 1) while frame k is solved, then
// Take(frame k + 1) returns it (or extracts now when it was not prefetched).
class AsyncFeatureExtractor {
 public:
  AsyncFeatureExtractor() = default;
  ~AsyncFeatureExtractor();
  void Configure(const FeatureParams& params, float min_depth, float max_depth);
  void Prefetch(const RgbdFrame& frame);
  StatusOr<FrameFeatures> Take(const RgbdFrame& frame);
  // Drops pending work (reset).
  void Clear();

 private:
  FeatureParams params_;
  float min_depth_ = 0.f, max_depth_ = 0.f;
  std::mutex mu_;
  std::map<int64_t, std::shared_future<StatusOr<FrameFeatures>>> pending_;
  // Requests dropped while their detection still runs: destroying the last future of std::async
  // waits for it, which would stall the receive thread that called Prefetch. Kept until ready.
  std::vector<std::shared_future<StatusOr<FrameFeatures>>> retired_;
};

struct SparseMatch;

// Two stored features that matched (the same material point): feature `feature_a` of the frame
// with frame_index `frame_a` and `feature_b` of `frame_b` (indices into the stored, lifted features).
// No padding: checkpoints store it as bytes.
struct FeatureLink {
  int64_t frame_a = -1;
  int64_t frame_b = -1;
  int32_t feature_a = -1;
  int32_t feature_b = -1;
};
static_assert(sizeof(FeatureLink) == 24, "FeatureLink is written to checkpoints as bytes");

// Every frame's lifted features, the matches between them, and the candidate choice of the history
// policy.
class FeatureHistory {
 public:
  void Clear() {
    frames_.clear();
    keyframes_.clear();
    links_.clear();
  }
  // Keeps the frame's lifted features (the others cannot anchor anything), and as links the
  // `matches` (of this frame's keypoints, against the history as it is now) whose keypoint lifted.
  void Add(FrameFeatures f, int keyframe_interval, const std::vector<SparseMatch>& matches = {});
  // History positions to match frame `next_index` against (FeatureParams's policy).
  std::vector<int> Candidates(const FeatureParams& params) const;
  // Drops what the policy can never match again (see FeatureParams::max_stored_keyframes), and the
  // links to it.
  void Compact(const FeatureParams& params);
  // The keyframe bundle adjustment (core/bundle.h): the canonical points of the newest
  // params.keyframes keyframes (the first frame's never) are corrected so that linked features agree.
  Status Adjust(const BundleParams& params, BundleStats* stats);
  // The stored frames, the positions of the keyframes among them, the links (checkpoints).
  const std::vector<FrameFeatures>& frames() const { return frames_; }
  const std::vector<int>& keyframes() const { return keyframes_; }
  const std::vector<FeatureLink>& links() const { return links_; }
  // Replaces the contents (resume from a checkpoint; validated by the caller).
  void Restore(std::vector<FrameFeatures> frames, std::vector<int> keyframes, std::vector<FeatureLink> links) {
    frames_ = std::move(frames);
    keyframes_ = std::move(keyframes);
    links_ = std::move(links);
  }
  size_t num_frames() const { return frames_.size(); }
  const FrameFeatures& frame(int i) const { return frames_[i]; }
  size_t num_features() const;

 private:
  std::vector<FrameFeatures> frames_;
  std::vector<int> keyframes_;
  std::vector<FeatureLink> links_;
};

// A surviving match: current keypoint `cur` observed at `target` (world) is the material point
// stored at `canonical` (grid units) by history frame `frame`.
struct SparseMatch {
  int cur = -1;
  int frame = -1;
  int feature = -1;
  float descriptor_distance = 0.f;
  vd_float4 canonical{};
  vd_float4 target{};
  // The keypoint's point in this frame's camera, and the earlier feature moved by the field as it
  // was before this frame's solve (world): the pair the global pose aligns.
  vd_float4 camera_point{};
  vd_float4 predicted{};
};

struct MatchStats {
  int candidate_frames = 0;
  int candidate_features = 0;
  int mutual = 0;
  int pruned_descriptor = 0, pruned_ratio = 0, pruned_screen = 0, pruned_world = 0, pruned_position = 0;
  int kept = 0;
};

// Device side: matching against the history and lifting into the canonical pose.
class FeatureMatcher {
 public:
  // params are validated by the caller (EngineParams::Validate at start-up).
  FeatureMatcher(ocl::Context* ctx, const FeatureParams& params) : ctx_(ctx), params_(params) {}

  // Matches `cur` (camera points of this frame, `cam_to_world` its pose) against the history
  // frames `candidates`; earlier features are moved by the current field for the screen and 3D
  // pruning (`field`: the dense grid's or the bricks'). Appends the survivors to `out`.
  Status Match(const FrameFeatures& cur, const FeatureHistory& history, const std::vector<int>& candidates,
               const DeviceField& field, const VdPose& cam_to_world, VdCamera cam, std::vector<SparseMatch>* out,
               MatchStats* stats);
  // Lifts `f`'s keypoints into the canonical pose (fills f->canonical). `raster` is the live mesh
  // rendered at this frame's pose; with `no_model` the grid has no surface yet.
  Status Lift(FrameFeatures* f, const DeviceRaster& raster, const DeviceMesh& mesh, const DeviceField& field,
              const VdPose& cam_to_world, const VdPose& world_to_cam, bool no_model);

 private:
  ocl::Context* ctx_;
  const FeatureParams params_;
  ocl::Buffer<uint8_t> cur_desc_, cand_desc_;
  ocl::Buffer<float> dist_;
  ocl::Buffer<int32_t> frames_;
  ocl::Buffer<VdMatchBest> rows_, cols_;
  ocl::Buffer<vd_float4> cand_canonical_, cand_predicted_;
  ocl::Buffer<vd_float4> lift_points_, lift_out_;
  ocl::Buffer<int32_t> lift_pixels_;
  // Host staging, reused.
  std::vector<uint8_t> cand_desc_host_, cand_desc_t_host_;
  std::vector<vd_float4> cand_canonical_host_, predicted_host_;
  std::vector<int32_t> frames_host_;
  std::vector<VdMatchBest> rows_host_, cols_host_;
};

// Re-expresses the matches' targets for the pose estimated after matching, dropping those now
// farther than prune.max_world_distance from their prediction.
void RetargetMatches(const VdPose& cam_to_world, const VdMatchPrune& prune, std::vector<SparseMatch>* matches);

// The point-to-point constraints of E_sparse: each match as three axis-aligned rows of the
// point-to-plane form the solver takes (|S(g) - f|^2 = sum over the axes e of (e . (S(g) - f))^2),
// weight w_s / w_d each.
void AppendSparseConstraints(const std::vector<SparseMatch>& matches, float weight, std::vector<VdCorrespondence>* out);

}  // namespace vd
