// The rigid tracker's host math on exact problems: poses recovered from point-to-plane and
// point-to-point data, unobserved directions held by the degeneracy prior, failures detected.
#include "core/rigid_tracker.h"

#include <cmath>
#include <random>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

namespace vd {
namespace {

Eigen::Matrix4d MakePose(const Eigen::Vector3d& axis_angle, const Eigen::Vector3d& t) {
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  if (axis_angle.norm() > 0)
    T.topLeftCorner<3, 3>() = Eigen::AngleAxisd(axis_angle.norm(), axis_angle.normalized()).toRotationMatrix();
  T.topRightCorner<3, 1>() = t;
  return T;
}

// A point of the model surface (world) with its normal, and the camera point that sees it.
struct PlanePoint {
  Eigen::Vector3d q, m, p;
};

// Point-to-plane samples on the planes with the given normals through (0, 0, 1.2); the camera
// points are where a camera at truth sees them.
std::vector<PlanePoint> PlaneSamples(const std::vector<Eigen::Vector3d>& normals, const Eigen::Matrix4d& truth) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.3, 0.3);
  const Eigen::Matrix4d inv = truth.inverse();
  std::vector<PlanePoint> out;
  for (const Eigen::Vector3d& n : normals) {
    // Two tangent directions of the plane.
    const Eigen::Vector3d t1 = n.unitOrthogonal(), t2 = n.cross(t1);
    for (int i = 0; i < 200; ++i) {
      PlanePoint s;
      s.q = Eigen::Vector3d(0, 0, 1.2) + u(rng) * t1 + u(rng) * t2;
      s.m = n;
      s.p = inv.topLeftCorner<3, 3>() * s.q + inv.topRightCorner<3, 1>();
      out.push_back(s);
    }
  }
  return out;
}

// The accumulator the device reduction writes (shared/icp.h) for these samples at pose T.
std::vector<double> Accumulate(const std::vector<PlanePoint>& samples, const Eigen::Matrix4d& T) {
  std::vector<double> acc(VD_ICP_ACC, 0.0);
  for (const PlanePoint& s : samples) {
    const Eigen::Vector3d pw = T.topLeftCorner<3, 3>() * s.p + T.topRightCorner<3, 1>();
    const double r = s.m.dot(pw - s.q);
    Vector6d J;
    J << pw.cross(s.m), s.m;
    int k = 0;
    for (int a = 0; a < 6; ++a)
      for (int b = a; b < 6; ++b) acc[k++] += J(a) * J(b);
    for (int a = 0; a < 6; ++a) acc[VD_ICP_ACC_JTR + a] += J(a) * r;
    acc[VD_ICP_ACC_R2] += r * r;
    acc[VD_ICP_ACC_COUNT] += 1.0;
  }
  return acc;
}

double RotationErrorDeg(const Eigen::Matrix4d& a, const Eigen::Matrix4d& b) {
  const Eigen::Matrix3d d = a.topLeftCorner<3, 3>().transpose() * b.topLeftCorner<3, 3>();
  return Eigen::AngleAxisd(d).angle() * 180.0 / M_PI;
}

TEST(RigidTrackerTest, AccumulatorUnpacksToTheNormalEquations) {
  const Eigen::Matrix4d truth = MakePose({0.02, -0.01, 0.03}, {0.01, 0.02, -0.01});
  const auto samples = PlaneSamples({Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitZ()}, truth);
  const auto acc = Accumulate(samples, Eigen::Matrix4d::Identity());
  const IcpSystem sys = IcpSystem::FromAccumulator(acc.data());
  Matrix6d A = Matrix6d::Zero();
  Vector6d b = Vector6d::Zero();
  for (const PlanePoint& s : samples) {
    Vector6d J;
    J << s.p.cross(s.m), s.m;
    A += J * J.transpose();
    b += J * s.m.dot(s.p - s.q);
  }
  EXPECT_LT((sys.A - A).norm(), 1e-9 * A.norm());
  EXPECT_LT((sys.b - b).norm(), 1e-9 * b.norm());
  EXPECT_EQ(sys.inliers, int(samples.size()));
  EXPECT_GT(sys.sum_sq_residual, 0.0);
}

// Gauss-Newton iterations from the identity, each on the normal equations at the current pose.
Eigen::Matrix4d Iterate(const std::vector<PlanePoint>& samples, const PoseStepParams& params, int iterations) {
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  Vector6d xi_total = Vector6d::Zero();
  for (int it = 0; it < iterations; ++it) {
    const auto acc = Accumulate(samples, T);
    const PoseStep step = SolvePoseStep(IcpSystem::FromAccumulator(acc.data()), {}, T, xi_total, params);
    EXPECT_TRUE(step.ok);
    T = step.pose;
    xi_total += step.xi;
  }
  return T;
}

