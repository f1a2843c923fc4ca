#pragma once
// Per-stage timing statistics (last, mean, median, p95) and frame-rate bookkeeping.
#include <algorithm>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "core/engine.h"

namespace vd {

class StageStats {
 public:
  void Add(const StageTimes& t, double total_ms) {
    for (int s = 0; s < StageTimes::kCount; ++s) samples_[s].push_back(t.ms[s]);
    totals_.push_back(total_ms);
    last_ = t;
  }
  size_t count() const { return totals_.size(); }
  const StageTimes& last() const { return last_; }
  double Mean(int stage) const { return MeanOf(stage < 0 ? totals_ : samples_[stage]); }
  double Percentile(int stage, double q) const {
    std::vector<double> v = stage < 0 ? totals_ : samples_[stage];
    if (v.empty()) return 0.0;
    const size_t i = std::min(v.size() - 1, static_cast<size_t>(q * (v.size() - 1) + 0.5));
    std::nth_element(v.begin(), v.begin() + i, v.end());
    return v[i];
  }
  // {"stages": {...}, "total": {...}} with mean/median/p95 in ms.
  std::string Json() const;
  // "preprocess 3.1 | raster 2.0 | ..." of the means.
  std::string Summary() const;

 private:
  static double MeanOf(const std::vector<double>& v) {
    if (v.empty()) return 0.0;
    double s = 0;
    for (double x : v) s += x;
    return s / v.size();
  }
  std::array<std::vector<double>, StageTimes::kCount> samples_;
  std::vector<double> totals_;
  StageTimes last_;
};

}  // namespace vd
