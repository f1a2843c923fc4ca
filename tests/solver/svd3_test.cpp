// The 3x3 SVD and the Procrustes rotation of shared/svd3.h and shared/procrustes.h against Eigen
// (double precision) on random, structured and degenerate inputs.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include "cpu_ref/procrustes_ref.h"
#include "shared/procrustes.h"
#include "shared/svd3.h"

namespace vd {
namespace {

Eigen::Matrix3d ToEigen(const VdMat3& a) {
  Eigen::Matrix3d m;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) m(r, c) = a.m[3 * r + c];
  return m;
}

VdMat3 FromEigen(const Eigen::Matrix3d& m) {
  VdMat3 a;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) a.m[3 * r + c] = static_cast<float>(m(r, c));
  return a;
}

Eigen::Vector3d ToEigen(const vd_float4& v) { return {v.x, v.y, v.z}; }
vd_float4 ToF4(const Eigen::Vector3d& v) { return VD_F4(float(v.x()), float(v.y()), float(v.z()), 0.f); }

double MaxAbs(const Eigen::Matrix3d& m) { return m.cwiseAbs().maxCoeff(); }

Eigen::Matrix3d RandomRotation(std::mt19937& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  return Eigen::Quaterniond(g(rng), g(rng), g(rng), g(rng)).normalized().toRotationMatrix();
}

// The reference: Kabsch with Eigen's JacobiSVD in double on the same (float) S.
Eigen::Matrix3d EigenProcrustes(const VdMat3& s) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(ToEigen(s), Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d v = svd.matrixV();
  if ((v * svd.matrixU().transpose()).determinant() < 0) v.col(2) *= -1;
  return v * svd.matrixU().transpose();
}

// Checks U Σ Vᵀ against Eigen's singular values and A; tolerances relative to σ1 (float keeps
// every singular value to about eps·σ1, not eps·σi).
void ExpectGoodSvd(const Eigen::Matrix3d& a, double tol, double* worst_sigma, double* worst_rec) {
  VdMat3 u, v;
  vd_float4 sigma;
  vd_svd3(FromEigen(a), &u, &sigma, &v);
  const Eigen::Matrix3d A = ToEigen(FromEigen(a));
  const Eigen::Vector3d ref = Eigen::JacobiSVD<Eigen::Matrix3d>(A).singularValues();
  const Eigen::Vector3d s = ToEigen(sigma);
  const double scale = std::max(ref(0), 1e-300);
  // Equal singular values may come out in either order by an ulp.
  EXPECT_GE(s(0), s(1) - 1e-6 * scale);
  EXPECT_GE(s(1), s(2) - 1e-6 * scale);
  EXPECT_GE(s(2), 0.0);
  const double err_sigma = (s - ref).cwiseAbs().maxCoeff() / scale;
  EXPECT_LE(err_sigma, tol) << "sigma " << s.transpose() << " vs " << ref.transpose() << "\nA =\n" << A;
  const Eigen::Matrix3d U = ToEigen(u), V = ToEigen(v);
  const double err_rec = MaxAbs(U * s.asDiagonal() * V.transpose() - A) / scale;
  EXPECT_LE(err_rec, tol) << "A =\n" << A;
  EXPECT_LE(MaxAbs(U.transpose() * U - Eigen::Matrix3d::Identity()), 1e-5);
  EXPECT_LE(MaxAbs(V.transpose() * V - Eigen::Matrix3d::Identity()), 1e-5);
  EXPECT_NEAR(V.determinant(), 1.0, 1e-5);
  *worst_sigma = std::max(*worst_sigma, err_sigma);
  *worst_rec = std::max(*worst_rec, err_rec);
}

TEST(Svd3Test, MatchesEigenOnRandomMatrices) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  std::uniform_real_distribution<double> expo(-6.0, 6.0);
  double worst_sigma = 0, worst_rec = 0;
  for (int i = 0; i < 20000; ++i) {
    Eigen::Matrix3d a;
    for (int k = 0; k < 9; ++k) a(k / 3, k % 3) = uni(rng);
    a *= std::pow(10.0, expo(rng));  // scale invariance over 12 decades
    ExpectGoodSvd(a, 1e-5, &worst_sigma, &worst_rec);
    if (HasFailure()) return;
  }
  std::printf("random: worst |sigma - eigen| / sigma1 = %.2e, worst |U S V^T - A| / sigma1 = %.2e\n", worst_sigma,
              worst_rec);
}

