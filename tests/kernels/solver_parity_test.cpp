// The cached B^T B build of the position step (shared/solver.h: per-cell moments, then per-point
// assembly) and its product on the device against their CPU references, and both against an
// independent assembly that walks every constraint's 8 x 8 corner pairs in double precision.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <random>
#include <tuple>

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
  // The constraints as they came, and each one's cell (-1: none).
  std::vector<VdCorrespondence> raw;
  std::vector<int> cell_of;
  // Constraints sorted by cell (cpu::SortConstraints), each one's cell, and the cells' ranges (m + 1
  // entries).
  std::vector<VdCorrespondence> cons;
  std::vector<int> cons_cell;
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
  // A crowded cell (more than vd_sort_indices' insertion sort takes): 40 more constraints in the
  // cell of the first vertex's first one that has a cell, each a little off the last.
  for (size_t i = 0; i < raw.size(); ++i) {
    if (vd_constraint_cell(raw[i], p.active.compact.data(), p.vol) < 0) continue;
    for (int r = 1; r <= 40; ++r) {
      VdCorrespondence c = raw[i];
      c.target.z += 1e-4f * float(r);
      c.canonical.w = 0.1f + 0.01f * float(r);
      raw.push_back(c);
    }
    break;
  }
  const int m = int(p.active.list.size());
  p.cell_of.resize(raw.size());
  for (size_t i = 0; i < raw.size(); ++i) p.cell_of[i] = vd_constraint_cell(raw[i], p.active.compact.data(), p.vol);
  cpu::SortConstraints(raw.data(), p.cell_of.data(), int(raw.size()), m, &p.cell_start, &p.cons, &p.cons_cell);
  p.raw = std::move(raw);
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

// Weights of the product and PCG tests (edge weights not all 1).
VdSolverWeights ProductWeights() {
  VdSolverWeights w{};
  w.w_dense = 0.8f;
  w.w_reg = 0.5f;
  w.damping = 0.01f;
  w.weighted_edges = 1;
  return w;
}

// The cached system of problem p with edge weights ew, built on the device (ocl::BuildBtb).
struct DeviceSystem {
  ocl::Buffer<float> blocks;
  ocl::Buffer<int32_t> nbr;
  ocl::Buffer<vd_float4> rhs;
  ocl::Buffer<VdMat3> inv;
};
StatusOr<DeviceSystem> BuildOnDevice(ocl::Context* ctx, const Problem& p, const std::vector<float>& ew,
                                     VdSolverWeights w) {
  const size_t m = p.active.list.size();
  DeviceActiveSet a;
  a.count = m;
  a.list = ToDevice(ctx, p.active.list);
  a.compact = ToDevice(ctx, p.active.compact);
  a.neighbours = ToDevice(ctx, p.active.neighbours);
  auto d_ew = ToDevice(ctx, ew);
  auto d_cons = ToDevice(ctx, p.cons);
  auto d_start = ToDevice(ctx, p.cell_start);
  DeviceSystem sys;
  VD_ASSIGN_OR_RETURN(auto moments, ctx->Alloc<float>(size_t(VD_CELL_MOMENT_FLOATS) * m));
  VD_ASSIGN_OR_RETURN(sys.blocks, ctx->Alloc<float>(size_t(VD_BTB_FLOATS) * m));
  VD_ASSIGN_OR_RETURN(sys.nbr, ctx->Alloc<int32_t>(size_t(VD_BTB_BLOCKS) * m));
  VD_ASSIGN_OR_RETURN(sys.rhs, ctx->Alloc<vd_float4>(m));
  VD_ASSIGN_OR_RETURN(sys.inv, ctx->Alloc<VdMat3>(m));
  VD_RETURN_IF_ERROR(ocl::BuildBtb(*ctx, DeviceLattice::Dense(p.vol), a, d_ew, d_cons, d_start, w, moments, sys.blocks,
                                   sys.nbr, sys.rhs, sys.inv));
  return sys;
}

