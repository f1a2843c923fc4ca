#include "core/features.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <set>
#include <sstream>
#include <tuple>

#include "ocl/features_ocl.h"
#include "vd/common/flags.h"
#include "vd/common/thread_name.h"

namespace vd {
namespace {

// SIFT octave of a keypoint as OpenCV packs it (low byte, signed; -1 = the upsampled octave).
int KeypointOctave(const cv::KeyPoint& kp) {
  int o = kp.octave & 255;
  return o < 128 ? o : o - 256;
}

VdPose Inverse(const VdPose& T) {
  // R^T and -R^T t.
  const float r[3][3] = {{T.r0.x, T.r0.y, T.r0.z}, {T.r1.x, T.r1.y, T.r1.z}, {T.r2.x, T.r2.y, T.r2.z}};
  const float t[3] = {T.r0.w, T.r1.w, T.r2.w};
  VdPose o;
  float rows[3][4];
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) rows[i][j] = r[j][i];
    rows[i][3] = -(r[0][i] * t[0] + r[1][i] * t[1] + r[2][i] * t[2]);
  }
  o.r0 = VD_F4(rows[0][0], rows[0][1], rows[0][2], rows[0][3]);
  o.r1 = VD_F4(rows[1][0], rows[1][1], rows[1][2], rows[1][3]);
  o.r2 = VD_F4(rows[2][0], rows[2][1], rows[2][2], rows[2][3]);
  return o;
}

}  // namespace

Status FeatureParams::Validate() const {
  if (!(w_sparse >= 0.f && w_sparse <= 1e4f)) return ParamOutOfBounds("FeatureParams", "w_sparse", w_sparse, "0 <= w_s <= 1e4");
  if (!(max_keypoints >= 1 && max_keypoints <= 4096)) return ParamOutOfBounds("FeatureParams", "max_keypoints", max_keypoints, "1..4096");
  if (!(octaves >= 1 && octaves <= 8)) return ParamOutOfBounds("FeatureParams", "octaves", octaves, "1..8");
  if (!(detect_scale == 1.f || detect_scale == 0.5f || detect_scale == 0.25f))
    return ParamOutOfBounds("FeatureParams", "detect_scale", detect_scale, "one of 1, 0.5, 0.25");
  if (!(octave_layers >= 1 && octave_layers <= 8)) return ParamOutOfBounds("FeatureParams", "octave_layers", octave_layers, "1..8");
  if (!(contrast_threshold > 0.f && contrast_threshold < 1.f))
    return ParamOutOfBounds("FeatureParams", "contrast_threshold", contrast_threshold, "0 < c < 1");
  if (!(max_orientations >= 1 && max_orientations <= 4)) return ParamOutOfBounds("FeatureParams", "max_orientations", max_orientations, "1..4");
  if (!(max_depth_spread > 0.f)) return ParamOutOfBounds("FeatureParams", "max_depth_spread", max_depth_spread, "> 0");
  if (!(max_pair_matches >= 1 && max_pair_matches <= 4096)) return ParamOutOfBounds("FeatureParams", "max_pair_matches", max_pair_matches, "1..4096");
  if (!(keep_per_pair >= 1 && keep_per_pair <= max_pair_matches))
    return ParamOutOfBounds("FeatureParams", "keep_per_pair", keep_per_pair, "1 <= keep_per_pair <= max_pair_matches");
  if (!(prune.max_descriptor_distance > 0.f)) return ParamOutOfBounds("FeatureParams", "prune.max_descriptor_distance", prune.max_descriptor_distance, "> 0");
  if (!(prune.max_ratio > 0.f && prune.max_ratio <= 1.f)) return ParamOutOfBounds("FeatureParams", "prune.max_ratio", prune.max_ratio, "0 < r <= 1");
  if (!(prune.max_screen_distance > 0.f)) return ParamOutOfBounds("FeatureParams", "prune.max_screen_distance", prune.max_screen_distance, "> 0");
  if (!(prune.max_world_distance > 0.f)) return ParamOutOfBounds("FeatureParams", "prune.max_world_distance", prune.max_world_distance, "> 0");
  if (!(recent_frames >= 0 && recent_frames <= 64)) return ParamOutOfBounds("FeatureParams", "recent_frames", recent_frames, "0..64");
  if (!(keyframe_interval >= 1)) return ParamOutOfBounds("FeatureParams", "keyframe_interval", keyframe_interval, ">= 1");
  if (!(max_keyframes >= 0 && max_keyframes <= 1024)) return ParamOutOfBounds("FeatureParams", "max_keyframes", max_keyframes, "0..1024");
  if (!(max_stored_keyframes >= std::max(2, max_keyframes) && max_stored_keyframes <= 100000))
    return ParamOutOfBounds("FeatureParams", "max_stored_keyframes", max_stored_keyframes, "max(2, max_keyframes)..100000");
  if (!(pose_huber > 0.f)) return ParamOutOfBounds("FeatureParams", "pose_huber", pose_huber, "> 0");
  if (!(lift_max_depth_gap > 0.f)) return ParamOutOfBounds("FeatureParams", "lift_max_depth_gap", lift_max_depth_gap, "> 0");
  if (!(lift_tolerance > 0.f)) return ParamOutOfBounds("FeatureParams", "lift_tolerance", lift_tolerance, "> 0");
  if (!(lift_iterations >= 1 && lift_iterations <= 50)) return ParamOutOfBounds("FeatureParams", "lift_iterations", lift_iterations, "1..50");
  return bundle.Validate();
}