TEST(Svd3Test, MatchesEigenOnStructuredSpectra) {
  std::mt19937 rng(11);
  // Repeated, clustered, widely spread and zero singular values, with and without reflections.
  const double spectra[][3] = {{1, 1, 1},      {1, 1, 0},     {1, 0, 0},        {0, 0, 0},   {1, 1e-3, 1e-3},
                               {1, 1e-3, 0},   {1, 0.5, 0.5}, {1, 1 - 1e-6, 0.3}, {2, 1, 1e-7}, {1, 1e-7, 1e-7},
                               {5, 4, 3},      {1e3, 1, 1e-3}};
  double worst_sigma = 0, worst_rec = 0;
  for (const auto& sp : spectra) {
    for (int i = 0; i < 300; ++i) {
      Eigen::Matrix3d u = RandomRotation(rng), v = RandomRotation(rng);
      if (i % 2) u.col(2) *= -1;  // det(A) < 0 half of the time
      const Eigen::Matrix3d a = u * Eigen::Vector3d(sp[0], sp[1], sp[2]).asDiagonal() * v.transpose();
      ExpectGoodSvd(a, 1e-5, &worst_sigma, &worst_rec);
      if (HasFailure()) return;
    }
  }
  // Outer products formed in float (rank 1 and 2 up to the rounding of the products), some with
  // an axis-aligned left factor as grid neighbours give: Jacobi then meets column pairs whose norms
  // are ~1e-20 of the largest, where d² + 4γ² would be denormal.
  std::normal_distribution<float> g(0.f, 1.f);
  for (int i = 0; i < 3000; ++i) {
    VdMat3 s = vd_mat3_zero();
    for (int r = 0; r <= i % 2; ++r) {
      vd_float4 p = VD_F4(g(rng), g(rng), g(rng), 0.f);
      if (i % 3 == 0) p = (r == 0) ? VD_F4(0.f, p.y, 0.f, 0.f) : VD_F4(0.f, 0.f, p.z, 0.f);
      vd_mat3_add_outer(&s, p, VD_F4(g(rng), g(rng), g(rng), 0.f));
    }
    ExpectGoodSvd(ToEigen(s), 1e-5, &worst_sigma, &worst_rec);
    if (HasFailure()) return;
  }
  // Axis-aligned and sparse inputs, where Jacobi meets exact zeros.
  const Eigen::Matrix3d sparse[] = {Eigen::Matrix3d::Identity(), -Eigen::Matrix3d::Identity(),
                                    Eigen::Vector3d(0, 3, -2).asDiagonal(), Eigen::Matrix3d::Zero(),
                                    (Eigen::Matrix3d() << 0, 1, 0, 0, 0, 1, 1, 0, 0).finished(),
                                    (Eigen::Matrix3d() << 0, 0, 0, 0, 0, 0, 0, 0, 5).finished()};
  for (const auto& a : sparse) ExpectGoodSvd(a, 1e-6, &worst_sigma, &worst_rec);
  std::printf("structured: worst |sigma - eigen| / sigma1 = %.2e, worst |U S V^T - A| / sigma1 = %.2e\n", worst_sigma,
              worst_rec);
}

TEST(Svd3Test, RotationFormHasProperRotationsAndSignedSigma) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  for (int i = 0; i < 2000; ++i) {
    Eigen::Matrix3d a;
    for (int k = 0; k < 9; ++k) a(k / 3, k % 3) = uni(rng);
    VdMat3 u, v;
    vd_float4 sigma;
    vd_svd3_rotations(FromEigen(a), &u, &sigma, &v);
    EXPECT_NEAR(vd_mat3_det(u), 1.0f, 1e-5f);
    EXPECT_NEAR(vd_mat3_det(v), 1.0f, 1e-5f);
    EXPECT_EQ(sigma.z < 0, a.determinant() < 0) << a;
    EXPECT_GE(sigma.y, std::fabs(sigma.z));
    const Eigen::Matrix3d rec = ToEigen(u) * ToEigen(sigma).asDiagonal() * ToEigen(v).transpose();
    EXPECT_LE(MaxAbs(rec - a), 1e-5 * 3);
  }
}

