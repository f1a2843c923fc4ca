#include "core/colour_registration.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <vector>

namespace vd {
namespace {

constexpr int kSide = 8;  // the sides' level is read from kSide..kReach pixels out

double Median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

}  // namespace

const char* VerdictName(ColourRegistration::Verdict v) {
  switch (v) {
    case ColourRegistration::Verdict::kRegistered:
      return "registered";
    case ColourRegistration::Verdict::kUnregistered:
      return "not registered";
    default:
      return "undecided";
  }
}

void ColourRegistration::Clear() {
  profile_ = {};
  samples_ = {};
  frames_ = 0;
  verdict_ = Verdict::kUndecided;
}

double ColourRegistration::Ratio(const Profile& p) {
  constexpr int R = kReach;
  double peak = 0.0;
  for (int k = -kPeakReach; k <= kPeakReach; ++k) peak = std::max(peak, p[k + R]);
  std::vector<double> near, far;
  for (int k = kSide; k <= R; ++k) {
    near.push_back(p[R - k]);
    far.push_back(p[R + k]);
  }
  const double level = std::max(Median(near), Median(far));
  if (!(peak > 0.0)) return 0.0;
  // Texture on neither side (a uniform object before nothing): only the edge itself has a step.
  if (!(level > 1e-9 * peak)) return 1e9;
  return peak / level;
}

double ColourRegistration::ratio() const {
  const int64_t enough = std::max<int64_t>(1, params_.min_samples / 4);
  double r = -1.0;
  for (int axis = 0; axis < 2; ++axis)
    if (samples_[axis] >= enough) r = r < 0.0 ? Ratio(profile_[axis]) : std::min(r, Ratio(profile_[axis]));
  if (r >= 0.0) return r;
  Profile both;
  for (size_t i = 0; i < both.size(); ++i) both[i] = profile_[0][i] + profile_[1][i];
  return Ratio(both);
}

ColourRegistration::Verdict ColourRegistration::Add(const RgbdFrame& frame) {
  if (verdict_ != Verdict::kUndecided) return verdict_;
  ++frames_;
  const int w = frame.depth.cols, h = frame.depth.rows;
  if (!frame.color.empty() && frame.color.type() == CV_8UC3 && frame.depth.type() == CV_16UC1 &&
      frame.color.size() == frame.depth.size() && w > 2 * kReach + 2 && h > 2 * kReach + 2 && frame.depth_scale > 0.f) {
    cv::Mat gray8, luma;
    cv::cvtColor(frame.color, gray8, cv::COLOR_BGR2GRAY);
    gray8.convertTo(luma, CV_32F, 1.0 / 255.0);
    const float lo = min_depth_ * frame.depth_scale, hi = max_depth_ * frame.depth_scale;
    auto depth_at = [&](int x, int y) {
      const float d = float(frame.depth.at<uint16_t>(y, x));
      return d > 0.f && d >= lo && d <= hi ? d : 0.f;  // 0: no surface
    };
    // Along x (axis 0) and y (axis 1): the pair (p, p + 1) is an edge; the step at offset k is
    // between the pair k further towards the far side.
    for (int axis = 0; axis < 2; ++axis) {
      const int len = axis == 0 ? w : h, lines = axis == 0 ? h : w;
      for (int line = 0; line < lines; ++line) {
        auto depth = [&](int p) { return axis == 0 ? depth_at(p, line) : depth_at(line, p); };
        auto step = [&](int p) {
          const float a = axis == 0 ? luma.at<float>(line, p) : luma.at<float>(p, line);
          const float b = axis == 0 ? luma.at<float>(line, p + 1) : luma.at<float>(p + 1, line);
          return double(std::fabs(b - a));
        };
        float za = depth(kReach);
        for (int p = kReach; p + 1 + kReach < len; ++p) {
          const float zb = depth(p + 1);
          int far = 0;  // +1: the far side is p + 1; -1: it is p
          if ((za > 0.f) != (zb > 0.f))
            far = za > 0.f ? 1 : -1;
          else if (za > 0.f && std::fabs(za - zb) > params_.edge_jump * std::min(za, zb))
            far = zb > za ? 1 : -1;
          if (far != 0) {
            for (int k = -kReach; k <= kReach; ++k) profile_[axis][k + kReach] += step(p + far * k);
            ++samples_[axis];
          }
          za = zb;
        }
      }
    }
  }
  if (samples() >= params_.min_samples)
    verdict_ = ratio() >= params_.min_peak_ratio ? Verdict::kRegistered : Verdict::kUnregistered;
  else if (frames_ >= params_.max_frames)
    verdict_ = Verdict::kUnregistered;
  return verdict_;
}

}  // namespace vd
