#pragma once
// Per-stage timing statistics (last, mean, median, p95) and frame-rate bookkeeping.
#include <algorithm>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "core/engine.h"

namespace vd {

// The q-quantile (0..1, nearest rank) of v; 0 when v is empty.
double Percentile(std::vector<double> v, double q);

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
  double Percentile(int stage, double q) const { return vd::Percentile(stage < 0 ? totals_ : samples_[stage], q); }
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