TEST(Svd3Test, Mat3Helpers) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  Eigen::Matrix3d a, b;
  for (int k = 0; k < 9; ++k) a(k / 3, k % 3) = uni(rng), b(k / 3, k % 3) = uni(rng);
  const VdMat3 fa = FromEigen(a), fb = FromEigen(b);
  const Eigen::Matrix3d A = ToEigen(fa), B = ToEigen(fb);
  EXPECT_LE(MaxAbs(ToEigen(vd_mat3_mul(fa, fb)) - A * B), 1e-6);
  EXPECT_LE(MaxAbs(ToEigen(vd_mat3_mul_transpose(fa, fb)) - A * B.transpose()), 1e-6);
  EXPECT_EQ(ToEigen(vd_mat3_transpose(fa)), A.transpose());
  EXPECT_NEAR(vd_mat3_det(fa), A.determinant(), 1e-6);
  const vd_float4 p = VD_F4(0.3f, -0.2f, 0.7f, 9.f);
  EXPECT_LE((ToEigen(vd_mat3_apply(fa, p)) - A * ToEigen(p)).cwiseAbs().maxCoeff(), 1e-6);
  VdMat3 s = vd_mat3_zero();
  vd_mat3_add_outer(&s, p, VD_F4(1.f, 2.f, 3.f, 7.f));
  EXPECT_LE(MaxAbs(ToEigen(s) - ToEigen(p) * Eigen::RowVector3d(1, 2, 3)), 1e-7);
  EXPECT_EQ(vd_mat3_max_abs(fa), float(A.cwiseAbs().maxCoeff()));
  VdMat3 bad = fa;
  bad.m[4] = NAN;
  EXPECT_FALSE(vd_mat3_is_finite(bad));
  bad.m[4] = INFINITY;
  EXPECT_FALSE(vd_mat3_is_finite(bad));
  EXPECT_TRUE(vd_mat3_is_finite(fa));
}

// A 7-point neighbourhood: point 0 at centre with up to 6 grid neighbours (compact indices 1-6
// in the order +x, −x, +y, −y, +z, −z); slots not in `present` are −1.
struct Neighbourhood {
  std::vector<int> neighbours = std::vector<int>(6 * 7, -1);
  std::vector<vd_float4> t_hat = std::vector<vd_float4>(7);
  std::vector<vd_float4> t = std::vector<vd_float4>(7);
};

Neighbourhood MakeNeighbourhood(const Eigen::Vector3d& centre, double h, const Eigen::Matrix3d& rot,
                                const Eigen::Vector3d& shift, const std::vector<int>& present, double noise,
                                std::mt19937& rng) {
  static const int kDirs[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  std::normal_distribution<double> g(0.0, noise);
  Neighbourhood nb;
  nb.t_hat[0] = ToF4(centre);
  nb.t[0] = ToF4(rot * centre + shift);
  for (int d = 0; d < 6; ++d) {
    const Eigen::Vector3d th = centre + h * Eigen::Vector3d(kDirs[d][0], kDirs[d][1], kDirs[d][2]);
    nb.t_hat[1 + d] = ToF4(th);
    const Eigen::Vector3d jitter = noise > 0 ? Eigen::Vector3d(g(rng), g(rng), g(rng)) : Eigen::Vector3d::Zero();
    nb.t[1 + d] = ToF4(rot * th + shift + jitter);
  }
  for (int d : present) nb.neighbours[d] = 1 + d;
  return nb;
}

Eigen::Matrix3d PointRotation(const Neighbourhood& nb) {
  const vd_float4 q =
      vd_procrustes_point(0, nb.neighbours.data(), nullptr, nb.t.data(), nb.t_hat.data(), VD_F4(0.f, 0.f, 0.f, 1.f), 0);
  EXPECT_NEAR(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w, 1.f, 1e-6f);
  EXPECT_GE(q.w, 0.f);
  return ToEigen(vd_quat_to_mat3(q));
}

TEST(ProcrustesTest, RecoversKnownRotationFromNoiseFreeNeighbourhoods) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> pos(-1.0, 1.0);
  const std::vector<std::vector<int>> patterns = {
      {0, 1, 2, 3, 4, 5},  // full 6-neighbourhood
      {0, 2, 4},           // three orthogonal directions
      {1, 2, 5},           // three others
      {0, 2},              // two non-collinear: the cross product fixes the third axis
      {3, 5},
      {0, 1, 2, 3},  // coplanar (rank 2)
  };
  // Near the origin the float positions carry ~4e-7 relative rounding over a 1 cm spacing, so
  // the rotation is recoverable to 1e-5. At 1-2 m the positions' rounding alone (~1e-5 of the
  // spacing, worst with only 2-3 neighbours) moves the optimum by that much: checked at 1e-4.
  double worst_near = 0, worst_far = 0;
  for (const auto& present : patterns) {
    for (int i = 0; i < 500; ++i) {
      const Eigen::Matrix3d rot = RandomRotation(rng);
      const bool far = i % 2 == 1;
      const Eigen::Vector3d centre = far ? Eigen::Vector3d(pos(rng), pos(rng), 1.0 + pos(rng))
                                         : Eigen::Vector3d(0.05 * pos(rng), 0.05 * pos(rng), 0.05 * pos(rng));
      const Eigen::Vector3d shift = far ? Eigen::Vector3d(0.2, -0.1, 0.3) : Eigen::Vector3d(0.002, -0.001, 0.003);
      const Neighbourhood nb = MakeNeighbourhood(centre, 0.01, rot, shift, present, 0.0, rng);
      const double err = MaxAbs(PointRotation(nb) - rot);
      (far ? worst_far : worst_near) = std::max(far ? worst_far : worst_near, err);
      ASSERT_LE(err, far ? 1e-4 : 1e-5) << "pattern of " << present.size() << " neighbours at " << centre.transpose()
                                        << ", rotation\n" << rot;
    }
  }
  std::printf("noise-free recovery: worst |R - R_true| = %.2e near the origin, %.2e at 1-2 m\n", worst_near, worst_far);
}

