// The cached B^T B build of the position step (shared/solver.h: per-cell moments, then per-point
// assembly) and its product on the device against their CPU references, and both against an
// independent assembly that walks every constraint's 8 x 8 corner pairs in double precision.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <map>
#include <random>

#include "cpu_ref/cpu_ref.h"
#include "cpu_ref/solver_ref.h"
#include "ocl/solver_ocl.h"
#include "sphere_volume.h"
#include "test_scenes.h"

namespace vd {
namespace {

using test::AllClose;
using test::Flatten;
using test::FromDevice;
using test::ToDevice;

struct Problem {
  VdVolume vol{};
  cpu::ActiveSet active;
  // Constraints sorted by cell and the cells' ranges (m + 1 entries).
  std::vector<VdCorrespondence> cons;
  std::vector<vd_uint> cell_start;
};

// A sphere of 9.3 voxels; three constraints per marching-cubes vertex (the vertex and two points
// nudged inside its cell), every seventh with weight 0 (not a constraint).
Problem MakeProblem() {
  Problem p;
  const test::AnalyticVolume sphere = test::MakeSphereVolume(
      test::TestVolume(30, 28, 26, 0.01f, VD_F4(-0.15f, -0.14f, 0.87f, 1.f)), 0.002f, -0.003f, 1.001f, 0.093f);
  p.vol = sphere.vol;
  const cpu::McMesh mc = cpu::MarchingCubes(sphere.tsdf.data(), sphere.weight.data(), sphere.color.data(), p.vol);
  p.active = cpu::BuildActiveSet(mc.codes.data(), p.vol);
  std::vector<VdCorrespondence> raw;
  for (size_t i = 0; i < mc.positions_grid.size(); ++i) {
    for (int r = 0; r < 3; ++r) {
      VdCorrespondence c;
      const vd_float4 g = mc.positions_grid[i];
      const float cx = std::floor(g.x), cy = std::floor(g.y), cz = std::floor(g.z);
      const float s = 0.37f * float(r);
      c.canonical = VD_F4(cx + std::fmod(g.x - cx + s, 1.f), cy + std::fmod(g.y - cy + 0.5f * s, 1.f),
                          cz + std::fmod(g.z - cz + 0.25f * s, 1.f), (raw.size() % 7 == 0) ? 0.f : 0.2f + 0.15f * float(i % 5));
      c.normal = mc.normals[i];
      c.normal.w = 0.f;
      const float shift = 0.002f + 0.001f * std::sin(float(i));
      c.target = VD_F4(p.vol.origin.x + 0.01f * g.x, p.vol.origin.y + 0.01f * g.y, p.vol.origin.z + 0.01f * g.z, 0.f) +
                 c.normal * shift;
      c.target.w = 0.f;
      raw.push_back(c);
    }
  }
  // Counting sort by cell, as the device's count/scan/scatter does (order within a cell aside).
  const int m = int(p.active.list.size());
  std::vector<std::vector<VdCorrespondence>> by_cell(m);
  for (const auto& c : raw) {
    const int kc = vd_constraint_cell(c, p.active.compact.data(), p.vol);
    if (kc >= 0) by_cell[kc].push_back(c);
  }
  p.cell_start.assign(m + 1, 0u);
  for (int k = 0; k < m; ++k) {
    p.cell_start[k + 1] = p.cell_start[k] + vd_uint(by_cell[k].size());
    p.cons.insert(p.cons.end(), by_cell[k].begin(), by_cell[k].end());
  }
  return p;
}

// Independent: every constraint adds w_d w alpha_o alpha_q n n^T to the block (idx_o, idx_q)
// and w_d w alpha_o (n . p) n to b_o.
struct IndependentBtb {
  std::map<std::pair<int, int>, Eigen::Matrix3d> blocks;
  std::vector<Eigen::Vector3d> rhs;
};
IndependentBtb AssembleIndependently(const Problem& p, VdSolverWeights w) {
  const int m = int(p.active.list.size());
  IndependentBtb ref;
  ref.rhs.assign(m, Eigen::Vector3d::Zero());
  for (const auto& c : p.cons) {
    int idx[8];
    float al[8];
    EXPECT_TRUE(vd_cell_corners(c.canonical, p.active.compact.data(), p.vol, idx, al));
    const Eigen::Vector3d n(c.normal.x, c.normal.y, c.normal.z), t(c.target.x, c.target.y, c.target.z);
    const double f[3] = {c.canonical.x - std::floor(c.canonical.x), c.canonical.y - std::floor(c.canonical.y),
                         c.canonical.z - std::floor(c.canonical.z)};
    for (int o = 0; o < 8; ++o) {
      const double ao = (o & 1 ? f[0] : 1 - f[0]) * (o & 2 ? f[1] : 1 - f[1]) * (o & 4 ? f[2] : 1 - f[2]);
      ref.rhs[idx[o]] += double(w.w_dense) * c.canonical.w * ao * n.dot(t) * n;
      for (int q = 0; q < 8; ++q) {
        const double aq = (q & 1 ? f[0] : 1 - f[0]) * (q & 2 ? f[1] : 1 - f[1]) * (q & 4 ? f[2] : 1 - f[2]);
        auto it = ref.blocks.try_emplace({idx[o], idx[q]}, Eigen::Matrix3d::Zero()).first;
        it->second += double(w.w_dense) * c.canonical.w * ao * aq * n * n.transpose();
      }
    }
  }
  return ref;
}

// Symmetric ARAP edge weights in [0.2, 1] (adaptive rigidity): w_kj = w_jk, from the pair.
std::vector<float> EdgeWeights(const Problem& p) {
  const int m = int(p.active.list.size());
  std::vector<float> w(6 * size_t(m), 0.f);
  for (int k = 0; k < m; ++k)
    for (int j = 0; j < 6; ++j) {
      const int nb = p.active.neighbours[6 * k + j];
      if (nb < 0) continue;
      const unsigned h = unsigned(std::min(k, nb)) * 2654435761u ^ unsigned(std::max(k, nb)) * 40503u;
      w[6 * size_t(k) + j] = 0.2f + 0.8f * float(h % 1000u) / 999.f;
    }
  return w;
}

// The cached block of point k at offset o (0..26); zero outside M.
Eigen::Matrix3d StoredBlock(const std::vector<float>& blocks, const std::vector<int>& nbr, int k, int o) {
  if (nbr[VD_BTB_BLOCKS * k + o] < 0) return Eigen::Matrix3d::Zero();
  const float* b = &blocks[size_t(VD_BTB_FLOATS) * k + 6 * o];
  Eigen::Matrix3d got;
  got << b[0], b[1], b[2], b[1], b[3], b[4], b[2], b[4], b[5];
  return got;
}

TEST(SolverParityTest, CachedBtbBuildMatchesCpuAndAnIndependentAssembly) {
  VD_REQUIRE_OCL(ctx);
  const Problem p = MakeProblem();
  const int m = int(p.active.list.size());
  ASSERT_GT(m, 2000);
  ASSERT_GT(p.cons.size(), 2000u);
  VdSolverWeights w{};
  w.w_dense = 1.3f;
  w.w_reg = 2.f;
  w.damping = 2e-4f;
  w.weighted_edges = 1;  // the edge weights below are not all 1

  // Device.
  auto d_list = ToDevice(ctx, p.active.list);
  auto d_compact = ToDevice(ctx, p.active.compact);
  auto d_nb = ToDevice(ctx, p.active.neighbours);
  const std::vector<float> ew = EdgeWeights(p);
  auto d_ew = ToDevice(ctx, ew);
  auto d_cons = ToDevice(ctx, p.cons);
  auto d_start = ToDevice(ctx, p.cell_start);
  auto d_moments = ctx->Alloc<float>(size_t(VD_CELL_MOMENT_FLOATS) * m);
  auto d_blocks = ctx->Alloc<float>(size_t(VD_BTB_FLOATS) * m);
  auto d_nbr = ctx->Alloc<int32_t>(size_t(VD_BTB_BLOCKS) * m);
  auto d_rhs = ctx->Alloc<vd_float4>(m);
  auto d_inv = ctx->Alloc<VdMat3>(m);
  ASSERT_TRUE(d_moments.ok() && d_blocks.ok() && d_nbr.ok() && d_rhs.ok() && d_inv.ok());
  ASSERT_TRUE(ocl::BuildBtb(*ctx, m, d_list, d_compact, p.vol, d_nb, d_ew, d_cons, d_start, w, *d_moments, *d_blocks,
                            *d_nbr, *d_rhs, *d_inv)
                  .ok());
  const auto blocks = FromDevice(ctx, *d_blocks, size_t(VD_BTB_FLOATS) * m);
  const auto nbr = FromDevice(ctx, *d_nbr, size_t(VD_BTB_BLOCKS) * m);
  const auto rhs = FromDevice(ctx, *d_rhs, m);
  const auto inv = FromDevice(ctx, *d_inv, m);

  // CPU reference: the same per-item functions.
  std::vector<float> moments(size_t(VD_CELL_MOMENT_FLOATS) * m, 0.f), blocks_ref(size_t(VD_BTB_FLOATS) * m);
  std::vector<int> nbr_ref(size_t(VD_BTB_BLOCKS) * m);
  std::vector<vd_float4> rhs_ref(m);
  std::vector<VdMat3> inv_ref(m);
  cpu::CellMoments(p.active.list.data(), p.vol, p.cons.data(), p.cell_start.data(), m, moments.data());
  cpu::BtbAssemble(p.active.list.data(), p.active.compact.data(), p.vol, p.active.neighbours.data(), ew.data(),
                   moments.data(), w, nullptr, m, blocks_ref.data(), nbr_ref.data(), rhs_ref.data(), inv_ref.data());
  EXPECT_EQ(nbr, nbr_ref);
  EXPECT_TRUE(AllClose(blocks, blocks_ref, 1e-6f, 1e-5f));
  EXPECT_TRUE(AllClose(Flatten(rhs), Flatten(rhs_ref), 1e-7f, 1e-5f));
  std::vector<float> inv_f, inv_ref_f;
  for (int k = 0; k < m; ++k)
    for (int a = 0; a < 9; ++a) {
      inv_f.push_back(inv[k].m[a]);
      inv_ref_f.push_back(inv_ref[k].m[a]);
    }
  EXPECT_TRUE(AllClose(inv_f, inv_ref_f, 1e-6f, 1e-5f));

  const IndependentBtb ref = AssembleIndependently(p, w);
  double worst_block = 0, largest_block = 0, worst_rhs = 0, worst_inv = 0;
  size_t nonzero_blocks = 0;
  for (int k = 0; k < m; ++k) {
    double degree = 0;
    for (int j = 0; j < 6; ++j)
      if (p.active.neighbours[6 * k + j] >= 0) degree += ew[6 * size_t(k) + j];
    for (int o = 0; o < VD_BTB_BLOCKS; ++o) {
      const int j = nbr[VD_BTB_BLOCKS * k + o];
      const Eigen::Matrix3d got = StoredBlock(blocks, nbr, k, o);
      Eigen::Matrix3d want = Eigen::Matrix3d::Zero();
      if (j >= 0) {
        auto it = ref.blocks.find({k, j});
        if (it != ref.blocks.end()) want = it->second;
      }
      nonzero_blocks += want.norm() > 0;
      // The ARAP Laplacian and the damping, folded into the diagonal block and the face blocks
      // (neighbour directions -x, +x, -y, +y, -z, +z).
      if (o == 13) want += (2.0 * w.w_reg * degree + w.damping) * Eigen::Matrix3d::Identity();
      for (int f = 0; f < 6; ++f) {
        const int face = 13 + (f & 1 ? 1 : -1) * (f < 2 ? 1 : f < 4 ? 3 : 9);
        if (face == o && p.active.neighbours[6 * k + f] >= 0)
          want -= 2.0 * w.w_reg * ew[6 * size_t(k) + f] * Eigen::Matrix3d::Identity();
      }
      worst_block = std::max(worst_block, (got - want).cwiseAbs().maxCoeff());
      largest_block = std::max(largest_block, want.cwiseAbs().maxCoeff());
      if (o == 13) {
        const Eigen::Matrix3d want_inv = want.inverse();
        Eigen::Matrix3d got_inv;
        for (int a = 0; a < 9; ++a) got_inv(a / 3, a % 3) = inv[k].m[a];
        worst_inv = std::max(worst_inv, (got_inv - want_inv).cwiseAbs().maxCoeff() / want_inv.cwiseAbs().maxCoeff());
      }
    }
    const Eigen::Vector3d got_rhs(rhs[k].x, rhs[k].y, rhs[k].z);
    worst_rhs = std::max(worst_rhs, (got_rhs - ref.rhs[k]).cwiseAbs().maxCoeff());
  }
  std::printf("%d points, %zu constraints, %zu non-zero blocks; worst block error %.3g (largest %.3g), rhs %.3g, "
              "relative inverse diagonal %.3g\n",
              m, p.cons.size(), nonzero_blocks, worst_block, largest_block, worst_rhs, worst_inv);
  EXPECT_GT(nonzero_blocks, size_t(8) * m);
  EXPECT_LT(worst_block, 2e-6 * largest_block);
  EXPECT_LT(worst_rhs, 1e-6);
  EXPECT_LT(worst_inv, 1e-5);
}

// The product A d with the cached blocks on the device, on the CPU, and in double precision from the independent blocks.
TEST(SolverParityTest, CachedApplyMatchesCpuAndTheIndependentProduct) {
  VD_REQUIRE_OCL(ctx);
  const Problem p = MakeProblem();
  const int m = int(p.active.list.size());
  VdSolverWeights w{};
  w.w_dense = 0.8f;
  w.w_reg = 1.5f;
  w.damping = 3e-3f;
  w.weighted_edges = 1;
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> uni(-1.f, 1.f);
  std::vector<vd_float4> d(m);
  for (auto& v : d) v = VD_F4(uni(rng), uni(rng), uni(rng), 7.f);  // w is not part of the product

  auto d_list = ToDevice(ctx, p.active.list);
  auto d_compact = ToDevice(ctx, p.active.compact);
  auto d_nb = ToDevice(ctx, p.active.neighbours);
  auto d_cons = ToDevice(ctx, p.cons);
  auto d_start = ToDevice(ctx, p.cell_start);
  auto d_d = ToDevice(ctx, d);
  const std::vector<float> ew = EdgeWeights(p);
  auto d_ew = ToDevice(ctx, ew);
  auto d_moments = ctx->Alloc<float>(size_t(VD_CELL_MOMENT_FLOATS) * m);
  auto d_blocks = ctx->Alloc<float>(size_t(VD_BTB_FLOATS) * m);
  auto d_nbr = ctx->Alloc<int32_t>(size_t(VD_BTB_BLOCKS) * m);
  auto d_rhs = ctx->Alloc<vd_float4>(m);
  auto d_inv = ctx->Alloc<VdMat3>(m);
  auto d_q = ctx->Alloc<vd_float4>(m);
  ASSERT_TRUE(d_moments.ok() && d_blocks.ok() && d_nbr.ok() && d_rhs.ok() && d_inv.ok() && d_q.ok());
  ASSERT_TRUE(ocl::BuildBtb(*ctx, m, d_list, d_compact, p.vol, d_nb, d_ew, d_cons, d_start, w, *d_moments, *d_blocks,
                            *d_nbr, *d_rhs, *d_inv)
                  .ok());
  ASSERT_TRUE(ocl::ApplySystemCached(*ctx, m, *d_blocks, *d_nbr, d_d, *d_q).ok());
  const auto q = FromDevice(ctx, *d_q, m);
  const auto blocks = FromDevice(ctx, *d_blocks, size_t(VD_BTB_FLOATS) * m);
  const auto nbr = FromDevice(ctx, *d_nbr, size_t(VD_BTB_BLOCKS) * m);

  std::vector<vd_float4> q_cpu(m);
  cpu::ApplySystemCached(blocks.data(), nbr.data(), d.data(), m, q_cpu.data());
  EXPECT_TRUE(AllClose(Flatten(q), Flatten(q_cpu), 1e-6f, 1e-5f));

  const IndependentBtb ref = AssembleIndependently(p, w);
  std::vector<Eigen::Vector3d> want(m, Eigen::Vector3d::Zero());
  auto vec = [&](int k) { return Eigen::Vector3d(d[k].x, d[k].y, d[k].z); };
  for (const auto& [pair, block] : ref.blocks) want[pair.first] += block * vec(pair.second);
  double worst = 0, largest = 0;
  for (int k = 0; k < m; ++k) {
    want[k] += double(w.damping) * vec(k);
    for (int j = 0; j < 6; ++j) {
      const int nb = p.active.neighbours[6 * k + j];
      if (nb >= 0) want[k] += 2.0 * w.w_reg * ew[6 * size_t(k) + j] * (vec(k) - vec(nb));
    }
    const Eigen::Vector3d got(q[k].x, q[k].y, q[k].z);
    worst = std::max(worst, (got - want[k]).cwiseAbs().maxCoeff());
    largest = std::max(largest, want[k].cwiseAbs().maxCoeff());
    EXPECT_EQ(q[k].w, 0.f);
  }
  std::printf("%d points: worst product error %.3g (largest entry %.3g)\n", m, worst, largest);
  EXPECT_GT(largest, 1.0);
  EXPECT_LT(worst, 2e-5 * largest);
}

// One PCG iteration with its scalars on the device (dot partials, vd_pcg_scalars, update,
// direction) against the same iteration in double precision on the host.
// Adaptive rigidity's edge weights (vd_arap_edge_weights_kernel) on the device and the CPU: 1 for
// a rigid motion of the whole set; for a set folded by 40 degrees about the plane x = 0, low on
// the edges that straddle the fold, 1 away from it, never under the floor, and the same from
// either end of an edge.
TEST(SolverParityTest, ArapEdgeWeightsGiveWayAtAFoldOnly) {
  VD_REQUIRE_OCL(ctx);
  const Problem p = MakeProblem();
  const int m = int(p.active.list.size());
  const auto& nb = p.active.neighbours;
  std::vector<vd_float4> rest(m);
  for (int k = 0; k < m; ++k) {
    int x, y, z;
    vd_grid_coords(p.active.list[k], p.vol, &x, &y, &z);
    rest[k] = vd_rest_position(p.vol, x, y, z);
  }
  auto rotate_y = [](float deg, vd_float4 v) {
    const float a = deg * float(M_PI) / 180.f;
    return VD_F4(std::cos(a) * v.x + std::sin(a) * v.z, v.y, -std::sin(a) * v.x + std::cos(a) * v.z, v.w);
  };
  auto quat_y = [](float deg) {
    const float a = 0.5f * deg * float(M_PI) / 180.f;
    return VD_F4(0.f, std::sin(a), 0.f, std::cos(a));
  };
  const float voxel = p.vol.voxel_size, scale2 = (0.3f * voxel) * (0.3f * voxel), floor_w = 0.1f;
  auto run = [&](const std::vector<vd_float4>& x, const std::vector<vd_float4>& rot) {
    std::vector<float> w_cpu(6 * size_t(m), -1.f);
    cpu::ArapEdgeWeights(nb.data(), x.data(), rot.data(), rest.data(), m, scale2, floor_w, w_cpu.data());
    auto d_w = ctx->Alloc<float>(6 * size_t(m));
    EXPECT_TRUE(d_w.ok());
    EXPECT_TRUE(ocl::ArapEdgeWeights(*ctx, m, ToDevice(ctx, nb), ToDevice(ctx, x), ToDevice(ctx, rot),
                                     ToDevice(ctx, rest), scale2, floor_w, *d_w)
                    .ok());
    EXPECT_TRUE(AllClose(FromDevice(ctx, *d_w, 6 * size_t(m)), w_cpu, 1e-6f, 1e-5f));
    return w_cpu;
  };
  // Rigid: 25 degrees about y and 3 cm along x.
  std::vector<vd_float4> x(m), rot(m, quat_y(25.f));
  for (int k = 0; k < m; ++k) x[k] = rotate_y(25.f, rest[k]) + VD_F4(0.03f, 0.f, 0.f, 0.f);
  const std::vector<float> w_rigid = run(x, rot);
  for (int k = 0; k < m; ++k)
    for (int j = 0; j < 6; ++j)
      if (nb[6 * k + j] >= 0) ASSERT_NEAR(w_rigid[6 * k + j], 1.f, 1e-4f) << k;
  // Folded: the half x > 0 turned by 40 degrees about the y axis through the sphere's centre.
  const vd_float4 c = VD_F4(0.002f, 0.f, 1.001f, 0.f);
  for (int k = 0; k < m; ++k) {
    const bool turned = rest[k].x > c.x;
    x[k] = turned ? rotate_y(40.f, rest[k] - c) + c : rest[k];
    x[k].w = 1.f;
    rot[k] = turned ? quat_y(40.f) : quat_y(0.f);
  }
  const std::vector<float> w = run(x, rot);
  int straddle = 0, away = 0;
  for (int k = 0; k < m; ++k)
    for (int j = 0; j < 6; ++j) {
      const int n = nb[6 * k + j];
      if (n < 0) {
        EXPECT_EQ(w[6 * k + j], 0.f);
        continue;
      }
      // The same edge seen from n: the opposite direction (directions come in +/- pairs).
      EXPECT_EQ(nb[6 * n + (j ^ 1)], k);
      EXPECT_FLOAT_EQ(w[6 * n + (j ^ 1)], w[6 * k + j]);
      EXPECT_GE(w[6 * k + j], floor_w);
      if ((rest[k].x > c.x) != (rest[n].x > c.x)) {
        EXPECT_LT(w[6 * k + j], 0.5f) << "edge across the fold";
        ++straddle;
      } else if (std::fabs(rest[k].x - c.x) > 1.5f * voxel && std::fabs(rest[n].x - c.x) > 1.5f * voxel) {
        EXPECT_NEAR(w[6 * k + j], 1.f, 1e-4f);
        ++away;
      }
    }
  EXPECT_GT(straddle, 50);
  EXPECT_GT(away, 10 * straddle);
}

TEST(SolverParityTest, PcgScalarsUpdateAndDirectionMatchAHostIteration) {
  VD_REQUIRE_OCL(ctx);
  const int n = 5000, chunk = 256, groups = (n + chunk - 1) / chunk;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> uni(-1.f, 1.f);
  std::vector<vd_float4> b(n), x(n), r(n), p(n), q(n);
  std::vector<VdMat3> dinv(n);
  for (int k = 0; k < n; ++k) {
    b[k] = VD_F4(uni(rng), uni(rng), uni(rng), 0.f);
    x[k] = VD_F4(uni(rng), uni(rng), uni(rng), 0.25f);
    r[k] = VD_F4(uni(rng), uni(rng), uni(rng), 0.f);
    p[k] = VD_F4(uni(rng), uni(rng), uni(rng), 0.f);
    q[k] = p[k] * 2.f + VD_F4(0.1f * uni(rng), 0.1f * uni(rng), 0.1f * uni(rng), 0.f);
    for (int a = 0; a < 9; ++a) dinv[k].m[a] = (a % 4 == 0 ? 0.5f : 0.f) + 0.05f * uni(rng);
  }
  std::vector<vd_float4> z(n);
  for (int k = 0; k < n; ++k) z[k] = vd_mat3_apply(dinv[k], r[k]);
  const float tol = 0.1f;
  auto d_b = ToDevice(ctx, b), d_x = ToDevice(ctx, x), d_r = ToDevice(ctx, r), d_p = ToDevice(ctx, p),
       d_q = ToDevice(ctx, q), d_z = ToDevice(ctx, z);
  auto d_inv = ToDevice(ctx, dinv);
  auto d_part = ctx->Alloc<float>(2 * groups);
  auto d_scal = ctx->Alloc<float>(VD_PCG_SCALARS);
  ASSERT_TRUE(d_part.ok() && d_scal.ok());
  ASSERT_TRUE(ocl::DotPartials(*ctx, groups, d_b, d_b, n, chunk, *d_part).ok());
  ASSERT_TRUE(ocl::PcgScalars(*ctx, *d_part, groups, VD_PCG_SET_STOP, tol, *d_scal).ok());
  ASSERT_TRUE(ocl::DotPartials2(*ctx, groups, d_r, d_z, d_r, n, chunk, *d_part).ok());
  ASSERT_TRUE(ocl::PcgScalars(*ctx, *d_part, groups, VD_PCG_SET_RZ_RR, tol, *d_scal).ok());
  const auto s0 = FromDevice(ctx, *d_scal, VD_PCG_SCALARS);
  ASSERT_TRUE(ocl::DotPartials(*ctx, groups, d_p, d_q, n, chunk, *d_part).ok());
  ASSERT_TRUE(ocl::PcgScalars(*ctx, *d_part, groups, VD_PCG_SET_ALPHA, tol, *d_scal).ok());
  ASSERT_TRUE(ocl::PcgUpdate(*ctx, n, *d_scal, d_p, d_q, d_inv, d_x, d_r, d_z).ok());
  ASSERT_TRUE(ocl::DotPartials2(*ctx, groups, d_r, d_z, d_r, n, chunk, *d_part).ok());
  ASSERT_TRUE(ocl::PcgScalars(*ctx, *d_part, groups, VD_PCG_SET_BETA, tol, *d_scal).ok());
  ASSERT_TRUE(ocl::PcgDirection(*ctx, n, *d_scal, d_z, d_p).ok());
  const auto s1 = FromDevice(ctx, *d_scal, VD_PCG_SCALARS);

  // Host, double precision.
  auto dot = [&](const std::vector<vd_float4>& u, const std::vector<vd_float4>& v) {
    double acc = 0;
    for (int k = 0; k < n; ++k) acc += double(u[k].x) * v[k].x + double(u[k].y) * v[k].y + double(u[k].z) * v[k].z;
    return acc;
  };
  const double bb = dot(b, b), rz = dot(r, z), rr = dot(r, r), pq = dot(p, q);
  EXPECT_NEAR(s0[VD_PCG_STOP], tol * tol * bb, 1e-5 * tol * tol * bb);
  EXPECT_NEAR(s0[VD_PCG_RZ], rz, 1e-5 * std::fabs(rz) + 1e-6);
  EXPECT_NEAR(s0[VD_PCG_RR], rr, 1e-5 * rr);
  EXPECT_EQ(s0[VD_PCG_CONVERGED], 0.f);
  const double alpha = rz / pq;
  std::vector<vd_float4> x1(n), r1(n), z1(n), p1(n);
  for (int k = 0; k < n; ++k) {
    x1[k] = x[k] + p[k] * float(alpha);
    x1[k].w = x[k].w;
    r1[k] = r[k] - q[k] * float(alpha);
    r1[k].w = 0.f;
    z1[k] = vd_mat3_apply(dinv[k], r1[k]);
  }
  const double rz1 = dot(r1, z1), rr1 = dot(r1, r1), beta = rz1 / rz;
  for (int k = 0; k < n; ++k) {
    p1[k] = z1[k] + p[k] * float(beta);
    p1[k].w = 0.f;
  }
  EXPECT_NEAR(s1[VD_PCG_ALPHA], alpha, 1e-5 * std::fabs(alpha));
  EXPECT_NEAR(s1[VD_PCG_BETA], beta, 1e-4 * std::fabs(beta));
  EXPECT_NEAR(s1[VD_PCG_RR], rr1, 1e-4 * rr1);
  // rr1 is above tol^2 b.b here (checked), so the iteration has not converged.
  ASSERT_GT(rr1, tol * tol * bb);
  EXPECT_EQ(s1[VD_PCG_CONVERGED], 0.f);
  EXPECT_TRUE(AllClose(Flatten(FromDevice(ctx, d_x, n)), Flatten(x1), 1e-6f, 1e-5f));
  EXPECT_TRUE(AllClose(Flatten(FromDevice(ctx, d_r, n)), Flatten(r1), 1e-6f, 1e-5f));
  EXPECT_TRUE(AllClose(Flatten(FromDevice(ctx, d_z, n)), Flatten(z1), 1e-6f, 1e-5f));
  EXPECT_TRUE(AllClose(Flatten(FromDevice(ctx, d_p, n)), Flatten(p1), 1e-5f, 1e-4f));

  // Converged: alpha and beta are 0 from then on and x stays.
  ASSERT_TRUE(ocl::PcgScalars(*ctx, *d_part, groups, VD_PCG_SET_STOP, 10.f, *d_scal).ok());
  ASSERT_TRUE(ocl::PcgScalars(*ctx, *d_part, groups, VD_PCG_SET_RZ_RR, 10.f, *d_scal).ok());
  ASSERT_TRUE(ocl::DotPartials(*ctx, groups, d_p, d_q, n, chunk, *d_part).ok());
  ASSERT_TRUE(ocl::PcgScalars(*ctx, *d_part, groups, VD_PCG_SET_ALPHA, 10.f, *d_scal).ok());
  const auto s2 = FromDevice(ctx, *d_scal, VD_PCG_SCALARS);
  EXPECT_EQ(s2[VD_PCG_CONVERGED], 1.f);
  EXPECT_EQ(s2[VD_PCG_ALPHA], 0.f);
}

}  // namespace
}  // namespace vd
