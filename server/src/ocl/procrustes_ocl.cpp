// The launcher of kernels/procrustes.cl that DeviceSolver (core/solver.cpp) calls.
#include "ocl/procrustes_ocl.h"

namespace vd::ocl {

Status FitRotations(Context& ctx, size_t m, const Buffer<int32_t>& neighbours, const Buffer<float>& edge_w,
                    const Buffer<vd_float4>& t, const Buffer<vd_float4>& t_hat, int iterations,
                    Buffer<vd_float4>& rot) {
  if (iterations <= 0) return kProcrustes(ctx, m, neighbours, edge_w, t, t_hat, rot);
  return kProcrustesRefine(ctx, m, neighbours, edge_w, t, t_hat, rot, int32_t(iterations));
}

}  // namespace vd::ocl