TEST(ProcrustesTest, RecoversRotationsNearPiAndAtExtremeScales) {
  std::mt19937 rng(2);
  const std::vector<int> all = {0, 1, 2, 3, 4, 5};
  const Eigen::Vector3d axes[] = {Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitZ(),
                                  Eigen::Vector3d(1, 1, 1).normalized(), Eigen::Vector3d(-1, 2, 0.5).normalized()};
  for (const auto& axis : axes) {
    for (double angle : {M_PI, M_PI - 1e-4, 0.0, 1e-4, M_PI / 2}) {
      const Eigen::Matrix3d rot = Eigen::AngleAxisd(angle, axis).toRotationMatrix();
      const Neighbourhood nb = MakeNeighbourhood(Eigen::Vector3d(0.1, 0.2, 0.3), 0.004, rot, Eigen::Vector3d::Zero(),
                                                 all, 0.0, rng);
      EXPECT_LE(MaxAbs(PointRotation(nb) - rot), 1e-5) << "angle " << angle << " axis " << axis.transpose();
    }
  }
  for (double h : {1e-12, 1e-6, 1e3}) {
    const Eigen::Matrix3d rot = RandomRotation(rng);
    const Neighbourhood nb = MakeNeighbourhood(Eigen::Vector3d(h, 2 * h, -h), h, rot, Eigen::Vector3d::Zero(), all, 0.0, rng);
    EXPECT_LE(MaxAbs(PointRotation(nb) - rot), 1e-5) << "spacing " << h;
  }
}

TEST(ProcrustesTest, EqualsEigenSvdSolutionOnNoisyNeighbourhoods) {
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> pos(-1.0, 1.0);
  std::uniform_int_distribution<int> mask(1, 63);
  double worst = 0;
  int reflections = 0;
  for (int i = 0; i < 5000; ++i) {
    std::vector<int> present;
    const int m = mask(rng);
    for (int d = 0; d < 6; ++d)
      if (m & (1 << d)) present.push_back(d);
    // Noise up to the grid spacing itself: the best orthogonal matrix is then often a reflection.
    const double noise = 0.01 * std::pow(10.0, -3.0 * (pos(rng) + 1.0) / 2.0);
    const Neighbourhood nb = MakeNeighbourhood(Eigen::Vector3d(pos(rng), pos(rng), pos(rng)), 0.01, RandomRotation(rng),
                                               Eigen::Vector3d::Zero(), present, noise, rng);
    const VdMat3 s = vd_procrustes_covariance(0, nb.neighbours.data(), nullptr, nb.t.data(), nb.t_hat.data());
    Eigen::JacobiSVD<Eigen::Matrix3d> svd(ToEigen(s));
    const Eigen::Vector3d sv = svd.singularValues();
    reflections += ToEigen(s).determinant() < 0;
    const Eigen::Matrix3d r = PointRotation(nb);
    EXPECT_NEAR(r.determinant(), 1.0, 1e-5);
    EXPECT_LE(MaxAbs(r.transpose() * r - Eigen::Matrix3d::Identity()), 1e-5);
    // The optimum is unique when σ2 + σ3 > 0 with the reflection fix; its sensitivity to float
    // rounding of S grows like 1 / (σ2 + σ3) (rank-1 cases are checked separately).
    if (sv(1) < 1e-2 * sv(0)) continue;
    const double err = MaxAbs(r - EigenProcrustes(s));
    worst = std::max(worst, err);
    ASSERT_LE(err, 1e-5) << "singular values " << sv.transpose();
  }
  EXPECT_GT(reflections, 50);  // the reflection fix was exercised
  std::printf("noisy: worst |R - R_eigen| = %.2e (%d of 5000 with det S < 0)\n", worst, reflections);
}