// vd_sort_indices against std::sort over the sizes both of its branches take, repeats included.
// An unsolved frame's count (vd_solver_count_state): the listed points' w grows by one on the
// device as in the CPU reference, their positions and every unlisted point stay.
TEST(SolverParityTest, CountOptimisationCountsOnlyTheListedPoints) {
  VD_REQUIRE_OCL(ctx);
  const int n = 1000;
  std::vector<vd_float4> def_pos(n);
  for (int i = 0; i < n; ++i) def_pos[i] = VD_F4(0.001f * i, -0.002f * i, 0.5f, float(i % 7));
  std::vector<int32_t> list;
  for (int i = 3; i < n; i += 3) list.push_back(i);
  auto d_list = ToDevice(ctx, list);
  auto d_pos = ToDevice(ctx, def_pos);
  ASSERT_TRUE(ocl::CountOptimisation(*ctx, list.size(), d_list, d_pos).ok());
  std::vector<vd_float4> want = def_pos;
  cpu::CountOptimisation(list.data(), int(list.size()), want.data());
  EXPECT_EQ(Flatten(FromDevice(ctx, d_pos, n)), Flatten(want));
  for (int i = 0; i < n; ++i) {
    EXPECT_EQ(want[i].x, def_pos[i].x);
    EXPECT_EQ(want[i].w, def_pos[i].w + (i % 3 == 0 && i > 0 ? 1.f : 0.f)) << i;
  }
}

TEST(SolverParityTest, SortIndicesSortsAsStdSortDoes) {
  std::mt19937 rng(7);
  for (int n = 0; n <= 90; ++n) {
    std::vector<int> a(n);
    for (int& v : a) v = int(rng() % 50u);
    std::vector<int> want = a;
    std::sort(want.begin(), want.end());
    vd_sort_indices(a.data(), n);
    EXPECT_EQ(a, want) << n << " indices";
  }
}