void FeatureParams::Bind(FlagParser* f) {
  f->Section("Sparse colour features (E_sparse, section 5.2)");
  f->AddNegation("no-sift", &enabled,
                 "Turn the sparse colour term off: no SIFT features, depth-only non-rigid tracking (for comparisons)");
  f->Add("w-sparse", &w_sparse, "Weight of the sparse SIFT term E_sparse per match, relative to the dense term");
  f->Add("sift-max-keypoints", &max_keypoints, "SIFT keypoints with valid depth kept per frame (the strongest)");
  f->Add("sift-octaves", &octaves, "Octaves of the DoG scale space (from the upsampled one)");
  f->Add("sift-detect-scale", &detect_scale,
         "Detect on the colour image scaled by this (1, 0.5 or 0.25): 0.5 costs about a quarter and drops the "
         "finest octave");
  f->Add("sift-octave-layers", &octave_layers, "DoG layers per octave");
  f->Add("sift-contrast-threshold", &contrast_threshold, "DoG contrast threshold of the detector");
  f->Add("sift-max-orientations", &max_orientations, "Orientations kept per keypoint location and scale");
  f->Add("sift-max-depth-spread", &max_depth_spread,
         "A keypoint is dropped when its 3x3 depth neighbourhood spans more than this, metres");
  f->Add("match-max-pair", &max_pair_matches, "Mutual matches considered per frame pair, by descriptor distance");
  f->Add("match-keep-per-pair", &keep_per_pair, "Matches kept per frame pair after pruning");
  f->Add("match-max-descriptor-distance", &prune.max_descriptor_distance, "Matches beyond this SIFT distance are pruned");
  f->Add("match-max-ratio", &prune.max_ratio, "Lowe ratio: best / second-best distance above this is pruned");
  f->Add("match-max-screen-distance", &prune.max_screen_distance,
         "Matches whose predicted pixel is farther than this from the keypoint are pruned, pixels");
  f->Add("match-max-world-distance", &prune.max_world_distance,
         "Matches whose predicted point is farther than this from the observed one are pruned, metres");
  f->Add("history-recent-frames", &recent_frames, "Each frame is matched against this many latest frames ...");
  f->Add("history-max-keyframes", &max_keyframes, "... and at most this many keyframes spread over the whole history");
  f->Add("history-keyframe-interval", &keyframe_interval, "A keyframe every this many frames (frame 0 always)");
  f->Add("history-max-stored-keyframes", &max_stored_keyframes,
         "Keyframes stored at most (bounds memory on long runs); beyond it every second one is dropped");
  f->Add("sparse-pose-huber", &pose_huber, "Huber threshold of a match's residual in the global pose, metres");
  f->Add("lift-max-depth-gap", &lift_max_depth_gap,
         "A keypoint is lifted only where the rendered surface is within this of its depth, metres");
  f->Add("lift-tolerance", &lift_tolerance, "Newton on S(g) = f stops at this residual, metres");
  f->Add("lift-iterations", &lift_iterations, "Newton iterations of the lift at most");
  bundle.Bind(f);
}

