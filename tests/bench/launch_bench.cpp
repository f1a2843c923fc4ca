// What one kernel launch costs on the device beside the work it does: an axpy over one work-group
// (64 items, no work to speak of) and over the fine active set's size (45 k items), launched
// back to back with one wait at the end, and with a wait after each (a host round trip, as every
// PCG dot product makes). The engine launches ~370 kernels per frame (docs/BENCHMARKS.md).
//   vd_launch_bench [--launches N] [--device SPEC]
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "ocl/solver_ocl.h"
#include "vd/common/flags.h"

namespace vd {
namespace {

void Check(const Status& s) {
  if (!s.ok()) {
    std::fprintf(stderr, "vd_launch_bench: %s\n", s.ToString().c_str());
    std::exit(1);
  }
}

// Microseconds per launch of an axpy over `items`, waiting after every launch or only at the end.
double MicrosPerLaunch(ocl::Context& ctx, ocl::Buffer<vd_float4>& x, ocl::Buffer<vd_float4>& y, size_t items,
                       int launches, bool wait_each) {
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < launches; ++i) {
    Check(ocl::Axpy(ctx, items, 1e-6f, x, y));
    if (wait_each) Check(ctx.Finish());
  }
  Check(ctx.Finish());
  return std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count() / launches;
}

int Main(int argc, char** argv) {
  int launches = 2000;
  std::string device;
  FlagParser flags("vd_launch_bench: the cost of one kernel launch on the OpenCL device.");
  flags.Add("launches", &launches, "Launches per measurement", "N");
  flags.Add("device", &device, "OpenCL device: index or name substring (default first GPU, else CPU)");
  if (auto exit_code = flags.ParseCommandLine(argc, argv, "vd_launch_bench")) return *exit_code;
  auto ctx = ocl::Context::Create(device);
  Check(ctx.status());
  std::printf("device: %s\n", (*ctx)->Describe().c_str());
  const size_t n = 45000;
  auto x = (*ctx)->Alloc<vd_float4>(n);
  auto y = (*ctx)->Alloc<vd_float4>(n);
  Check(x.status());
  Check(y.status());
  Check((*ctx)->Fill(*x, VD_F4(1.f, 1.f, 1.f, 0.f), n));
  Check((*ctx)->Fill(*y, VD_F4(0.f, 0.f, 0.f, 0.f), n));
  // The first launches build the work-group variant; not counted.
  MicrosPerLaunch(**ctx, *x, *y, n, 20, true);
  for (size_t items : {size_t(64), n}) {
    const double queued = MicrosPerLaunch(**ctx, *x, *y, items, launches, false);
    const double waited = MicrosPerLaunch(**ctx, *x, *y, items, launches, true);
    std::printf("axpy over %6zu items: %8.1f us per launch queued, %8.1f us with a wait after each\n", items, queued,
                waited);
  }
  return 0;
}

}  // namespace
}  // namespace vd

int main(int argc, char** argv) { return vd::Main(argc, argv); }
