#include <cmath>
#include <cstdlib>
#include <cstring>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "cpu_ref/procrustes_ref.h"
#include "ocl/procrustes_ocl.h"
#include "test_scenes.h"

namespace vd {
namespace {

// Random active set: rest positions on a jittered grid, deformed by a smoothly varying rotation
// plus noise, and random neighbour slots (−1 with probability 0.3, else any compact index). The
// first points get hand-made degenerate neighbourhoods.
struct RandomSet {
  std::vector<int> neighbours;
  std::vector<vd_float4> t, t_hat;
};

RandomSet MakeSet(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> uni(-1.f, 1.f);
  std::uniform_int_distribution<int> pick(0, n - 1);
  std::bernoulli_distribution absent(0.3);
  std::normal_distribution<float> noise(0.f, 0.003f);
  RandomSet s;
  s.t.resize(n);
  s.t_hat.resize(n);
  s.neighbours.resize(6 * size_t(n));
  for (int k = 0; k < n; ++k) {
    const float x = 0.2f * uni(rng), y = 0.2f * uni(rng), z = 1.f + 0.2f * uni(rng);
    s.t_hat[k] = VD_F4(x, y, z, 1.f);
    const float a = 2.f * z;  // rotation about an axis that tilts with x
    const float c = std::cos(a), sn = std::sin(a);
    s.t[k] = VD_F4(c * x - sn * y + noise(rng), sn * x + c * y + 0.5f * x * x + noise(rng), z + noise(rng), 1.f);
    for (int d = 0; d < 6; ++d) s.neighbours[6 * k + d] = absent(rng) ? -1 : pick(rng);
    // At least one neighbour, so that only the hand-made points below have nothing to fit.
    if (s.neighbours[6 * k + 5] < 0) s.neighbours[6 * k + 5] = (k + 1) % n;
  }
  // k = 0: no neighbours; 1: one neighbour (rank 1); 2: neighbours collapsed onto the point;
  // 3: two neighbours on one line (rank 1); 4: only itself as neighbour (S = 0).
  for (int d = 0; d < 6; ++d) {
    s.neighbours[d] = -1;
    s.neighbours[6 + d] = d == 3 ? 10 : -1;
    s.neighbours[12 + d] = 20 + d;
    s.neighbours[18 + d] = d == 0 ? 30 : d == 1 ? 31 : -1;
    s.neighbours[24 + d] = 4;
  }
  for (int d = 0; d < 6; ++d) s.t[20 + d] = s.t[2];
  s.t_hat[31] = s.t_hat[3] + (s.t_hat[3] - s.t_hat[30]) * 2.f;
  s.t[31] = s.t[3] + (s.t[3] - s.t[30]) * 2.f;
  return s;
}

// Largest |q_a - q_b| entry over the points, q and -q taken as equal.
double WorstQuatDiff(const std::vector<vd_float4>& a, const std::vector<vd_float4>& b, int* worst_k) {
  double worst = 0;
  for (size_t k = 0; k < a.size(); ++k) {
    const float sign = a[k].x * b[k].x + a[k].y * b[k].y + a[k].z * b[k].z + a[k].w * b[k].w < 0.f ? -1.f : 1.f;
    const double err = std::max(std::max(std::fabs(a[k].x - sign * b[k].x), std::fabs(a[k].y - sign * b[k].y)),
                                std::max(std::fabs(a[k].z - sign * b[k].z), std::fabs(a[k].w - sign * b[k].w)));
    if (!(err <= worst)) {
      worst = err;
      *worst_k = int(k);
    }
  }
  return worst;
}

// The rotation step on the device and on the CPU from the same starting rotations `rot`.
struct BothRuns {
  std::vector<vd_float4> cpu, ocl;
};

BothRuns RunBoth(ocl::Context* ctx, const RandomSet& s, const std::vector<vd_float4>& rot, int iterations) {
  const int n = int(s.t.size());
  BothRuns out{rot, {}};
  // Edge weights in [0.1, 1] (adaptive rigidity), the same on both sides.
  std::vector<float> w(6 * size_t(n));
  for (size_t i = 0; i < w.size(); ++i) w[i] = 0.1f + 0.9f * float((i * 37) % 101) / 100.f;
  cpu::Procrustes(s.neighbours.data(), w.data(), s.t.data(), s.t_hat.data(), n, iterations, out.cpu.data());
  auto dn = test::ToDevice(ctx, s.neighbours);
  auto dw = test::ToDevice(ctx, w);
  auto dt = test::ToDevice(ctx, s.t);
  auto dth = test::ToDevice(ctx, s.t_hat);
  auto drot = test::ToDevice(ctx, rot);
  const Status run = ocl::FitRotations(*ctx, n, dn, dw, dt, dth, iterations, drot);
  EXPECT_TRUE(run.ok()) << run.ToString();
  out.ocl = test::FromDevice(ctx, drot, n);
  return out;
}

TEST(ProcrustesParityTest, ExactKernelMatchesCpuReferenceUpToQuaternionSign) {
  VD_REQUIRE_OCL(ctx);
  const int n = 5000;
  const RandomSet s = MakeSet(n, 42);
  // Garbage starting rotations: the exact path must not read them.
  const BothRuns r = RunBoth(ctx, s, std::vector<vd_float4>(n, VD_F4(0.3f, -2.f, 0.f, 0.1f)), 0);
  int worst_k = 0, identities = 0;
  const double worst = WorstQuatDiff(r.ocl, r.cpu, &worst_k);
  for (int k = 0; k < n; ++k) {
    const vd_float4 a = r.ocl[k], b = r.cpu[k];
    EXPECT_NEAR(a.x * a.x + a.y * a.y + a.z * a.z + a.w * a.w, 1.f, 1e-5f) << k;
    identities += b.x == 0.f && b.y == 0.f && b.z == 0.f && b.w == 1.f;
  }
  EXPECT_LE(worst, 1e-5) << "worst at k = " << worst_k << ": (" << r.ocl[worst_k].x << ", " << r.ocl[worst_k].y
                         << ", " << r.ocl[worst_k].z << ", " << r.ocl[worst_k].w << ") vs (" << r.cpu[worst_k].x
                         << ", " << r.cpu[worst_k].y << ", " << r.cpu[worst_k].z << ", " << r.cpu[worst_k].w << ")";
  // Exactly the three points with nothing to fit (no neighbours, collapsed, S = 0) are identity.
  EXPECT_EQ(identities, 3);
  for (int k : {0, 2, 4}) EXPECT_EQ(r.cpu[k].w, 1.f) << k;
  // The rank-1 points are not the identity: they turn their line onto the deformed one.
  for (int k : {1, 3}) EXPECT_LT(r.cpu[k].w, 0.9999f) << k;
  std::printf("exact: worst |q_ocl - q_cpu| over %d points: %.2e\n", n, worst);
}

TEST(ProcrustesParityTest, RefinedKernelMatchesCpuReferenceAndTheExactOptimum) {
  VD_REQUIRE_OCL(ctx);
  const int n = 5000;
  const RandomSet s = MakeSet(n, 43);
  const BothRuns exact = RunBoth(ctx, s, std::vector<vd_float4>(n, VD_F4(0.f, 0.f, 0.f, 1.f)), 0);
  // Warm starts ~6 degrees off the optimum, as a previous half-step leaves them.
  std::mt19937 rng(7);
  std::normal_distribution<float> g(0.f, 0.03f);
  std::vector<vd_float4> warm(n);
  for (int k = 0; k < n; ++k) {
    const vd_float4 turn = VD_F4(g(rng), g(rng), g(rng), 1.f);
    const vd_float4 q = vd_quat_mul(turn, exact.cpu[k]);
    warm[k] = q * (1.f / std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w));
  }
  const BothRuns r = RunBoth(ctx, s, warm, 3);
  int worst_k = 0;
  EXPECT_LE(WorstQuatDiff(r.ocl, r.cpu, &worst_k), 1e-5) << "at k = " << worst_k;
  // Points with nothing to fit keep their rotation bit for bit.
  for (int k : {0, 2, 4}) {
    EXPECT_EQ(r.ocl[k].x, warm[k].w < 0 ? -warm[k].x : warm[k].x) << k;
    EXPECT_EQ(r.cpu[k].w, std::fabs(warm[k].w)) << k;
  }
  // Where the optimum is unique and well conditioned (σ2 >= 0.1 σ1 of S), 3 steps reach it.
  std::vector<vd_float4> a, b;
  for (int k = 5; k < n; ++k) {
    VdMat3 u, v;
    vd_float4 sigma;
    vd_svd3(vd_procrustes_covariance(k, s.neighbours.data(), nullptr, s.t.data(), s.t_hat.data()), &u, &sigma, &v);
    if (sigma.y < 0.1f * sigma.x) continue;
    a.push_back(r.cpu[k]);
    b.push_back(exact.cpu[k]);
  }
  ASSERT_GT(a.size(), size_t(n / 2));
  const double off = WorstQuatDiff(a, b, &worst_k);
  EXPECT_LE(off, 2e-5) << "at the " << worst_k << "-th well-conditioned point";
  std::printf("refined (3 steps from ~6 deg): worst |q - q_exact| = %.2e\n", off);
}

// The laned refinement gives the same bits at every lane width (1, 4 and the device's own), item
// counts that fill no whole lane group included, and the CPU reference's to rounding.
TEST(ProcrustesParityTest, RefinedKernelIsTheSameAtEveryLaneWidth) {
  VD_REQUIRE_OCL(ctx);
  const int n = 1237;  // not a multiple of 4, 8 or 16
  const RandomSet s = MakeSet(n, 44);
  std::mt19937 rng(8);
  std::normal_distribution<float> g(0.f, 0.3f);
  std::vector<vd_float4> warm(n);
  for (auto& q : warm) {
    q = VD_F4(g(rng), g(rng), g(rng), 1.f);
    q = q * (1.f / std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w));
  }
  const BothRuns native = RunBoth(ctx, s, warm, 2);
  int worst_k = 0;
  const double off = WorstQuatDiff(native.ocl, native.cpu, &worst_k);
  EXPECT_LE(off, 1e-6) << "at k = " << worst_k;
  for (const char* lanes : {"1", "4"}) {
    auto other = test::ContextWithLanes(*ctx, lanes);
    ASSERT_TRUE(other.ok()) << other.status().ToString();
    ASSERT_EQ((*other)->lanes(), std::atoi(lanes));
    const BothRuns r = RunBoth(other->get(), s, warm, 2);
    for (int k = 0; k < n; ++k) {
      ASSERT_EQ(std::memcmp(&r.ocl[k], &native.ocl[k], sizeof(vd_float4)), 0)
          << "lanes " << lanes << " against " << ctx->lanes() << ", k = " << k;
    }
  }
  std::printf("refined at lanes %d, 4 and 1: identical; worst |q_ocl - q_cpu| = %.2e\n", ctx->lanes(), off);
}