TEST(RigidTrackerTest, RecoversAKnownPoseFromPointToPlaneData) {
  // 5 degrees and 4 cm away; three orthogonal planes observe all six directions.
  const Eigen::Matrix4d truth = MakePose(Eigen::Vector3d(1, 2, -1).normalized() * (5.0 * M_PI / 180.0), {0.03, -0.02, 0.015});
  const auto samples = PlaneSamples({Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), Eigen::Vector3d(0, 0, -1)}, truth);
  PoseStepParams params;
  const Eigen::Matrix4d exact = Iterate(samples, params, 10);
  EXPECT_LT((exact.topRightCorner<3, 1>() - truth.topRightCorner<3, 1>()).norm(), 1e-9);
  EXPECT_LT(RotationErrorDeg(exact, truth), 1e-7);
  // With the default degeneracy prior the soft pull towards the start costs under a micrometre.
  params.degeneracy = 5e-5;
  const Eigen::Matrix4d held = Iterate(samples, params, 10);
  EXPECT_LT((held.topRightCorner<3, 1>() - truth.topRightCorner<3, 1>()).norm(), 1e-6);
  EXPECT_LT(RotationErrorDeg(held, truth), 1e-4);
  // The first step alone already goes most of the way (Gauss-Newton on a near-linear problem).
  const Eigen::Matrix4d first = Iterate(samples, params, 1);
  EXPECT_LT((first.topRightCorner<3, 1>() - truth.topRightCorner<3, 1>()).norm(), 0.005);
}

TEST(RigidTrackerTest, RecoversAKnownPoseFromSparsePairsAlone) {
  const Eigen::Matrix4d truth = MakePose({0.05, 0.02, -0.04}, {-0.02, 0.01, 0.05});
  std::vector<PosePair> pairs;
  for (const Eigen::Vector3d& c : {Eigen::Vector3d(0.1, 0, 1), Eigen::Vector3d(-0.1, 0.1, 1.1),
                                  Eigen::Vector3d(0, -0.15, 0.9), Eigen::Vector3d(0.05, 0.05, 1.3)})
    pairs.push_back({c, truth.topLeftCorner<3, 3>() * c + truth.topRightCorner<3, 1>()});
  PoseStepParams params;
  params.sparse_weight = 1.0;
  // Above every residual here: plain least squares.
  params.sparse_huber = 1.0;
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  Vector6d xi_total = Vector6d::Zero();
  for (int it = 0; it < 10; ++it) {
    const PoseStep step = SolvePoseStep(IcpSystem(), pairs, T, xi_total, params);
    ASSERT_TRUE(step.ok);
    T = step.pose;
    xi_total += step.xi;
  }
  EXPECT_LT((T.topRightCorner<3, 1>() - truth.topRightCorner<3, 1>()).norm(), 1e-7);
  EXPECT_LT(RotationErrorDeg(T, truth), 1e-5);
}

TEST(RigidTrackerTest, HuberCapsTheWeightOfAFarPair) {
  // One pair 1 m off: with Huber 1 cm its rows count 1/100 of a close pair's.
  IcpSystem near_sys, far_sys;
  const Eigen::Matrix4d I = Eigen::Matrix4d::Identity();
  AddSparseRows({{Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(0.005, 0, 1)}}, I, 2.0, 0.01, &near_sys);
  AddSparseRows({{Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(1.0, 0, 1)}}, I, 2.0, 0.01, &far_sys);
  EXPECT_NEAR(near_sys.A(3, 3), 2.0, 1e-12);
  EXPECT_NEAR(far_sys.A(3, 3), 2.0 * 0.01 / 1.0, 1e-12);
}

