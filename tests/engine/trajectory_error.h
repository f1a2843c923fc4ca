#pragma once
// Absolute trajectory error against a data set's ground-truth poses (7-Scenes layout: one
// frame-%06d.pose.txt per frame, a row-major 4x4 camera-to-world matrix). Shared by
// sevenscenes_ate_test and vd_room_bench, so the test's bound and the benchmark's figure are the
// same measure.
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <string>
#include <vector>

namespace vd::test {

// Reads a 4x4 pose; false when the file is missing or holds fewer than 16 numbers.
inline bool ReadPoseFile(const std::string& path, Eigen::Matrix4d* T) {
  std::ifstream in(path);
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c)
      if (!(in >> (*T)(r, c))) return false;
  return true;
}

struct TrajectoryError {
  // RMSE of the camera positions, metres: anchored (world = the first frame's camera, which both
  // trajectories share by construction, no further alignment), and the standard ATE of Sturm et
  // al. (TUM RGB-D benchmark): after the rigid alignment (Horn / Umeyama, no scale) of the
  // estimated positions onto the ground truth.
  double anchored = 0, aligned = 0;
  // Largest anchored position error, metres.
  double worst = 0;
};

// est and gt: camera positions per frame, the same count (at least one).
inline TrajectoryError ComputeTrajectoryError(const std::vector<Eigen::Vector3d>& est,
                                              const std::vector<Eigen::Vector3d>& gt) {
  TrajectoryError out;
  const int n = int(std::min(est.size(), gt.size()));
  if (n == 0) return out;
  Eigen::Matrix3Xd a(3, n), b(3, n);
  double sum_sq = 0;
  for (int k = 0; k < n; ++k) {
    a.col(k) = est[k];
    b.col(k) = gt[k];
    const double e = (gt[k] - est[k]).norm();
    sum_sq += e * e;
    out.worst = std::max(out.worst, e);
  }
  out.anchored = std::sqrt(sum_sq / n);
  const Eigen::Matrix4d align = Eigen::umeyama(a, b, false);
  const Eigen::Matrix3Xd aligned = (align.topLeftCorner<3, 3>() * a).colwise() + align.topRightCorner<3, 1>();
  out.aligned = std::sqrt((aligned - b).colwise().squaredNorm().mean());
  return out;
}

}  // namespace vd::test