// The device's counting sort of the constraints by cell (count, a scatter whose atomics place them
// in any order, then each cell put back in input order) gives the CPU's exactly, bit for bit and
// place for place, run after run: the sums over a cell, and so the whole solve, repeat exactly.
TEST(SolverParityTest, ConstraintSortKeepsInputOrderWithinACellAndMatchesTheCpu) {
  VD_REQUIRE_OCL(ctx);
  const Problem p = MakeProblem();
  const size_t n = p.raw.size(), m = p.active.list.size(), total = p.cell_start[m];
  ASSERT_GT(total, 2000u);
  // The CPU's order is the input order within each cell.
  std::vector<vd_uint> next(p.cell_start.begin(), p.cell_start.end() - 1);
  vd_uint most = 0;
  for (size_t i = 0; i < n; ++i) {
    const int kc = p.cell_of[i];
    if (kc < 0) continue;
    const vd_uint c = next[kc]++;
    ASSERT_EQ(0, std::memcmp(&p.cons[c], &p.raw[i], sizeof(VdCorrespondence))) << "constraint " << i;
    ASSERT_EQ(p.cons_cell[c], kc);
    most = std::max(most, p.cell_start[kc + 1] - p.cell_start[kc]);
  }
  ASSERT_GT(most, 24u) << "no cell crowded enough for the heapsort";

  DeviceActiveSet a;
  a.count = m;
  a.list = ToDevice(ctx, p.active.list);
  a.compact = ToDevice(ctx, p.active.compact);
  a.neighbours = ToDevice(ctx, p.active.neighbours);
  const auto d_raw = ToDevice(ctx, p.raw);
  auto cell_of = ctx->Alloc<int32_t>(n);
  auto counts = ctx->Alloc<uint32_t>(m + 1);
  ASSERT_TRUE(cell_of.ok() && counts.ok());
  ASSERT_TRUE(ctx->Fill(*counts, 0u, m + 1).ok());
  const Status counted = ocl::CountConstraints(*ctx, n, d_raw, DeviceLattice::Dense(p.vol), a, *cell_of, *counts);
  ASSERT_TRUE(counted.ok()) << counted.ToString();
  EXPECT_EQ(FromDevice(ctx, *cell_of, n), p.cell_of);
  const auto got_counts = FromDevice(ctx, *counts, m);
  for (size_t k = 0; k < m; ++k) ASSERT_EQ(got_counts[k], p.cell_start[k + 1] - p.cell_start[k]) << "cell " << k;

  const auto d_start = ToDevice(ctx, p.cell_start);
  auto cursor = ctx->Alloc<uint32_t>(m);
  auto order = ctx->Alloc<int32_t>(total);
  auto sorted = ctx->Alloc<VdCorrespondence>(total);
  auto sorted_cell = ctx->Alloc<int32_t>(total);
  ASSERT_TRUE(cursor.ok() && order.ok() && sorted.ok() && sorted_cell.ok());
  for (int run = 0; run < 3; ++run) {
    ASSERT_TRUE(ctx->Fill(*cursor, 0u, m).ok());
    const Status st =
        ocl::SortConstraints(*ctx, n, m, d_raw, *cell_of, d_start, *cursor, *order, *sorted, *sorted_cell);
    ASSERT_TRUE(st.ok()) << st.ToString();
    const auto got = FromDevice(ctx, *sorted, total);
    EXPECT_EQ(0, std::memcmp(got.data(), p.cons.data(), total * sizeof(VdCorrespondence))) << "run " << run;
    EXPECT_EQ(FromDevice(ctx, *sorted_cell, total), p.cons_cell) << "run " << run;
  }
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

  const std::vector<float> ew = EdgeWeights(p);
  auto sys = BuildOnDevice(ctx, p, ew, w);
  ASSERT_TRUE(sys.ok()) << sys.status().ToString();
  const auto blocks = FromDevice(ctx, sys->blocks, size_t(VD_BTB_FLOATS) * m);
  const auto nbr = FromDevice(ctx, sys->nbr, size_t(VD_BTB_BLOCKS) * m);
  const auto rhs = FromDevice(ctx, sys->rhs, m);
  const auto inv = FromDevice(ctx, sys->inv, m);

  // CPU reference: the same per-item functions.
  std::vector<float> moments(size_t(VD_CELL_MOMENT_FLOATS) * m, 0.f), blocks_ref(size_t(VD_BTB_FLOATS) * m);
  std::vector<int> nbr_ref(size_t(VD_BTB_BLOCKS) * m);
  std::vector<vd_float4> rhs_ref(m);
  std::vector<VdMat3> inv_ref(m);
  const VdActive act =
      vd_active(vd_lattice_dense(p.vol), nullptr, nullptr, p.active.list.data(), p.active.compact.data());
  cpu::CellMoments(act, p.cons.data(), p.cell_start.data(), m, moments.data());
  cpu::BtbAssemble(act, p.active.neighbours.data(), ew.data(), moments.data(), w, nullptr, m, blocks_ref.data(),
                   nbr_ref.data(), rhs_ref.data(), inv_ref.data());
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

  auto d_d = ToDevice(ctx, d);
  const std::vector<float> ew = EdgeWeights(p);
  auto sys = BuildOnDevice(ctx, p, ew, w);
  auto d_q = ctx->Alloc<vd_float4>(m);
  ASSERT_TRUE(sys.ok() && d_q.ok());
  ASSERT_TRUE(ocl::ApplySystemCached(*ctx, m, sys->blocks, sys->nbr, d_d, *d_q).ok());
  const auto q = FromDevice(ctx, *d_q, m);
  const auto blocks = FromDevice(ctx, sys->blocks, size_t(VD_BTB_FLOATS) * m);
  const auto nbr = FromDevice(ctx, sys->nbr, size_t(VD_BTB_BLOCKS) * m);

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

// The PCG in its Chronopoulos/Gear form (shared/solver.h) on the cached system of the sphere
// problem: every pass on the device against its CPU reference, the iterates against textbook PCG
// in double precision on the host (the same in exact arithmetic), and the convergence test.
TEST(SolverParityTest, ChronopoulosGearPcgMatchesCpuAndTextbookPcg) {
  VD_REQUIRE_OCL(ctx);
  const Problem p = MakeProblem();
  const int m = int(p.active.list.size());
  const VdSolverWeights w = ProductWeights();
  auto sys = BuildOnDevice(ctx, p, EdgeWeights(p), w);
  ASSERT_TRUE(sys.ok()) << sys.status().ToString();
  auto& d_blocks = sys->blocks;
  auto& d_nbr = sys->nbr;
  auto& d_inv = sys->inv;
  const auto blocks = FromDevice(ctx, d_blocks, size_t(VD_BTB_FLOATS) * m);
  const auto nbr = FromDevice(ctx, d_nbr, size_t(VD_BTB_BLOCKS) * m);
  const auto inv = FromDevice(ctx, d_inv, m);

  // A x = b from x = 0: r = b, u = M^-1 b; p and s start as NaN (beta 0 must not read them).
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> uni(-1.f, 1.f);
  std::vector<vd_float4> b(m), x(m), u(m), wv(m), pv(m, VD_F4(NAN, NAN, NAN, 0.f)), sv(pv);
  for (int k = 0; k < m; ++k) {
    b[k] = VD_F4(uni(rng), uni(rng), uni(rng), 0.f);
    x[k] = VD_F4(0.f, 0.f, 0.f, 3.f);  // w is the point's optimisation count: kept
    u[k] = vd_mat3_apply(inv[k], b[k]);
  }
  std::vector<vd_float4> r = b;
  auto d_r = ToDevice(ctx, r), d_u = ToDevice(ctx, u), d_x = ToDevice(ctx, x), d_p = ToDevice(ctx, pv),
       d_s = ToDevice(ctx, sv);
  auto d_w = ctx->Alloc<vd_float4>(m);
  const int groups = int(ocl::PcgGroups(size_t(m)));
  auto d_part = ctx->Alloc<float>(3 * size_t(groups));
  auto d_scal = ctx->Alloc<float>(VD_PCG_SCALARS);
  ASSERT_TRUE(d_w.ok() && d_part.ok() && d_scal.ok());
  std::vector<float> part(3 * size_t(groups)), scal(VD_PCG_SCALARS, 0.f);
  // The stop threshold from b.b (tolerance 1e-6: no convergence within the iterations below).
  double bb = 0;
  for (const auto& v : b) bb += double(v.x) * v.x + double(v.y) * v.y + double(v.z) * v.z;
  const float tol = 1e-6f;
  scal[VD_PCG_STOP] = float(tol * tol * bb);
  ASSERT_TRUE(ctx->Upload(*d_scal, scal.data(), VD_PCG_SCALARS).ok());

  auto expect_same = [&](const std::vector<vd_float4>& host, const ocl::Buffer<vd_float4>& dev, const char* what,
                         int it) {
    EXPECT_TRUE(AllClose(Flatten(FromDevice(ctx, dev, m)), Flatten(host), 1e-5f, 1e-4f))
        << what << ", iteration " << it;
  };
  auto expect_partials = [&](int n, const char* what, int it) {
    EXPECT_TRUE(AllClose(FromDevice(ctx, *d_part, size_t(n) * groups),
                         std::vector<float>(part.begin(), part.begin() + n * groups), 1e-5f, 1e-4f))
        << what << ", iteration " << it;
  };
  auto expect_scalars = [&](int it) {
    const auto got = FromDevice(ctx, *d_scal, VD_PCG_SCALARS);
    for (int i : {VD_PCG_GAMMA, VD_PCG_RR, VD_PCG_ALPHA, VD_PCG_BETA})
      EXPECT_NEAR(got[i], scal[i], 1e-4 * std::fabs(scal[i]) + 1e-12) << "scalar " << i << ", iteration " << it;
    EXPECT_EQ(got[VD_PCG_CONVERGED], scal[VD_PCG_CONVERGED]) << "iteration " << it;
  };

  // Textbook PCG in double on the host, from the same blocks and preconditioner.
  using V = std::vector<Eigen::Vector3d>;
  auto apply = [&](const V& d) {
    V q(m, Eigen::Vector3d::Zero());
    for (int k = 0; k < m; ++k)
      for (int o = 0; o < VD_BTB_BLOCKS; ++o) {
        const int j = nbr[VD_BTB_BLOCKS * k + o];
        if (j >= 0) q[k] += StoredBlock(blocks, nbr, k, o) * d[j];
      }
    return q;
  };
  auto dot = [&](const V& a, const V& c) {
    double acc = 0;
    for (int k = 0; k < m; ++k) acc += a[k].dot(c[k]);
    return acc;
  };
  auto precond = [&](const V& v) {
    V z(m);
    for (int k = 0; k < m; ++k) {
      Eigen::Matrix3d mi;
      for (int a = 0; a < 9; ++a) mi(a / 3, a % 3) = inv[k].m[a];
      z[k] = mi * v[k];
    }
    return z;
  };
  V hx(m, Eigen::Vector3d::Zero()), hr(m);
  for (int k = 0; k < m; ++k) hr[k] = Eigen::Vector3d(b[k].x, b[k].y, b[k].z);
  V hz = precond(hr), hp = hz;
  double rz = dot(hr, hz);

  // Start: w = A u with its dots, the first step size.
  ASSERT_TRUE(ocl::PcgApplyDots(*ctx, m, *d_scal, d_blocks, d_nbr, d_r, d_u, *d_w, *d_part).ok());
  cpu::PcgApplyDots(scal.data(), blocks.data(), nbr.data(), r.data(), u.data(), m, wv.data(), part.data());
  expect_same(wv, *d_w, "w", 0);
  expect_partials(3, "start triples", 0);
  // The dots alone (the constraints' path, whose product is applied before) give the same triples.
  {
    auto d_part2 = ctx->Alloc<float>(3 * size_t(groups));
    ASSERT_TRUE(d_part2.ok());
    ASSERT_TRUE(ocl::PcgDots(*ctx, m, d_r, d_u, *d_w, *d_part2).ok());
    std::vector<float> part2(3 * size_t(groups));
    cpu::PcgDots(r.data(), u.data(), wv.data(), m, part2.data());
    EXPECT_TRUE(AllClose(FromDevice(ctx, *d_part2, 3 * size_t(groups)), part2, 1e-5f, 1e-4f));
    EXPECT_TRUE(AllClose(part2, std::vector<float>(part.begin(), part.begin() + 3 * groups), 1e-5f, 1e-4f));
  }
  ASSERT_TRUE(ocl::PcgScalars(*ctx, *d_part, groups, VD_PCG_SET_START, tol, *d_scal).ok());
  cpu::PcgScalars(part.data(), groups, VD_PCG_SET_START, tol, scal.data());
  expect_scalars(0);
  const int kIterations = 6;
  for (int it = 1; it <= kIterations; ++it) {
    ASSERT_TRUE(ocl::PcgCgUpdate(*ctx, m, *d_scal, d_inv, *d_w, d_p, d_s, d_x, d_r, d_u, *d_part).ok());
    cpu::PcgCgUpdate(scal.data(), inv.data(), wv.data(), m, pv.data(), sv.data(), x.data(), r.data(), u.data(),
                     part.data());
    for (auto [host, dev, what] :
         {std::tuple{&x, &d_x, "x"}, {&r, &d_r, "r"}, {&u, &d_u, "u"}, {&pv, &d_p, "p"}, {&sv, &d_s, "s"}})
      expect_same(*host, *dev, what, it);
    expect_partials(1, "r.r", it);
    ASSERT_TRUE(ocl::PcgScalars(*ctx, *d_part, groups, VD_PCG_SET_RR, tol, *d_scal).ok());
    cpu::PcgScalars(part.data(), groups, VD_PCG_SET_RR, tol, scal.data());
    expect_scalars(it);
    ASSERT_EQ(scal[VD_PCG_CONVERGED], 0.f);
    ASSERT_TRUE(ocl::PcgApplyDots(*ctx, m, *d_scal, d_blocks, d_nbr, d_r, d_u, *d_w, *d_part).ok());
    cpu::PcgApplyDots(scal.data(), blocks.data(), nbr.data(), r.data(), u.data(), m, wv.data(), part.data());
    expect_same(wv, *d_w, "w", it);
    expect_partials(3, "triples", it);
    ASSERT_TRUE(ocl::PcgScalars(*ctx, *d_part, groups, VD_PCG_SET_NEXT, tol, *d_scal).ok());
    cpu::PcgScalars(part.data(), groups, VD_PCG_SET_NEXT, tol, scal.data());
    expect_scalars(it);

    // The textbook iteration it.
    const V q = apply(hp);
    const double alpha = rz / dot(hp, q);
    for (int k = 0; k < m; ++k) {
      hx[k] += alpha * hp[k];
      hr[k] -= alpha * q[k];
    }
    hz = precond(hr);
    const double rz_new = dot(hr, hz);
    for (int k = 0; k < m; ++k) hp[k] = hz[k] + (rz_new / rz) * hp[k];
    rz = rz_new;
    // The iterates agree with textbook PCG's to float precision.
    const auto gx = FromDevice(ctx, d_x, m);
    double worst = 0, largest = 0;
    for (int k = 0; k < m; ++k) {
      worst = std::max(worst, (Eigen::Vector3d(gx[k].x, gx[k].y, gx[k].z) - hx[k]).cwiseAbs().maxCoeff());
      largest = std::max(largest, hx[k].cwiseAbs().maxCoeff());
      ASSERT_EQ(gx[k].w, 3.f);
    }
    std::printf("iteration %d: |x - x_textbook| %.3g of %.3g, r.r %.4g (textbook %.4g)\n", it, worst, largest,
                scal[VD_PCG_RR], dot(hr, hr));
    EXPECT_LT(worst, 1e-4 * largest) << "iteration " << it;
    EXPECT_NEAR(scal[VD_PCG_RR], dot(hr, hr), 1e-3 * dot(hr, hr)) << "iteration " << it;
  }
  // The iterations reduce the residual (the system is well conditioned with the preconditioner).
  EXPECT_LT(dot(hr, hr), 0.05 * bb);

  // Converged (tolerance 0.5): alpha and beta 0, and a further update leaves x and r as they are.
  scal.assign(VD_PCG_SCALARS, 0.f);
  scal[VD_PCG_STOP] = float(0.25 * bb);
  scal[VD_PCG_ALPHA] = 1.f;
  scal[VD_PCG_BETA] = 1.f;
  ASSERT_TRUE(ctx->Upload(*d_scal, scal.data(), VD_PCG_SCALARS).ok());
  ASSERT_TRUE(ocl::PcgCgUpdate(*ctx, m, *d_scal, d_inv, *d_w, d_p, d_s, d_x, d_r, d_u, *d_part).ok());
  ASSERT_TRUE(ocl::PcgScalars(*ctx, *d_part, groups, VD_PCG_SET_RR, 0.5f, *d_scal).ok());
  const auto s2 = FromDevice(ctx, *d_scal, VD_PCG_SCALARS);
  EXPECT_EQ(s2[VD_PCG_CONVERGED], 1.f);
  EXPECT_EQ(s2[VD_PCG_ALPHA], 0.f);
  EXPECT_EQ(s2[VD_PCG_BETA], 0.f);
  // Converged, the product and the update queued behind the host's read of the test (the solver
  // reads it one iteration late) do nothing at all, on the device as in the CPU reference: w, the
  // partial sums, x, r, u, p and s stay as they were.
  const auto w0 = FromDevice(ctx, *d_w, m);
  const auto part0 = FromDevice(ctx, *d_part, size_t(groups));
  ASSERT_TRUE(ocl::PcgApplyDots(*ctx, m, *d_scal, d_blocks, d_nbr, d_r, d_u, *d_w, *d_part).ok());
  EXPECT_EQ(Flatten(FromDevice(ctx, *d_w, m)), Flatten(w0));
  EXPECT_EQ(FromDevice(ctx, *d_part, size_t(groups)), part0);
  ASSERT_TRUE(ocl::PcgScalars(*ctx, *d_part, groups, VD_PCG_SET_NEXT, 0.5f, *d_scal).ok());
  EXPECT_EQ(FromDevice(ctx, *d_scal, VD_PCG_SCALARS)[VD_PCG_CONVERGED], 1.f);
  const auto x1 = FromDevice(ctx, d_x, m), r1 = FromDevice(ctx, d_r, m), u1 = FromDevice(ctx, d_u, m),
             p1 = FromDevice(ctx, d_p, m), s1 = FromDevice(ctx, d_s, m);
  ASSERT_TRUE(ocl::PcgCgUpdate(*ctx, m, *d_scal, d_inv, *d_w, d_p, d_s, d_x, d_r, d_u, *d_part).ok());
  EXPECT_EQ(Flatten(FromDevice(ctx, d_x, m)), Flatten(x1));
  EXPECT_EQ(Flatten(FromDevice(ctx, d_r, m)), Flatten(r1));
  EXPECT_EQ(Flatten(FromDevice(ctx, d_u, m)), Flatten(u1));
  EXPECT_EQ(Flatten(FromDevice(ctx, d_p, m)), Flatten(p1));
  EXPECT_EQ(Flatten(FromDevice(ctx, d_s, m)), Flatten(s1));
  const auto done = FromDevice(ctx, *d_scal, VD_PCG_SCALARS);
  std::vector<vd_float4> wc = w0, xc = x1;
  std::vector<float> partc = part0;
  cpu::PcgApplyDots(done.data(), blocks.data(), nbr.data(), r1.data(), u1.data(), m, wc.data(), partc.data());
  EXPECT_EQ(Flatten(wc), Flatten(w0));
  EXPECT_EQ(partc, part0);
}

// The start of a position step in one pass (vd_pcg_start: b, r = b - A x, u = M^-1 r and b.b) on
// the device, on the CPU, and as the separate passes it replaces.
TEST(SolverParityTest, PcgStartMatchesCpuAndTheSeparatePasses) {
  VD_REQUIRE_OCL(ctx);
  const Problem p = MakeProblem();
  const int m = int(p.active.list.size());
  const VdSolverWeights w = ProductWeights();
  const std::vector<float> ew = EdgeWeights(p);
  auto sys = BuildOnDevice(ctx, p, ew, w);
  ASSERT_TRUE(sys.ok()) << sys.status().ToString();
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> uni(-1.f, 1.f);
  std::vector<vd_float4> x(m), rot(m);
  for (int k = 0; k < m; ++k) {
    const int g = p.active.list[k];
    const int gx = g % p.vol.dim_x, gy = (g / p.vol.dim_x) % p.vol.dim_y, gz = g / (p.vol.dim_x * p.vol.dim_y);
    x[k] = vd_rest_position(p.vol, gx, gy, gz) + VD_F4(0.002f * uni(rng), 0.002f * uni(rng), 0.002f * uni(rng), 0.f);
    x[k].w = 2.f;
    const vd_float4 q = VD_F4(0.1f * uni(rng), 0.1f * uni(rng), 0.1f * uni(rng), 1.f);
    rot[k] = q * (1.f / std::sqrt(vd_dot3(q, q) + q.w * q.w));
  }
  auto d_nb = ToDevice(ctx, p.active.neighbours);
  auto d_ew = ToDevice(ctx, ew);
  auto d_x = ToDevice(ctx, x), d_rot = ToDevice(ctx, rot);
  auto d_r = ctx->Alloc<vd_float4>(m), d_u = ctx->Alloc<vd_float4>(m), d_b = ctx->Alloc<vd_float4>(m),
       d_r2 = ctx->Alloc<vd_float4>(m), d_u2 = ctx->Alloc<vd_float4>(m);
  const int groups = int(ocl::PcgGroups(size_t(m)));
  auto d_part = ctx->Alloc<float>(groups);
  ASSERT_TRUE(d_r.ok() && d_u.ok() && d_b.ok() && d_r2.ok() && d_u2.ok() && d_part.ok());
  ASSERT_TRUE(ocl::PcgStart(*ctx, m, p.vol.voxel_size, d_nb, d_ew, d_rot, sys->rhs, w, sys->blocks, sys->nbr, sys->inv,
                            d_x, *d_r, *d_u, *d_part)
                  .ok());
  // The separate passes.
  ASSERT_TRUE(ocl::SystemRhs(*ctx, m, p.vol.voxel_size, d_nb, d_ew, d_rot, sys->rhs, d_x, w, *d_b).ok());
  ASSERT_TRUE(ocl::ApplySystemCached(*ctx, m, sys->blocks, sys->nbr, d_x, *d_r2).ok());
  ASSERT_TRUE(ocl::SubFrom(*ctx, m, *d_b, *d_r2).ok());
  ASSERT_TRUE(ocl::Precondition(*ctx, m, sys->inv, *d_r2, *d_u2).ok());
  const auto r = FromDevice(ctx, *d_r, m), u = FromDevice(ctx, *d_u, m), b = FromDevice(ctx, *d_b, m);
  const auto part = FromDevice(ctx, *d_part, groups);
  EXPECT_TRUE(AllClose(Flatten(r), Flatten(FromDevice(ctx, *d_r2, m)), 1e-6f, 1e-5f));
  EXPECT_TRUE(AllClose(Flatten(u), Flatten(FromDevice(ctx, *d_u2, m)), 1e-6f, 1e-5f));
  double bb = 0, bb_dev = 0, r_scale = 0;
  for (const auto& v : b) bb += double(v.x) * v.x + double(v.y) * v.y + double(v.z) * v.z;
  for (float v : part) bb_dev += v;
  for (const auto& v : r) r_scale = std::max(r_scale, double(std::fabs(v.x)) + std::fabs(v.y) + std::fabs(v.z));
  std::printf("%d points: b.b %.6g (device partials %.6g), largest |r| %.3g\n", m, bb, bb_dev, r_scale);
  EXPECT_NEAR(bb_dev, bb, 1e-5 * bb);
  EXPECT_GT(r_scale, 1e-3);  // x is off the solution: the residual is not trivially zero

  // CPU reference.
  const auto blocks = FromDevice(ctx, sys->blocks, size_t(VD_BTB_FLOATS) * m);
  const auto nbr = FromDevice(ctx, sys->nbr, size_t(VD_BTB_BLOCKS) * m);
  const auto inv = FromDevice(ctx, sys->inv, m);
  const auto rhs = FromDevice(ctx, sys->rhs, m);
  std::vector<vd_float4> r_cpu(m), u_cpu(m);
  std::vector<float> part_cpu(groups);
  cpu::PcgStart(p.vol.voxel_size, p.active.neighbours.data(), ew.data(), rot.data(), rhs.data(), w, blocks.data(),
                nbr.data(), inv.data(), x.data(), m, r_cpu.data(), u_cpu.data(), part_cpu.data());
  EXPECT_TRUE(AllClose(Flatten(r), Flatten(r_cpu), 1e-6f, 1e-5f));
  EXPECT_TRUE(AllClose(Flatten(u), Flatten(u_cpu), 1e-6f, 1e-5f));
  EXPECT_TRUE(AllClose(part, part_cpu, 1e-5f, 1e-5f));
}

}  // namespace
}  // namespace vd