TEST(ProcrustesTest, NeverReturnsAReflection) {
  std::mt19937 rng(6);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  for (int i = 0; i < 5000; ++i) {
    Eigen::Matrix3d a;
    for (int k = 0; k < 9; ++k) a(k / 3, k % 3) = uni(rng);
    if (a.determinant() > 0) a.row(0) *= -1;
    const VdMat3 s = FromEigen(a);
    const Eigen::Matrix3d r = ToEigen(vd_procrustes_rotation(s));
    ASSERT_NEAR(r.determinant(), 1.0, 1e-5) << a;
    ASSERT_LE(MaxAbs(r.transpose() * r - Eigen::Matrix3d::Identity()), 1e-5);
    const Eigen::Vector3d sv = Eigen::JacobiSVD<Eigen::Matrix3d>(ToEigen(s)).singularValues();
    if (sv(1) + sv(2) > 1e-2 * sv(0)) {
      ASSERT_LE(MaxAbs(r - EigenProcrustes(s)), 1e-4) << sv.transpose();
    }
  }
}

bool AllFinite(const Eigen::Matrix3d& m) { return m.allFinite(); }

TEST(ProcrustesTest, DegenerateInputsGiveWellDefinedRotations) {
  std::mt19937 rng(8);
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  // No neighbours at all, and S = 0 directly.
  Neighbourhood lonely = MakeNeighbourhood(Eigen::Vector3d(0, 0, 1), 0.01, RandomRotation(rng), Eigen::Vector3d::Zero(), {}, 0, rng);
  EXPECT_EQ(PointRotation(lonely), I);
  EXPECT_EQ(ToEigen(vd_procrustes_rotation(vd_mat3_zero())), I);
  // Every neighbour collapsed onto the point: nothing constrains R.
  Neighbourhood collapsed = MakeNeighbourhood(Eigen::Vector3d(0, 0, 1), 0.01, I, Eigen::Vector3d::Zero(), {0, 1, 2, 3, 4, 5}, 0, rng);
  for (auto& p : collapsed.t) p = VD_F4(0.5f, 0.5f, 0.5f, 1.f);
  EXPECT_EQ(PointRotation(collapsed), I);
  // Non-finite covariances.
  VdMat3 bad = vd_mat3_identity();
  bad.m[1] = NAN;
  EXPECT_EQ(ToEigen(vd_procrustes_rotation(bad)), I);
  bad.m[1] = -INFINITY;
  EXPECT_EQ(ToEigen(vd_procrustes_rotation(bad)), I);

  // Rank 1: one neighbour, two opposite neighbours (along z, along x). R must map the rest
  // direction onto the deformed one by the shortest arc (angle between them, no twist).
  for (int i = 0; i < 500; ++i) {
    const Eigen::Matrix3d rot = RandomRotation(rng);
    const std::vector<int> pattern = i % 3 == 0 ? std::vector<int>{2} : i % 3 == 1 ? std::vector<int>{4, 5} : std::vector<int>{0, 1};
    const Neighbourhood nb = MakeNeighbourhood(Eigen::Vector3d(0.3, -0.2, 0.8), 0.01, rot, Eigen::Vector3d::Zero(), pattern, 0, rng);
    const Eigen::Matrix3d r = PointRotation(nb);
    ASSERT_TRUE(AllFinite(r));
    EXPECT_NEAR(r.determinant(), 1.0, 1e-5);
    const int j = 1 + pattern[0];
    const Eigen::Vector3d p = (ToEigen(nb.t_hat[0]) - ToEigen(nb.t_hat[j])).normalized();
    const Eigen::Vector3d q = (ToEigen(nb.t[0]) - ToEigen(nb.t[j])).normalized();
    EXPECT_LE((r * p - q).cwiseAbs().maxCoeff(), 1e-5) << "pattern " << i % 3;
    const double arc = std::acos(std::clamp(p.dot(q), -1.0, 1.0));
    const double turned = Eigen::AngleAxisd(r).angle();
    EXPECT_NEAR(turned, arc, 1e-4) << "not the shortest arc";
  }
  // Rank 1 with the deformed direction opposite the rest one (a half turn).
  VdMat3 flip = vd_mat3_zero();
  vd_mat3_add_outer(&flip, VD_F4(0.f, 0.6f, 0.8f, 0.f), VD_F4(0.f, -0.6f, -0.8f, 0.f));
  const Eigen::Matrix3d r_flip = ToEigen(vd_procrustes_rotation(flip));
  EXPECT_NEAR(r_flip.determinant(), 1.0, 1e-5);
  EXPECT_LE((r_flip * Eigen::Vector3d(0, 0.6, 0.8) - Eigen::Vector3d(0, -0.6, -0.8)).norm(), 1e-5);

  // Near-degenerate: collinear neighbours with noise just above and below the rank-1 threshold,
  // at many scales: always a finite proper rotation mapping the line onto the deformed line.
  for (int i = 0; i < 2000; ++i) {
    const Eigen::Matrix3d rot = RandomRotation(rng);
    const double off = 0.01 * std::pow(10.0, -2.0 - 6.0 * (i % 100) / 100.0);
    Neighbourhood nb = MakeNeighbourhood(Eigen::Vector3d(0, 0, 1), 0.01, rot, Eigen::Vector3d::Zero(), {0, 1}, 0, rng);
    nb.t[1].z += float(off);
    nb.t[2].y -= float(off);
    const Eigen::Matrix3d r = PointRotation(nb);
    ASSERT_TRUE(AllFinite(r));
    ASSERT_NEAR(r.determinant(), 1.0, 1e-5);
    const Eigen::Vector3d p = rot * Eigen::Vector3d::UnitX();
    EXPECT_GE((r * Eigen::Vector3d::UnitX()).dot(p), 1.0 - 1e-3) << "offset " << off;
  }
}

