#include "stats.h"

#include <cstdio>
#include <sstream>

namespace vd {

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  const size_t i = std::min(v.size() - 1, static_cast<size_t>(q * (v.size() - 1) + 0.5));
  std::nth_element(v.begin(), v.begin() + i, v.end());
  return v[i];
}

std::string StageStats::Json() const {
  std::ostringstream os;
  os.setf(std::ios::fixed);
  os.precision(3);
  auto entry = [&](int s) {
    os << "{\"mean_ms\": " << Mean(s) << ", \"median_ms\": " << Percentile(s, 0.5) << ", \"p95_ms\": " << Percentile(s, 0.95)
       << "}";
  };
  os << "{";
  for (int s = 0; s < StageTimes::kCount; ++s) {
    os << "\"" << StageTimes::kNames[s] << "\": ";
    entry(s);
    os << ", ";
  }
  os << "\"total\": ";
  entry(-1);
  os << "}";
  return os.str();
}

std::string StageStats::Summary() const {
  std::ostringstream os;
  os.setf(std::ios::fixed);
  os.precision(1);
  for (int s = 0; s < StageTimes::kCount; ++s) os << (s ? " | " : "") << StageTimes::kNames[s] << " " << Mean(s);
  os << " | total " << Mean(-1) << " ms";
  return os.str();
}

}  // namespace vd
