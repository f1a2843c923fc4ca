#pragma once
// The kernels of kernels/icp.cl, per-item math in shared/icp.h. One typed handle
// each (ocl/kernel.h), its parameters those of the __kernel in order; kFoo(ctx, items, args...)
// runs it over `items` work items (what one item is, above each).
#include <cstdint>

#include "ocl/kernel.h"
#include "shared/icp.h"

namespace vd::ocl {

// One item per chunk of `chunk` pixels, VD_ICP_ACC partial sums each.
inline constexpr Kernel<void(const Buffer<vd_float4>& vmap, const Buffer<vd_float4>& nmap,
                             const Buffer<vd_float4>& model_v, const Buffer<vd_float4>& model_n, int n, int chunk,
                             VdIcpParams prm, Buffer<float>& partials)> kIcpReduce{"vd_icp_reduce"};

}  // namespace vd::ocl