// The angle in degrees of the rotation between two unit quaternions.
double AngleDeg(vd_float4 a, vd_float4 b) {
  // 4 asin(|a − b| / 2) with b's sign matched to a: exact to float rounding near 0, where
  // acos(a · b) loses half the digits.
  const double sign = double(a.x) * b.x + double(a.y) * b.y + double(a.z) * b.z + double(a.w) * b.w < 0 ? -1.0 : 1.0;
  const double dx = a.x - sign * b.x, dy = a.y - sign * b.y, dz = a.z - sign * b.z, dw = a.w - sign * b.w;
  const double chord = std::sqrt(dx * dx + dy * dy + dz * dz + dw * dw);
  return 4.0 * std::asin(std::min(chord / 2.0, 1.0)) * 180.0 / M_PI;
}

vd_float4 ToQuat(const Eigen::Matrix3d& r) {
  const Eigen::Quaterniond q(r);
  return VD_F4(float(q.x()), float(q.y()), float(q.z()), float(q.w()));
}

// The warm-started refinement (vd_procrustes_refine) against the exact optimum on noisy
// neighbourhoods with a unique optimum (σ2 ≥ 0.1 σ1), from starts 2, 10, 30 and 90 degrees off.
// The worst angle left after each number of steps is the table the default
// SolverParams::rotation_iterations is chosen from.
TEST(ProcrustesRefineTest, ConvergesToTheExactOptimumFromWarmStarts) {
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> pos(-1.0, 1.0);
  std::uniform_int_distribution<int> mask(1, 63);
  std::normal_distribution<double> g(0.0, 1.0);
  const double starts[] = {2.0, 10.0, 30.0, 90.0};
  const int kSteps = 6;
  double worst[4][kSteps + 1] = {};
  int cases = 0;
  while (cases < 2000) {
    std::vector<int> present;
    const int m = mask(rng);
    for (int d = 0; d < 6; ++d)
      if (m & (1 << d)) present.push_back(d);
    const Neighbourhood nb = MakeNeighbourhood(Eigen::Vector3d(pos(rng), pos(rng), 1.0 + pos(rng)), 0.004,
                                               RandomRotation(rng), Eigen::Vector3d::Zero(), present, 0.0005, rng);
    const VdMat3 s = vd_procrustes_covariance(0, nb.neighbours.data(), nullptr, nb.t.data(), nb.t_hat.data());
    const Eigen::Vector3d sv = Eigen::JacobiSVD<Eigen::Matrix3d>(ToEigen(s)).singularValues();
    if (sv(1) < 0.1 * sv(0)) continue;
    ++cases;
    const vd_float4 exact = ToQuat(EigenProcrustes(s));
    for (int a = 0; a < 4; ++a) {
      const Eigen::Vector3d axis = Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
      const Eigen::Matrix3d start = Eigen::AngleAxisd(starts[a] * M_PI / 180.0, axis) * EigenProcrustes(s);
      for (int steps = 0; steps <= kSteps; ++steps) {
        const vd_float4 q = vd_procrustes_refine(s, ToQuat(start), steps);
        worst[a][steps] = std::max(worst[a][steps], AngleDeg(q, exact));
      }
    }
  }
  for (int a = 0; a < 4; ++a) {
    std::printf("start %4.0f deg off: worst angle after 0..%d steps:", starts[a], kSteps);
    for (int steps = 0; steps <= kSteps; ++steps) std::printf(" %.1e", worst[a][steps]);
    std::printf("\n");
  }
  // Newton near the optimum: quadratic, ~1e-5 degrees (float rounding) after 2 steps from a few
  // degrees (the flip-flop's case); from far, the 1-rad step limit first, then the same.
  EXPECT_LE(worst[0][1], 0.01);
  EXPECT_LE(worst[0][2], 1e-4);
  EXPECT_LE(worst[1][2], 1e-4);
  EXPECT_LE(worst[2][4], 1e-4);
  EXPECT_LE(worst[3][5], 1e-4);
  for (int a = 0; a < 4; ++a) EXPECT_LT(worst[a][kSteps], worst[a][0]) << starts[a];
}

