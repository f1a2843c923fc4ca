#pragma once
// The kernels of kernels/scan.cl. One typed handle
// each (ocl/kernel.h), its parameters those of the __kernel in order; kFoo(ctx, items, args...)
// runs it over `items` work items (what one item is, above each).
#include <cstdint>

#include "ocl/kernel.h"

namespace vd::ocl {

// One item per chunk of `chunk` elements.
inline constexpr Kernel<void(const Buffer<uint32_t>& in, uint32_t n, uint32_t chunk,
                             Buffer<uint32_t>& sums)> kScanSums{"vd_scan_sums"};
// One item per chunk; out[n] receives the total.
inline constexpr Kernel<void(const Buffer<uint32_t>& in, uint32_t n, uint32_t chunk, const Buffer<uint32_t>& offsets,
                             uint32_t use_offsets, Buffer<uint32_t>& out)> kScanApply{"vd_scan_apply"};

}  // namespace vd::ocl
