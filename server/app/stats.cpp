#include "stats.h"

#include <cstdio>
#include <sstream>

namespace vd {

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