TEST(ProcrustesRefineTest, DegenerateInputsKeepOrFollowTheWarmStart) {
  std::mt19937 rng(13);
  const vd_float4 warm = ToQuat(RandomRotation(rng));
  // Nothing to fit: the warm start comes back unchanged (sign normalised to w >= 0).
  for (const VdMat3& s : {vd_mat3_zero(), [] { VdMat3 b = vd_mat3_identity(); b.m[2] = NAN; return b; }()}) {
    const vd_float4 q = vd_procrustes_refine(s, warm, 3);
    const float sign = warm.w < 0 ? -1.f : 1.f;
    EXPECT_EQ(q.x, sign * warm.x);
    EXPECT_EQ(q.w, sign * warm.w);
  }
  // Rank 1 (one neighbour): R must turn the rest direction onto the deformed one, and keep the
  // warm start's twist about it: the result is the warm start turned by the shortest arc from
  // R_warm p to q, to first order in the small misalignment.
  double worst_line = 0, worst_twist = 0;
  for (int i = 0; i < 500; ++i) {
    const Eigen::Matrix3d rot = RandomRotation(rng);
    const Neighbourhood nb = MakeNeighbourhood(Eigen::Vector3d(0.3, -0.2, 0.8), 0.01, rot, Eigen::Vector3d::Zero(), {2}, 0, rng);
    const VdMat3 s = vd_procrustes_covariance(0, nb.neighbours.data(), nullptr, nb.t.data(), nb.t_hat.data());
    std::normal_distribution<double> g(0.0, 1.0);
    const Eigen::Matrix3d start =
        Eigen::AngleAxisd(3.0 * M_PI / 180.0, Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized()) * rot;
    const Eigen::Matrix3d r = ToEigen(vd_quat_to_mat3(vd_procrustes_refine(s, ToQuat(start), 4)));
    const Eigen::Vector3d p = (ToEigen(nb.t_hat[0]) - ToEigen(nb.t_hat[3])).normalized();
    const Eigen::Vector3d q = (ToEigen(nb.t[0]) - ToEigen(nb.t[3])).normalized();
    worst_line = std::max(worst_line, (r * p - q).norm());
    const Eigen::Matrix3d shortest = Eigen::Quaterniond::FromTwoVectors(start * p, q).toRotationMatrix() * start;
    worst_twist = std::max(worst_twist, Eigen::AngleAxisd(r * shortest.transpose()).angle() * 180.0 / M_PI);
  }
  EXPECT_LE(worst_line, 1e-4);
  EXPECT_LE(worst_twist, 0.2);
  std::printf("rank 1 from 3 deg: |R p - q| <= %.1e, twist off the warm start's <= %.2f deg\n", worst_line, worst_twist);
}