StatusOr<FrameFeatures> ExtractFeatures(const RgbdFrame& frame, const FeatureParams& params, float min_depth,
                                        float max_depth) {
  const auto t0 = std::chrono::steady_clock::now();
  FrameFeatures out;
  out.seq = frame.seq;
  if (frame.color.empty() || frame.depth.empty()) return out;
  if (frame.color.size() != frame.depth.size())
    return InvalidArgument("colour and depth differ in size; features need registered colour");
  cv::Mat gray;
  cv::cvtColor(frame.color, gray, cv::COLOR_BGR2GRAY);
  const Intrinsics& k = frame.intrinsics;
  const float inv_scale = 1.f / frame.depth_scale;
  const cv::Mat& depth = frame.depth;
  auto depth_at = [&](int x, int y) {
    const uint16_t d = depth.at<uint16_t>(y, x);
    const float m = d * inv_scale;
    return (d == 0 || m < min_depth || m > max_depth) ? 0.f : m;
  };
  cv::Mat mask(depth.size(), CV_8U);
  int x0 = depth.cols, y0 = depth.rows, x1 = -1, y1 = -1;
  for (int y = 0; y < depth.rows; ++y)
    for (int x = 0; x < depth.cols; ++x) {
      const bool valid = depth_at(x, y) > 0.f;
      mask.at<uint8_t>(y, x) = valid ? 255 : 0;
      if (valid) {
        x0 = std::min(x0, x);
        x1 = std::max(x1, x);
        y0 = std::min(y0, y);
        y1 = std::max(y1, y);
      }
    }
  if (x1 < 0) return out;
  // The scale space is built over the bounding box of the valid depth only (keypoints elsewhere
  // are discarded anyway), with a margin for the descriptor windows near its edge.
  const int margin = 24;
  const cv::Rect roi(cv::Point(std::max(0, x0 - margin), std::max(0, y0 - margin)),
                     cv::Point(std::min(depth.cols, x1 + 1 + margin), std::min(depth.rows, y1 + 1 + margin)));
  // Detection runs on the box scaled by detect_scale: at 1/2 OpenCV's upsampled first octave is
  // the full image's own resolution, the scale space costs about a quarter, and the keypoints of
  // the finest octave (the smallest blobs) are the ones given up.
  const float scale = params.detect_scale;
  cv::Mat gray_det = gray(roi), mask_det = mask(roi);
  if (scale != 1.f) {
    cv::resize(gray(roi), gray_det, cv::Size(), scale, scale, cv::INTER_AREA);
    cv::resize(mask(roi), mask_det, gray_det.size(), 0, 0, cv::INTER_NEAREST);
  }
  // Octaves of the detection image that are octaves -1 .. octaves - 2 of the full one.
  const int octave_shift = int(std::lround(std::log2(1.0 / scale)));
  // Detection-image pixel centres to full-image pixel coordinates.
  auto to_full = [&](const cv::Point2f& p) {
    return cv::Point2f((p.x + 0.5f) / scale - 0.5f + float(roi.x), (p.y + 0.5f) / scale - 0.5f + float(roi.y));
  };

  auto sift = cv::SIFT::create(0, params.octave_layers, params.contrast_threshold, 10.0, 1.6);
  std::vector<cv::KeyPoint> detected;
  sift->detect(gray_det, detected, mask_det);
  // Strongest first, so the caps below keep the best.
  std::stable_sort(detected.begin(), detected.end(),
                   [](const cv::KeyPoint& a, const cv::KeyPoint& b) { return a.response > b.response; });
  // Kept keypoints in the detection image (for the descriptors) and in the full one.
  std::vector<cv::KeyPoint> kept_det, kept;
  std::map<std::tuple<int, int, int>, int> orientations;
  for (const cv::KeyPoint& kd : detected) {
    if (int(kept.size()) >= params.max_keypoints) break;
    // Octaves -1 (OpenCV's upsampled first octave) .. octaves - 2 of the full image.
    if (KeypointOctave(kd) + octave_shift > params.octaves - 2) continue;
    cv::KeyPoint kp = kd;
    kp.pt = to_full(kd.pt);
    kp.size = kd.size / scale;
    const int x = int(std::lround(kp.pt.x)), y = int(std::lround(kp.pt.y));
    if (x < 1 || y < 1 || x >= depth.cols - 1 || y >= depth.rows - 1) continue;
    float lo = 1e9f, hi = 0.f;
    bool valid = true;
    for (int dy = -1; dy <= 1 && valid; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const float d = depth_at(x + dx, y + dy);
        if (d <= 0.f) {
          valid = false;
          break;
        }
        lo = std::min(lo, d);
        hi = std::max(hi, d);
      }
    if (!valid || hi - lo > params.max_depth_spread) continue;
    // One location (and scale) with several dominant orientations appears once per orientation.
    auto key = std::make_tuple(int(std::lround(kp.pt.x * 8)), int(std::lround(kp.pt.y * 8)), int(std::lround(kp.size * 8)));
    if (++orientations[key] > params.max_orientations) continue;
    kept_det.push_back(kd);
    kept.push_back(kp);
  }
  if (kept.empty()) return out;
  cv::Mat desc;
  sift->compute(gray_det, kept_det, desc);
  const int n = int(kept.size());
  if (desc.rows != n || desc.cols != VD_DESC_BYTES) return Internal("SIFT descriptors do not match the keypoints");
  out.u.resize(n);
  out.v.resize(n);
  out.size.resize(n);
  out.angle.resize(n);
  out.camera_points.resize(n);
  out.desc.resize(size_t(n) * VD_DESC_BYTES);
  for (int i = 0; i < n; ++i) {
    const cv::KeyPoint& kp = kept[i];
    const float z = depth_at(int(std::lround(kp.pt.x)), int(std::lround(kp.pt.y)));
    out.u[i] = kp.pt.x;
    out.v[i] = kp.pt.y;
    out.size[i] = kp.size;
    out.angle[i] = kp.angle;
    out.camera_points[i] = VD_F4((kp.pt.x - float(k.cx)) * z / float(k.fx), (kp.pt.y - float(k.cy)) * z / float(k.fy), z,
                                 z > 0.f ? 1.f : 0.f);
    const float* row = desc.ptr<float>(i);
    for (int j = 0; j < VD_DESC_BYTES; ++j)
      out.desc[size_t(i) * VD_DESC_BYTES + j] = uint8_t(std::clamp(std::lround(row[j]), 0L, 255L));
  }
  out.extract_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

AsyncFeatureExtractor::~AsyncFeatureExtractor() { Clear(); }

void AsyncFeatureExtractor::Configure(const FeatureParams& params, float min_depth, float max_depth) {
  std::lock_guard<std::mutex> lock(mu_);
  params_ = params;
  min_depth_ = min_depth;
  max_depth_ = max_depth;
}

void AsyncFeatureExtractor::Prefetch(const RgbdFrame& frame) {
  std::lock_guard<std::mutex> lock(mu_);
  if (pending_.count(frame.seq)) return;
  // At most a few frames ahead; older requests nobody took are dropped. Their threads finish on
  // their own: a finished one is released here, a running one is kept aside until it is.
  retired_.erase(std::remove_if(retired_.begin(), retired_.end(),
                                [](const auto& f) { return f.wait_for(std::chrono::seconds(0)) == std::future_status::ready; }),
                 retired_.end());
  while (pending_.size() >= 4) {
    retired_.push_back(std::move(pending_.begin()->second));
    pending_.erase(pending_.begin());
  }
  RgbdFrame copy = frame;
  copy.color = frame.color.clone();
  copy.depth = frame.depth.clone();
  const FeatureParams p = params_;
  const float lo = min_depth_, hi = max_depth_;
  pending_[frame.seq] = std::async(std::launch::async, [copy = std::move(copy), p, lo, hi]() {
                          NameThisThread("vd-sift");
                          return ExtractFeatures(copy, p, lo, hi);
                        }).share();
}

StatusOr<FrameFeatures> AsyncFeatureExtractor::Take(const RgbdFrame& frame) {
  std::shared_future<StatusOr<FrameFeatures>> fut;
  {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = pending_.find(frame.seq);
    if (it != pending_.end()) {
      fut = it->second;
      pending_.erase(it);
    }
  }
  if (fut.valid()) return fut.get();
  return ExtractFeatures(frame, params_, min_depth_, max_depth_);
}

void AsyncFeatureExtractor::Clear() {
  std::map<int64_t, std::shared_future<StatusOr<FrameFeatures>>> drop;
  std::vector<std::shared_future<StatusOr<FrameFeatures>>> retired;
  {
    std::lock_guard<std::mutex> lock(mu_);
    drop.swap(pending_);
    retired.swap(retired_);
  }
  for (auto& [seq, fut] : drop) fut.wait();
  for (auto& fut : retired) fut.wait();
}

void FeatureHistory::Add(FrameFeatures f, int keyframe_interval, const std::vector<SparseMatch>& matches) {
  // Only lifted features can anchor anything.
  FrameFeatures k;
  k.seq = f.seq;
  k.frame_index = f.frame_index;
  k.extract_ms = f.extract_ms;
  std::vector<int32_t> stored(f.size_keypoints(), -1);
  for (size_t i = 0; i < f.size_keypoints(); ++i) {
    if (i >= f.canonical.size() || !(f.canonical[i].w > 0.f)) continue;
    stored[i] = int32_t(k.u.size());
    k.u.push_back(f.u[i]);
    k.v.push_back(f.v[i]);
    k.size.push_back(f.size[i]);
    k.angle.push_back(f.angle[i]);
    k.camera_points.push_back(f.camera_points[i]);
    k.canonical.push_back(f.canonical[i]);
    k.desc.insert(k.desc.end(), f.desc.begin() + i * VD_DESC_BYTES, f.desc.begin() + (i + 1) * VD_DESC_BYTES);
  }
  if (k.size_keypoints() == 0) return;
  for (const SparseMatch& m : matches) {
    if (m.cur < 0 || size_t(m.cur) >= stored.size() || stored[m.cur] < 0) continue;
    if (m.frame < 0 || size_t(m.frame) >= frames_.size()) continue;
    const FrameFeatures& old = frames_[m.frame];
    if (m.feature < 0 || size_t(m.feature) >= old.size_keypoints()) continue;
    links_.push_back({k.frame_index, old.frame_index, stored[m.cur], int32_t(m.feature)});
  }
  const int pos = int(frames_.size());
  if (keyframes_.empty() || k.frame_index - frames_[keyframes_.back()].frame_index >= keyframe_interval)
    keyframes_.push_back(pos);
  frames_.push_back(std::move(k));
}

std::vector<int> FeatureHistory::Candidates(const FeatureParams& params) const {
  std::vector<int> out;
  const int n = int(frames_.size());
  const int recent_begin = std::max(0, n - params.recent_frames);
  // Keyframes before the recent window, thinned to max_keyframes spread evenly over the history
  // (the first one always: it was lifted before any deformation could drift).
  std::vector<int> older;
  for (int kf : keyframes_)
    if (kf < recent_begin) older.push_back(kf);
  const int m = int(older.size());
  if (m <= params.max_keyframes) {
    out = older;
  } else if (params.max_keyframes == 1) {
    out.push_back(older.front());
  } else if (params.max_keyframes > 1) {
    for (int i = 0; i < params.max_keyframes; ++i) {
      const int j = int(std::lround(double(i) * (m - 1) / (params.max_keyframes - 1)));
      if (out.empty() || out.back() != older[j]) out.push_back(older[j]);
    }
  }
  for (int i = recent_begin; i < n; ++i) out.push_back(i);
  return out;
}

void FeatureHistory::Compact(const FeatureParams& params) {
  const int n = int(frames_.size());
  const int recent_begin = std::max(0, n - params.recent_frames);
  std::vector<int> keep_kf = keyframes_;
  if (int(keep_kf.size()) > params.max_stored_keyframes) {
    // Every second keyframe after the first goes; the last one stays (it sets the interval).
    std::vector<int> thinned;
    for (size_t i = 0; i < keep_kf.size(); ++i)
      if (i == 0 || i % 2 == 0 || i + 1 == keep_kf.size()) thinned.push_back(keep_kf[i]);
    keep_kf.swap(thinned);
  }
  std::vector<char> keep(n, 0);
  for (int k : keep_kf) keep[k] = 1;
  for (int i = recent_begin; i < n; ++i) keep[i] = 1;
  if (std::count(keep.begin(), keep.end(), 1) == n) return;
  std::vector<int> new_index(n, -1);
  std::vector<FrameFeatures> frames;
  for (int i = 0; i < n; ++i) {
    if (!keep[i]) continue;
    new_index[i] = int(frames.size());
    frames.push_back(std::move(frames_[i]));
  }
  keyframes_.clear();
  for (int k : keep_kf) keyframes_.push_back(new_index[k]);
  frames_.swap(frames);
  std::set<int64_t> kept_frames;
  for (const FrameFeatures& f : frames_) kept_frames.insert(f.frame_index);
  links_.erase(std::remove_if(links_.begin(), links_.end(),
                              [&](const FeatureLink& l) {
                                return !kept_frames.count(l.frame_a) || !kept_frames.count(l.frame_b);
                              }),
               links_.end());
}

Status FeatureHistory::Adjust(const BundleParams& params, BundleStats* stats) {
  *stats = BundleStats();
  const int n = int(frames_.size());
  if (params.keyframes <= 0 || n < 2) return Status::Ok();
  // Free: the newest params.keyframes keyframes, never the first. The recent frames between them
  // stay as lifted: they leave the history within a few frames, and correcting them too raised the
  // tube's drift by 10 % (docs/BENCHMARKS.md "Long takes").
  std::vector<char> free(n, 0);
  const int num_kf = int(keyframes_.size());
  for (int k = std::max(1, num_kf - params.keyframes); k < num_kf; ++k) free[keyframes_[k]] = 1;
  std::map<int64_t, int> position;
  std::vector<std::vector<vd_float4>> points(n);
  for (int i = 0; i < n; ++i) {
    position[frames_[i].frame_index] = i;
    if (free[i]) points[i] = frames_[i].canonical;
  }
  std::vector<BundleLink> links;
  for (const FeatureLink& l : links_) {
    auto a = position.find(l.frame_a), b = position.find(l.frame_b);
    if (a == position.end() || b == position.end()) continue;
    if (!free[a->second] && !free[b->second]) continue;
    // A link to a feature that is not there or not a finite lifted point (a damaged history) is
    // left out rather than failing the frame.
    auto usable = [&](int f, int32_t i) {
      return i >= 0 && size_t(i) < frames_[f].canonical.size() && IsBundlePoint(frames_[f].canonical[i]);
    };
    if (!usable(a->second, l.feature_a) || !usable(b->second, l.feature_b)) continue;
    // The fixed side's point as it is.
    for (int f : {a->second, b->second})
      if (points[f].empty()) points[f] = frames_[f].canonical;
    links.push_back({a->second, l.feature_a, b->second, l.feature_b});
  }
  VD_RETURN_IF_ERROR(SolveBundle(params, free, links, &points, stats));
  for (int i = 0; i < n; ++i)
    if (free[i]) frames_[i].canonical = std::move(points[i]);
  return Status::Ok();
}

size_t FeatureHistory::num_features() const {
  size_t s = 0;
  for (const auto& f : frames_) s += f.size_keypoints();
  return s;
}

Status FeatureMatcher::Match(const FrameFeatures& cur, const FeatureHistory& history,
                             const std::vector<int>& candidates, const DeviceField& field, const VdPose& cam_to_world,
                             VdCamera cam, std::vector<SparseMatch>* out, MatchStats* stats) {
  const FeatureParams& params = params_;
  *stats = MatchStats();
  const int n_cur = int(cur.size_keypoints());
  if (n_cur == 0 || candidates.empty()) return Status::Ok();
  if (!field.valid()) return FailedPrecondition("feature matching needs the deformation field");
  cand_desc_host_.clear();
  cand_canonical_host_.clear();
  frames_host_.clear();
  for (int f : candidates) {
    const FrameFeatures& h = history.frame(f);
    frames_host_.push_back(int32_t(cand_canonical_host_.size()));
    cand_desc_host_.insert(cand_desc_host_.end(), h.desc.begin(), h.desc.end());
    cand_canonical_host_.insert(cand_canonical_host_.end(), h.canonical.begin(), h.canonical.end());
    frames_host_.push_back(int32_t(cand_canonical_host_.size()));
  }
  const int n_cand = int(cand_canonical_host_.size());
  const int num_frames = int(candidates.size());
  cand_desc_t_host_.resize(cand_desc_host_.size());
  vd_desc_transpose(cand_desc_host_.data(), n_cand, cand_desc_t_host_.data());
  stats->candidate_frames = num_frames;
  stats->candidate_features = n_cand;
  if (n_cand == 0) return Status::Ok();
  VD_RETURN_IF_ERROR(ctx_->Reserve(&cur_desc_, cur.desc.size()));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&cand_desc_, cand_desc_host_.size()));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&cand_canonical_, size_t(n_cand)));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&cand_predicted_, size_t(n_cand)));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&dist_, size_t(n_cur) * n_cand));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&frames_, frames_host_.size()));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&rows_, size_t(n_cur) * num_frames));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&cols_, size_t(n_cand)));
  VD_RETURN_IF_ERROR(ctx_->Upload(cur_desc_, cur.desc.data(), cur.desc.size()));
  VD_RETURN_IF_ERROR(ctx_->Upload(cand_desc_, cand_desc_t_host_.data(), cand_desc_t_host_.size()));
  VD_RETURN_IF_ERROR(ctx_->Upload(cand_canonical_, cand_canonical_host_.data(), size_t(n_cand)));
  VD_RETURN_IF_ERROR(ctx_->Upload(frames_, frames_host_.data(), frames_host_.size()));
  VD_RETURN_IF_ERROR(ocl::PredictFeatures(*ctx_, size_t(n_cand), cand_canonical_, field, cand_predicted_));
  VD_RETURN_IF_ERROR(
      ocl::MatchBest(*ctx_, cur_desc_, n_cur, cand_desc_, n_cand, frames_, num_frames, dist_, rows_, cols_));
  rows_host_.resize(size_t(n_cur) * num_frames);
  cols_host_.resize(size_t(n_cand));
  predicted_host_.resize(size_t(n_cand));
  VD_RETURN_IF_ERROR(ctx_->Download(rows_, rows_host_.data(), rows_host_.size()));
  VD_RETURN_IF_ERROR(ctx_->Download(cols_, cols_host_.data(), cols_host_.size()));
  VD_RETURN_IF_ERROR(ctx_->Download(cand_predicted_, predicted_host_.data(), predicted_host_.size()));

  const VdPose world_to_cam = Inverse(cam_to_world);
  struct Pair {
    int a, b;
    float d2;
  };
  std::vector<Pair> pairs;
  for (int f = 0; f < num_frames; ++f) {
    pairs.clear();
    for (int a = 0; a < n_cur; ++a) {
      const VdMatchBest& r = rows_host_[size_t(f) * n_cur + a];
      if (r.best < 0 || cols_host_[r.best].best != a) continue;
      pairs.push_back({a, r.best, r.best_d2});
    }
    stats->mutual += int(pairs.size());
    std::stable_sort(pairs.begin(), pairs.end(), [](const Pair& x, const Pair& y) { return x.d2 < y.d2; });
    if (int(pairs.size()) > params.max_pair_matches) pairs.resize(params.max_pair_matches);
    int kept = 0;
    for (const Pair& p : pairs) {
      if (kept >= params.keep_per_pair) break;
      const vd_float4 observed = vd_pose_apply(cam_to_world, cur.camera_points[p.a]);
      const vd_float4 predicted = predicted_host_[p.b];
      float du = 1e9f, dv = 1e9f;
      if (predicted.w > 0.f) {
        const vd_float4 pc = vd_pose_apply(world_to_cam, predicted);
        if (pc.z > 1e-3f) {
          du = vd_project_u(cam, pc) - cur.u[p.a];
          dv = vd_project_v(cam, pc) - cur.v[p.a];
        }
      }
      const int why = vd_match_prune(rows_host_[size_t(f) * n_cur + p.a], predicted, observed, du, dv, params.prune);
      switch (why) {
        case VD_PRUNE_DESCRIPTOR: ++stats->pruned_descriptor; continue;
        case VD_PRUNE_RATIO: ++stats->pruned_ratio; continue;
        case VD_PRUNE_SCREEN: ++stats->pruned_screen; continue;
        case VD_PRUNE_WORLD: ++stats->pruned_world; continue;
        case VD_PRUNE_NO_POSITION: ++stats->pruned_position; continue;
        default: break;
      }
      SparseMatch m;
      m.cur = p.a;
      m.frame = candidates[f];
      m.feature = p.b - frames_host_[2 * f];
      m.descriptor_distance = std::sqrt(p.d2);
      m.canonical = cand_canonical_host_[p.b];
      m.target = observed;
      m.camera_point = cur.camera_points[p.a];
      m.predicted = predicted;
      out->push_back(m);
      ++kept;
    }
    stats->kept += kept;
  }
  return Status::Ok();
}

