#include "core/rigid_tracker.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

namespace vd {

IcpSystem IcpSystem::FromAccumulator(const double acc[VD_ICP_ACC]) {
  IcpSystem s;
  int q = 0;
  for (int r = 0; r < 6; ++r)
    for (int c = r; c < 6; ++c) s.A(r, c) = s.A(c, r) = acc[q++];
  for (int r = 0; r < 6; ++r) s.b(r) = acc[VD_ICP_ACC_JTR + r];
  s.sum_sq_residual = acc[VD_ICP_ACC_R2];
  s.inliers = int(acc[VD_ICP_ACC_COUNT]);
  return s;
}

Eigen::Matrix4d PoseIncrement(const Vector6d& xi) {
  const Eigen::Vector3d w = xi.head<3>();
  Eigen::Matrix4d dT = Eigen::Matrix4d::Identity();
  const double angle = w.norm();
  if (angle > 1e-12) dT.topLeftCorner<3, 3>() = Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
  dT.topRightCorner<3, 1>() = xi.tail<3>();
  return dT;
}

void AddSparseRows(const std::vector<PosePair>& pairs, const Eigen::Matrix4d& T, double weight, double huber,
                   IcpSystem* sys) {
  for (const PosePair& m : pairs) {
    const Eigen::Vector3d pw = T.topLeftCorner<3, 3>() * m.camera_point + T.topRightCorner<3, 1>();
    const Eigen::Vector3d res = pw - m.world_target;
    const double norm = res.norm();
    const double w = weight * (norm <= huber ? 1.0 : huber / norm);
    for (int axis = 0; axis < 3; ++axis) {
      Eigen::Vector3d e = Eigen::Vector3d::Zero();
      e(axis) = 1.0;
      Vector6d J;
      J.head<3>() = pw.cross(e);
      J.tail<3>() = e;
      sys->A.noalias() += w * J * J.transpose();
      sys->b.noalias() += w * J * res(axis);
    }
  }
}

void AddDegeneracyPrior(double tau, const Vector6d& xi_total, IcpSystem* sys) {
  const Eigen::SelfAdjointEigenSolver<Matrix6d> es(sys->A);
  const double lmax = std::max(es.eigenvalues()(5), 1e-30);
  Vector6d mu;
  for (int i = 0; i < 6; ++i) {
    const double r = std::max(es.eigenvalues()(i) / lmax, 1e-12);
    mu(i) = lmax * tau * tau / r;
  }
  const Matrix6d P = es.eigenvectors() * mu.asDiagonal() * es.eigenvectors().transpose();
  sys->A += P;
  sys->b += P * xi_total;
}

PoseStep SolvePoseStep(IcpSystem sys, const std::vector<PosePair>& pairs, const Eigen::Matrix4d& T,
                       const Vector6d& xi_total, const PoseStepParams& params) {
  if (!pairs.empty()) AddSparseRows(pairs, T, params.sparse_weight, params.sparse_huber, &sys);
  if (params.degeneracy > 0.0) AddDegeneracyPrior(params.degeneracy, xi_total, &sys);
  PoseStep step;
  step.pose = T;
  step.xi = sys.A.ldlt().solve(-sys.b);
  if (!step.xi.allFinite()) {
    step.xi.setZero();
    return step;
  }
  step.pose = PoseIncrement(step.xi) * T;
  step.ok = true;
  return step;
}

std::string CheckTracking(const Eigen::Matrix4d& previous, const Eigen::Matrix4d& pose, int inliers,
                          int valid_pixels, const TrackingLimits& limits) {
  std::ostringstream why;
  if (!pose.allFinite()) {
    why << "non-finite pose";
    return why.str();
  }
  const Eigen::Matrix4d delta = previous.inverse() * pose;
  const double dt = delta.topRightCorner<3, 1>().norm();
  const double dr = Eigen::AngleAxisd(Eigen::Matrix3d(delta.topLeftCorner<3, 3>())).angle() * 180.0 / M_PI;
  if (inliers < limits.min_inlier_fraction * valid_pixels) {
    why << "too few ICP inliers (" << inliers << " of " << valid_pixels << " valid pixels)";
  } else if (dt > limits.max_translation || dr > limits.max_rotation_deg) {
    why << "implausible motion (" << dt * 1000 << " mm, " << dr << " deg in one frame)";
  }
  return why.str();
}

}  // namespace vd