TEST(QuaternionTest, RoundTripAndRotate) {
  std::mt19937 rng(9);
  std::normal_distribution<float> g(0.f, 1.f);
  for (int i = 0; i < 20000; ++i) {
    vd_float4 q = VD_F4(g(rng), g(rng), g(rng), g(rng));
    if (i % 4 == 0) q.w = 1e-4f * g(rng);  // near half turns, where w ~ 0
    const float n = std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
    // Not normalised on purpose: vd_quat_to_mat3 renormalises.
    const VdMat3 r = vd_quat_to_mat3(q);
    const Eigen::Matrix3d R = ToEigen(r);
    ASSERT_LE(MaxAbs(R.transpose() * R - Eigen::Matrix3d::Identity()), 1e-5);
    ASSERT_NEAR(R.determinant(), 1.0, 1e-5);
    const Eigen::Quaterniond ref(q.w, q.x, q.y, q.z);
    ASSERT_LE(MaxAbs(R - ref.normalized().toRotationMatrix()), 1e-5);
    const vd_float4 back = vd_mat3_to_quat(r);
    const float sign = q.w < 0 ? -1.f : 1.f;
    EXPECT_GE(back.w, 0.f);
    ASSERT_NEAR(back.x, sign * q.x / n, 1e-5f);
    ASSERT_NEAR(back.y, sign * q.y / n, 1e-5f);
    ASSERT_NEAR(back.z, sign * q.z / n, 1e-5f);
    ASSERT_NEAR(back.w, sign * q.w / n, 1e-5f);
    const vd_float4 v = VD_F4(g(rng), g(rng), g(rng), 0.f);
    const vd_float4 qn = VD_F4(q.x / n, q.y / n, q.z / n, q.w / n);
    ASSERT_LE((ToEigen(vd_quat_rotate(qn, v)) - R * ToEigen(v)).cwiseAbs().maxCoeff(), 1e-5 * (1 + ToEigen(v).norm()));
  }
  EXPECT_EQ(ToEigen(vd_quat_to_mat3(VD_F4(0.f, 0.f, 0.f, 0.f))), Eigen::Matrix3d::Identity());
  EXPECT_EQ(ToEigen(vd_quat_to_mat3(VD_F4(NAN, 0.f, 0.f, 1.f))), Eigen::Matrix3d::Identity());
  const vd_float4 id = vd_mat3_to_quat(vd_mat3_identity());
  EXPECT_EQ(id.x, 0.f);
  EXPECT_EQ(id.y, 0.f);
  EXPECT_EQ(id.z, 0.f);
  EXPECT_EQ(id.w, 1.f);
}

// Random active set: a slab of grid points with random holes; neighbours in compact indices.
struct ActiveSet {
  std::vector<int> neighbours;
  std::vector<vd_float4> t, t_hat;
};

ActiveSet RandomActiveSet(int n_target, std::mt19937& rng) {
  const int dim = static_cast<int>(std::ceil(std::cbrt(n_target / 0.8)));
  std::vector<int> index(size_t(dim) * dim * dim, -1);
  std::bernoulli_distribution keep(0.8);
  ActiveSet s;
  std::vector<int> cells;
  for (int c = 0; c < dim * dim * dim && int(cells.size()) < n_target; ++c) {
    if (!keep(rng)) continue;
    index[c] = int(cells.size());
    cells.push_back(c);
  }
  std::normal_distribution<float> g(0.f, 0.002f);
  const float h = 0.01f;
  for (int c : cells) {
    const int x = c % dim, y = (c / dim) % dim, z = c / (dim * dim);
    s.t_hat.push_back(VD_F4(h * x, h * y, h * z, 1.f));
    // A smooth bend plus noise.
    const float a = 0.3f * std::sin(0.05f * z);
    s.t.push_back(VD_F4(h * x * std::cos(a) - h * y * std::sin(a) + g(rng), h * x * std::sin(a) + h * y * std::cos(a) + g(rng),
                        h * z + g(rng), 1.f));
    const int nx[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    for (const auto& d : nx) {
      const int xx = x + d[0], yy = y + d[1], zz = z + d[2];
      const bool inside = xx >= 0 && yy >= 0 && zz >= 0 && xx < dim && yy < dim && zz < dim;
      s.neighbours.push_back(inside ? index[xx + dim * (yy + dim * zz)] : -1);
    }
  }
  return s;
}

TEST(ProcrustesTest, CpuReferenceMatchesPointFunctionAndReportsThroughput) {
  std::mt19937 rng(10);
  const ActiveSet s = RandomActiveSet(200000, rng);
  const int n = int(s.t.size());
  ASSERT_GT(n, 150000);
  std::vector<vd_float4> rot(n);
  cpu::Procrustes(s.neighbours.data(), nullptr, s.t.data(), s.t_hat.data(), n, 0, rot.data());
  for (int k = 0; k < n; k += 997) {
    const vd_float4 q =
        vd_procrustes_point(k, s.neighbours.data(), nullptr, s.t.data(), s.t_hat.data(), VD_F4(0.f, 0.f, 0.f, 1.f), 0);
    EXPECT_EQ(rot[k].x, q.x);
    EXPECT_EQ(rot[k].y, q.y);
    EXPECT_EQ(rot[k].z, q.z);
    EXPECT_EQ(rot[k].w, q.w);
  }
  double best = 1e30;
  for (int rep = 0; rep < 3; ++rep) {
    const auto t0 = std::chrono::steady_clock::now();
    cpu::Procrustes(s.neighbours.data(), nullptr, s.t.data(), s.t_hat.data(), n, 0, rot.data());
    best = std::min(best, std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  std::printf("cpu::Procrustes: %d points in %.2f ms = %.1f ms per million points (best of 3)\n", n, best,
              best * 1e6 / n);
}

}  // namespace
}  // namespace vd