TEST(RigidTrackerTest, UnobservedDirectionsAreHeld) {
  // A plane z = 1.2 seen face on, and a wall x = 0 that the data barely sees (weight 1e-6, an
  // information ratio far below tau): x and the spin about z are nearly unobserved. The truth
  // slides 2 cm in x and 1 cm towards the camera. A bare Gauss-Newton step follows the slide on
  // the wall's say-so alone; the prior holds it and follows only the approach.
  const Eigen::Matrix4d truth = MakePose({0, 0, 0.02}, {0.02, 0, -0.01});
  const auto face = PlaneSamples({Eigen::Vector3d(0, 0, -1)}, truth);
  const auto wall = PlaneSamples({Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY()}, truth);
  auto run = [&](double tau) {
    PoseStepParams params;
    params.degeneracy = tau;
    Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
    Vector6d xi_total = Vector6d::Zero();
    for (int it = 0; it < 5; ++it) {
      auto acc = Accumulate(face, T);
      const auto weak = Accumulate(wall, T);
      for (int k = 0; k < VD_ICP_ACC; ++k) acc[k] += 1e-6 * weak[k];
      const PoseStep step = SolvePoseStep(IcpSystem::FromAccumulator(acc.data()), {}, T, xi_total, params);
      EXPECT_TRUE(step.ok);
      T = step.pose;
      xi_total += step.xi;
    }
    return T;
  };
  const Eigen::Matrix4d free = run(0.0);
  EXPECT_NEAR(free(0, 3), 0.02, 1e-4);
  EXPECT_NEAR(RotationErrorDeg(free, Eigen::Matrix4d::Identity()), 0.02 * 180 / M_PI, 1e-3);
  const Eigen::Matrix4d held = run(5e-5);
  EXPECT_NEAR(held(2, 3), -0.01, 1e-5);
  EXPECT_LT(std::abs(held(0, 3)), 1e-4);
  EXPECT_LT(std::abs(held(1, 3)), 1e-4);
  EXPECT_LT(RotationErrorDeg(held, Eigen::Matrix4d::Identity()), 0.01);
}

TEST(RigidTrackerTest, PriorShrinksAWeakDirectionByTheStatedFactor) {
  // Eigenvalues 1 (five directions) and r = 2 tau: the weak step shrinks by r^2 / (r^2 + tau^2) = 0.8.
  const double tau = 1e-3, r = 2 * tau;
  IcpSystem sys;
  sys.A = Matrix6d::Identity();
  sys.A(5, 5) = r;
  sys.b = -Vector6d::Ones() * 1e-3;
  PoseStepParams params;
  params.degeneracy = tau;
  const PoseStep held = SolvePoseStep(sys, {}, Eigen::Matrix4d::Identity(), Vector6d::Zero(), params);
  params.degeneracy = 0;
  const PoseStep free = SolvePoseStep(sys, {}, Eigen::Matrix4d::Identity(), Vector6d::Zero(), params);
  ASSERT_TRUE(held.ok && free.ok);
  EXPECT_NEAR(held.xi(5) / free.xi(5), 0.8, 1e-9);
  // Strong directions (r = 1 >> tau) keep their step to within tau^2.
  EXPECT_NEAR(held.xi(0) / free.xi(0), 1.0, 2 * tau * tau);
}

TEST(RigidTrackerTest, ANonFiniteSystemIsAFailedStep) {
  IcpSystem sys;
  sys.A = Matrix6d::Identity();
  sys.b(2) = std::nan("");
  const Eigen::Matrix4d T = MakePose({0, 0.1, 0}, {0.1, 0, 0});
  const PoseStep step = SolvePoseStep(sys, {}, T, Vector6d::Zero(), PoseStepParams());
  EXPECT_FALSE(step.ok);
  EXPECT_EQ(step.pose, T);
  EXPECT_TRUE(step.xi.isZero());
}

TEST(RigidTrackerTest, TrackingFailuresAreDetected) {
  const TrackingLimits limits;
  const Eigen::Matrix4d prev = MakePose({0, 0.3, 0}, {0.5, 0, 0});
  const Eigen::Matrix4d small = prev * MakePose({0.01, 0, 0}, {0.01, 0, 0});
  EXPECT_EQ(CheckTracking(prev, small, 5000, 10000, limits), "");
  // 999 of 10000 valid pixels: below 10 %.
  EXPECT_NE(CheckTracking(prev, small, 999, 10000, limits).find("too few ICP inliers (999 of 10000"), std::string::npos);
  EXPECT_EQ(CheckTracking(prev, small, 1000, 10000, limits), "");
  // 25 cm in one frame, and 40 degrees.
  EXPECT_NE(CheckTracking(prev, prev * MakePose({0, 0, 0}, {0.25, 0, 0}), 5000, 10000, limits).find("implausible motion (250 mm"),
            std::string::npos);
  EXPECT_NE(CheckTracking(prev, prev * MakePose({0, 0, 40 * M_PI / 180}, {0, 0, 0}), 5000, 10000, limits).find("40 deg"),
            std::string::npos);
  Eigen::Matrix4d nan_pose = small;
  nan_pose(0, 3) = std::nan("");
  EXPECT_EQ(CheckTracking(prev, nan_pose, 5000, 10000, limits), "non-finite pose");
}

}  // namespace
}  // namespace vd