TEST(ProcrustesParityTest, RecoversAGlobalRotationOnTheDevice) {
  VD_REQUIRE_OCL(ctx);
  // A 12^3 block of grid points with every 6-neighbour present where it exists, rotated rigidly:
  // every R_k is the global rotation.
  const int dim = 12, n = dim * dim * dim;
  const float h = 0.01f;
  const float qx = 0.2f, qy = -0.4f, qz = 0.1f, qw = 0.8f;
  const float qn = std::sqrt(qx * qx + qy * qy + qz * qz + qw * qw);
  const vd_float4 q = VD_F4(qx / qn, qy / qn, qz / qn, qw / qn);
  std::vector<int> neighbours(6 * n);
  std::vector<vd_float4> t(n), t_hat(n);
  for (int k = 0; k < n; ++k) {
    const int x = k % dim, y = (k / dim) % dim, z = k / (dim * dim);
    t_hat[k] = VD_F4(h * (x - dim / 2), h * (y - dim / 2), h * (z - dim / 2), 1.f);
    t[k] = vd_quat_rotate(q, t_hat[k]) + VD_F4(0.01f, 0.02f, 0.03f, 1.f);
    const int off[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    for (int d = 0; d < 6; ++d) {
      const int xx = x + off[d][0], yy = y + off[d][1], zz = z + off[d][2];
      const bool inside = xx >= 0 && yy >= 0 && zz >= 0 && xx < dim && yy < dim && zz < dim;
      neighbours[6 * k + d] = inside ? xx + dim * (yy + dim * zz) : -1;
    }
  }
  auto dn = test::ToDevice(ctx, neighbours);
  auto dt = test::ToDevice(ctx, t);
  auto dth = test::ToDevice(ctx, t_hat);
  auto dw = test::ToDevice(ctx, std::vector<float>(6 * size_t(n), 1.f));
  auto drot = ctx->Alloc<vd_float4>(n);
  ASSERT_TRUE(drot.ok());
  ASSERT_TRUE(ocl::FitRotations(*ctx, n, dn, dw, dt, dth, 0, *drot).ok());
  const auto rot = test::FromDevice(ctx, *drot, n);
  std::vector<float> expect;
  for (int k = 0; k < n; ++k) expect.insert(expect.end(), {q.x, q.y, q.z, q.w});
  EXPECT_TRUE(test::AllClose(test::Flatten(rot), expect, 1e-5f, 0.f));
}

}  // namespace
}  // namespace vd
