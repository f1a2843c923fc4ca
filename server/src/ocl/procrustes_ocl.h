#pragma once
// The kernels of kernels/procrustes.cl, per-item math in shared/procrustes.h. One typed handle
// each (ocl/kernel.h), its parameters those of the __kernel in order; kFoo(ctx, items, args...)
// runs it over `items` work items (what one item is, above each).
#include <cstdint>

#include "ocl/kernel.h"
#include "shared/procrustes.h"

namespace vd::ocl {

// One item per active point: R_k as a unit quaternion, the exact optimum (SVD).
inline constexpr Kernel<void(const Buffer<int32_t>& neighbours, const Buffer<float>& edge_w, const Buffer<vd_float4>& t,
                             const Buffer<vd_float4>& t_hat, Buffer<vd_float4>& rot)>
    kProcrustes{"vd_procrustes"};
// Laned, one lane per active point: R_k refined by `iterations` steps from the rotation rot holds.
inline constexpr Kernel<void(const Buffer<int32_t>& neighbours, const Buffer<float>& edge_w, const Buffer<vd_float4>& t,
                             const Buffer<vd_float4>& t_hat, Buffer<vd_float4>& rot, int32_t iterations)>
    kProcrustesRefine{"vd_procrustes_refine_kernel", kLaned};

// The rotation step of DeviceSolver (core/solver.cpp): R_k of each of the m active points fitted
// to its neighbours' current positions t against their rest positions t_hat, each edge weighted by
// edge_w (6 per point): exact (SVD) when iterations = 0, else refined from the rotations rot holds
// (shared/procrustes.h).
Status FitRotations(Context& ctx, size_t m, const Buffer<int32_t>& neighbours, const Buffer<float>& edge_w,
                    const Buffer<vd_float4>& t, const Buffer<vd_float4>& t_hat, int iterations, Buffer<vd_float4>& rot);

}  // namespace vd::ocl