Status FeatureMatcher::Lift(FrameFeatures* f, const DeviceRaster& raster, const DeviceMesh& mesh,
                            const DeviceField& field, const VdPose& cam_to_world, const VdPose& world_to_cam,
                            bool no_model) {
  const FeatureParams& params = params_;
  const size_t n = f->size_keypoints();
  f->canonical.assign(n, VD_F4(0.f, 0.f, 0.f, 0.f));
  if (n == 0) return Status::Ok();
  if (!field.valid()) return FailedPrecondition("lifting features needs the deformation field");
  std::vector<vd_float4> points(n);
  std::vector<int32_t> pixels(n);
  const VdCamera& cam = raster.cam;
  for (size_t i = 0; i < n; ++i) {
    points[i] = vd_pose_apply(cam_to_world, f->camera_points[i]);
    points[i].w = f->camera_points[i].w;
    const int x = int(std::lround(f->u[i])), y = int(std::lround(f->v[i]));
    pixels[i] = (no_model || x < 0 || y < 0 || x >= cam.width || y >= cam.height) ? -1 : y * cam.width + x;
  }
  VdLiftParams lp{};
  lp.world_to_cam = world_to_cam;
  lp.max_depth_gap = params.lift_max_depth_gap;
  lp.tolerance = params.lift_tolerance;
  lp.iterations = params.lift_iterations;
  lp.no_model = no_model ? 1 : 0;
  VD_RETURN_IF_ERROR(ctx_->Reserve(&lift_points_, n));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&lift_pixels_, n));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&lift_out_, n));
  VD_RETURN_IF_ERROR(ctx_->Upload(lift_points_, points.data(), n));
  VD_RETURN_IF_ERROR(ctx_->Upload(lift_pixels_, pixels.data(), n));
  VD_RETURN_IF_ERROR(ocl::LiftFeatures(*ctx_, n, lift_points_, lift_pixels_, raster.ids, raster.bary, raster.vertex,
                                       mesh.positions_grid, mesh.triangles, field, lp, lift_out_));
  return ctx_->Download(lift_out_, f->canonical.data(), n);
}

void RetargetMatches(const VdPose& cam_to_world, const VdMatchPrune& prune, std::vector<SparseMatch>* matches) {
  size_t kept = 0;
  for (SparseMatch& m : *matches) {
    m.target = vd_pose_apply(cam_to_world, m.camera_point);
    vd_float4 e = m.target - m.predicted;
    if (vd_dot3(e, e) > prune.max_world_distance * prune.max_world_distance) continue;
    (*matches)[kept++] = m;
  }
  matches->resize(kept);
}

void AppendSparseConstraints(const std::vector<SparseMatch>& matches, float weight, std::vector<VdCorrespondence>* out) {
  for (const SparseMatch& m : matches) {
    for (int axis = 0; axis < 3; ++axis) {
      VdCorrespondence c;
      c.canonical = VD_F4(m.canonical.x, m.canonical.y, m.canonical.z, weight);
      c.target = VD_F4(m.target.x, m.target.y, m.target.z, -1.f);  // w: no brick hint
      c.normal = VD_F4(axis == 0 ? 1.f : 0.f, axis == 1 ? 1.f : 0.f, axis == 2 ? 1.f : 0.f, 0.f);
      out->push_back(c);
    }
  }
}

}  // namespace vd
