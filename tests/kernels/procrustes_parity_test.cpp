#include <cmath>
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

TEST(ProcrustesParityTest, KernelMatchesCpuReferenceUpToQuaternionSign) {
  VD_REQUIRE_OCL(ctx);
  const int n = 5000;
  const RandomSet s = MakeSet(n, 42);
  std::vector<vd_float4> cpu_rot(n);
  cpu::Procrustes(s.neighbours.data(), s.t.data(), s.t_hat.data(), n, cpu_rot.data());

  auto dn = test::ToDevice(ctx, s.neighbours);
  auto dt = test::ToDevice(ctx, s.t);
  auto dth = test::ToDevice(ctx, s.t_hat);
  auto drot = ctx->Alloc<vd_float4>(n);
  ASSERT_TRUE(drot.ok()) << drot.status().ToString();
  Status run = ocl::kProcrustes(*ctx, n, dn, dt, dth, *drot);
  ASSERT_TRUE(run.ok()) << run.ToString();
  const std::vector<vd_float4> ocl_rot = test::FromDevice(ctx, *drot, n);

  double worst = 0;
  int worst_k = 0, identities = 0;
  for (int k = 0; k < n; ++k) {
    const vd_float4 a = ocl_rot[k], b = cpu_rot[k];
    const float sign = a.x * b.x + a.y * b.y + a.z * b.z + a.w * b.w < 0.f ? -1.f : 1.f;
    const double err = std::max(std::max(std::fabs(a.x - sign * b.x), std::fabs(a.y - sign * b.y)),
                                std::max(std::fabs(a.z - sign * b.z), std::fabs(a.w - sign * b.w)));
    if (!(err <= worst)) {
      worst = err;
      worst_k = k;
    }
    EXPECT_NEAR(a.x * a.x + a.y * a.y + a.z * a.z + a.w * a.w, 1.f, 1e-5f) << k;
    identities += b.x == 0.f && b.y == 0.f && b.z == 0.f && b.w == 1.f;
  }
  EXPECT_LE(worst, 1e-5) << "worst at k = " << worst_k << ": (" << ocl_rot[worst_k].x << ", " << ocl_rot[worst_k].y
                         << ", " << ocl_rot[worst_k].z << ", " << ocl_rot[worst_k].w << ") vs (" << cpu_rot[worst_k].x
                         << ", " << cpu_rot[worst_k].y << ", " << cpu_rot[worst_k].z << ", " << cpu_rot[worst_k].w << ")";
  // Exactly the three points with nothing to fit (no neighbours, collapsed, S = 0) are identity.
  EXPECT_EQ(identities, 3);
  for (int k : {0, 2, 4}) EXPECT_EQ(cpu_rot[k].w, 1.f) << k;
  // The rank-1 points are not the identity: they turn their line onto the deformed one.
  for (int k : {1, 3}) EXPECT_LT(cpu_rot[k].w, 0.9999f) << k;
  std::printf("worst |q_ocl - q_cpu| over %d points: %.2e\n", n, worst);
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
  auto drot = ctx->Alloc<vd_float4>(n);
  ASSERT_TRUE(drot.ok());
  ASSERT_TRUE(ocl::kProcrustes(*ctx, n, dn, dt, dth, *drot).ok());
  const auto rot = test::FromDevice(ctx, *drot, n);
  std::vector<float> expect;
  for (int k = 0; k < n; ++k) expect.insert(expect.end(), {q.x, q.y, q.z, q.w});
  EXPECT_TRUE(test::AllClose(test::Flatten(rot), expect, 1e-5f, 0.f));
}

}  // namespace
}  // namespace vd
