#pragma once
// Host math of the rigid tracker: one Gauss-Newton pose step from the ICP normal equations the
// device reduced (shared/icp.h) and the sparse matches, and the decision whether a frame's pose is
// plausible. Pure functions, no device: tests/solver/rigid_tracker_test.cpp checks them on the CPU.
// The increment is a left one, T' = exp(xi) T with xi = (omega, v), as the kernel linearises it.
#include <string>
#include <vector>

#include <Eigen/Core>

#include "shared/icp.h"

namespace vd {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

// The normal equations A xi = -b of one ICP iteration.
struct IcpSystem {
  Matrix6d A = Matrix6d::Zero();
  Vector6d b = Vector6d::Zero();
  // Sum of squared point-to-plane residuals of the inliers, and their count.
  double sum_sq_residual = 0.0;
  int inliers = 0;
  // Unpacks the device reduction (layout in shared/icp.h: upper triangle of J^T J row by row,
  // J^T r, r^2, count).
  static IcpSystem FromAccumulator(const double acc[VD_ICP_ACC]);
};

// A sparse match as the pose sees it: the keypoint in this frame's camera and where the model
// says it is in the world.
struct PosePair {
  Eigen::Vector3d camera_point;
  Eigen::Vector3d world_target;
};

struct PoseStepParams {
  // Weight of each sparse row against one dense pixel row: w_s / w_d, divided by the level's
  // pixel-count ratio so the balance is the same on every pyramid level.
  double sparse_weight = 0.0;
  // Huber threshold of the sparse rows, metres: a wrong match pulls linearly, not quadratically.
  double sparse_huber = 0.01;
  // Information ratio below which a direction counts as unobserved (EngineParams::icp_degeneracy);
  // 0 = no prior.
  double degeneracy = 0.0;
};

struct PoseStep {
  Vector6d xi = Vector6d::Zero();
  // exp(xi) * T, or T when the step failed.
  Eigen::Matrix4d pose = Eigen::Matrix4d::Identity();
  // False when the system gave a non-finite step (the caller stops iterating).
  bool ok = false;
};

// exp(xi) for xi = (omega, v): rotation by the angle-axis omega, then translation v (first order
// in the coupling, as the linearisation).
Eigen::Matrix4d PoseIncrement(const Vector6d& xi);

// Adds three Huber-weighted point-to-point rows e_axis . (T p - q) per pair at pose T.
void AddSparseRows(const std::vector<PosePair>& pairs, const Eigen::Matrix4d& T, double weight, double huber,
                   IcpSystem* sys);

// Prior towards the frame's starting pose in the directions the data barely observes (the spin of
// a surface of revolution about its axis, a plane sliding in itself), where a bare Gauss-Newton
// step turns noise and small model errors into drift. Direction i of A, with information ratio
// r_i = lambda_i / lambda_max, gets prior weight lambda_i (tau / r_i)^2: its step shrinks by
// r_i^2 / (r_i^2 + tau^2), nothing for r_i >> tau, all for r_i << tau. xi_total is the sum of this
// frame's increments so far (the first-order twist from the starting pose).
void AddDegeneracyPrior(double tau, const Vector6d& xi_total, IcpSystem* sys);

// One step from pose T: the sparse rows and the prior added to `sys`, then solved.
PoseStep SolvePoseStep(IcpSystem sys, const std::vector<PosePair>& pairs, const Eigen::Matrix4d& T,
                       const Vector6d& xi_total, const PoseStepParams& params);

struct TrackingLimits {
  // Fails below this fraction of the valid pixels as inliers ...
  float min_inlier_fraction = 0.10f;
  // ... or when the pose moves more than this in one frame (the sensor does not teleport).
  float max_translation = 0.20f;
  float max_rotation_deg = 30.f;
};

// Empty when `pose` is a plausible successor of `previous`, else why it is not.
std::string CheckTracking(const Eigen::Matrix4d& previous, const Eigen::Matrix4d& pose, int inliers,
                          int valid_pixels, const TrackingLimits& limits);

}  // namespace vd
