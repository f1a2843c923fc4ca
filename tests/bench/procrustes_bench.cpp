// The rotation step (kernel vd_procrustes) on the OpenCL device against its CPU reference
// (cpu::Procrustes, OpenMP) on the same active set, in one run so the ratio survives a noisy
// machine. The active set is a one-ring-like shell of grid points around a sphere (4-6 neighbours
// each, compact x-fastest order as a list builder would emit), deformed by a smooth twist plus
// noise. The paper's figure: 400K grid points in 1.9 ms on a GPU.
//   vd_procrustes_bench [--points N] [--reps N] [--device SPEC]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "cpu_ref/procrustes_ref.h"
#include "ocl/ocl.h"
#include "ocl/procrustes_ocl.h"

namespace vd {
namespace {

struct Timing {
  double wall_ms;
  double cpu_ms;
};

// Median wall and process-CPU milliseconds of f over reps runs.
Timing Median(int reps, const std::function<void()>& f) {
  std::vector<double> wall, cpu;
  for (int r = 0; r < reps; ++r) {
    const std::clock_t c0 = std::clock();
    const auto t0 = std::chrono::steady_clock::now();
    f();
    wall.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    cpu.push_back(1000.0 * double(std::clock() - c0) / CLOCKS_PER_SEC);
  }
  std::nth_element(wall.begin(), wall.begin() + reps / 2, wall.end());
  std::nth_element(cpu.begin(), cpu.begin() + reps / 2, cpu.end());
  return {wall[reps / 2], cpu[reps / 2]};
}

void Check(const Status& s) {
  if (!s.ok()) {
    std::fprintf(stderr, "vd_procrustes_bench: %s\n", s.ToString().c_str());
    std::exit(1);
  }
}

struct ActiveSet {
  std::vector<int> neighbours;
  std::vector<vd_float4> t, t_hat;
};

// Grid points within 1.5 voxels of a sphere whose radius gives about `points` of them.
ActiveSet MakeShell(int points) {
  const double radius = std::sqrt(points / (4.0 * M_PI * 3.0));
  const int dim = int(2 * radius + 6);
  const float h = 0.004f;
  std::vector<int> index(size_t(dim) * dim * dim, -1);
  ActiveSet s;
  std::mt19937 rng(1);
  std::normal_distribution<float> noise(0.f, 0.0005f);
  std::vector<int> cells;
  for (int z = 0; z < dim; ++z)
    for (int y = 0; y < dim; ++y)
      for (int x = 0; x < dim; ++x) {
        const double dx = x - dim / 2.0, dy = y - dim / 2.0, dz = z - dim / 2.0;
        if (std::fabs(std::sqrt(dx * dx + dy * dy + dz * dz) - radius) >= 1.5) continue;
        const size_t c = x + size_t(dim) * (y + size_t(dim) * z);
        index[c] = int(cells.size());
        cells.push_back(int(c));
        const float px = h * float(dx), py = h * float(dy), pz = 1.5f + h * float(dz);
        s.t_hat.push_back(VD_F4(px, py, pz, 1.f));
        const float a = 1.5f * (pz - 1.5f);  // twist about the viewing axis, growing with depth
        s.t.push_back(VD_F4(std::cos(a) * px - std::sin(a) * py + noise(rng),
                            std::sin(a) * px + std::cos(a) * py + noise(rng), pz + noise(rng), 1.f));
      }
  const int off[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  s.neighbours.reserve(6 * cells.size());
  for (int c : cells) {
    const int x = c % dim, y = (c / dim) % dim, z = c / (dim * dim);
    for (const auto& d : off) {
      const int xx = x + d[0], yy = y + d[1], zz = z + d[2];
      const bool inside = xx >= 0 && yy >= 0 && zz >= 0 && xx < dim && yy < dim && zz < dim;
      s.neighbours.push_back(inside ? index[xx + size_t(dim) * (yy + size_t(dim) * zz)] : -1);
    }
  }
  return s;
}

int Main(int argc, char** argv) {
  int points = 400000, reps = 11;
  std::string device;
  for (int i = 1; i < argc; ++i) {
    const bool has_value = i + 1 < argc;
    if (!std::strcmp(argv[i], "--points") && has_value) {
      points = std::atoi(argv[++i]);
    } else if (!std::strcmp(argv[i], "--reps") && has_value) {
      reps = std::atoi(argv[++i]);
    } else if (!std::strcmp(argv[i], "--device") && has_value) {
      device = argv[++i];
    } else {
      std::fprintf(stderr, "usage: vd_procrustes_bench [--points N (>= 1000)] [--reps N (>= 1)] [--device SPEC]\n");
      return 2;
    }
  }
  if (points < 1000 || points > 50000000 || reps < 1) {
    std::fprintf(stderr, "vd_procrustes_bench: --points must be in [1000, 5e7] and --reps >= 1\n");
    return 2;
  }
  const ActiveSet s = MakeShell(points);
  const int n = int(s.t.size());
  int links = 0;
  for (int j : s.neighbours) links += j >= 0;

  auto ctx_or = ocl::Context::Create(device);
  Check(ctx_or.status());
  ocl::Context* ctx = ctx_or->get();
  std::printf("active set: %d grid points, %.2f neighbours each; device %s\n", n, double(links) / n,
              ctx->Describe().c_str());

  auto dn = ctx->Alloc<int>(s.neighbours.size());
  auto dt = ctx->Alloc<vd_float4>(n), dth = ctx->Alloc<vd_float4>(n), drot = ctx->Alloc<vd_float4>(n);
  auto dw = ctx->Alloc<float>(6 * size_t(n));
  Check(dw.status());
  Check(ctx->Fill(*dw, 1.f, 6 * size_t(n)));
  Check(dn.status());
  Check(dt.status());
  Check(dth.status());
  Check(drot.status());
  Check(ctx->Upload(*dn, s.neighbours.data(), s.neighbours.size()));
  Check(ctx->Upload(*dt, s.t.data(), n));
  Check(ctx->Upload(*dth, s.t_hat.data(), n));

  // Exact (SVD, iterations 0) and warm-started refinement (2 steps, the solver's default) on the
  // device, same run; the refinement starts from the exact answer, as the flip-flop's previous
  // half-step leaves it near the optimum (its cost does not depend on where it starts).
  std::vector<vd_float4> cpu_rot(n, VD_F4(0.f, 0.f, 0.f, 1.f)), ocl_rot(n), warm_rot(n);
  auto cpu = [&] { cpu::Procrustes(s.neighbours.data(), nullptr, s.t.data(), s.t_hat.data(), n, 0, cpu_rot.data()); };
  auto ocl = [&] {
    Check(ocl::FitRotations(*ctx, n, *dn, *dw, *dt, *dth, 0, *drot));
    Check(ctx->Finish());
  };
  cpu();
  ocl();  // builds the work-group variant outside the timing
  Check(ctx->Download(*drot, ocl_rot.data(), n));
  auto refine = [&] {
    Check(ocl::FitRotations(*ctx, n, *dn, *dw, *dt, *dth, 2, *drot));
    Check(ctx->Finish());
  };
  refine();
  Check(ctx->Download(*drot, warm_rot.data(), n));
  double worst = 0, worst_refined = 0;
  for (int k = 0; k < n; ++k) {
    auto diff = [](vd_float4 a, vd_float4 b) {
      const float sign = a.x * b.x + a.y * b.y + a.z * b.z + a.w * b.w < 0.f ? -1.f : 1.f;
      return std::max({double(std::fabs(a.x - sign * b.x)), double(std::fabs(a.y - sign * b.y)),
                       double(std::fabs(a.z - sign * b.z)), double(std::fabs(a.w - sign * b.w))});
    };
    worst = std::max(worst, diff(ocl_rot[k], cpu_rot[k]));
    worst_refined = std::max(worst_refined, diff(warm_rot[k], cpu_rot[k]));
  }
  const Timing tc = Median(reps, cpu);
  const Timing to = Median(reps, ocl);
  const Timing tr = Median(reps, refine);
  std::printf("%-30s %10s %10s %14s\n", "backend", "wall_ms", "cpu_ms", "ms/1M points");
  std::printf("%-30s %10.2f %10.2f %14.1f\n", "cpu::Procrustes exact (OMP)", tc.wall_ms, tc.cpu_ms, tc.wall_ms * 1e6 / n);
  std::printf("%-30s %10.2f %10.2f %14.1f\n", "vd_procrustes exact (OpenCL)", to.wall_ms, to.cpu_ms, to.wall_ms * 1e6 / n);
  std::printf("%-30s %10.2f %10.2f %14.1f\n", "vd_procrustes 2 steps (OpenCL)", tr.wall_ms, tr.cpu_ms, tr.wall_ms * 1e6 / n);
  std::printf("ocl/cpu wall %.2f; exact/refined wall %.2f; max |q_ocl - q_cpu| = %.1e, refined %.1e; median of %d\n",
              to.wall_ms / tc.wall_ms, to.wall_ms / tr.wall_ms, worst, worst_refined, reps);
  return worst <= 1e-5 && worst_refined <= 1e-4 ? 0 : 1;
}

}  // namespace
}  // namespace vd

int main(int argc, char** argv) { return vd::Main(argc, argv); }
