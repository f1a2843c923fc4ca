#pragma once
// The kernels of kernels/raster.cl, per-item math in shared/raster.h. One typed handle
// each (ocl/kernel.h), its parameters those of the __kernel in order; kFoo(ctx, items, args...)
// runs it over `items` work items (what one item is, above each).
#include <cstdint>

#include "ocl/kernel.h"
#include "shared/raster.h"

namespace vd::ocl {

// One item per triangle.
inline constexpr Kernel<void(const Buffer<vd_float4>& pos, const Buffer<int32_t>& tris, VdPose T, VdCamera cam,
                             Buffer<uint32_t>& depth_bits)> kRasterDepthPass{"vd_raster_depth_pass"};
// One item per triangle.
inline constexpr Kernel<void(const Buffer<vd_float4>& pos, const Buffer<int32_t>& tris, VdPose T, VdCamera cam,
                             const Buffer<uint32_t>& depth_bits,
                             Buffer<uint32_t>& ids)> kRasterIdPass{"vd_raster_id_pass"};
// One item per pixel.
inline constexpr Kernel<void(const Buffer<vd_float4>& pos, const Buffer<vd_float4>& nrm, const Buffer<int32_t>& tris,
                             VdPose T, VdCamera cam, const Buffer<uint32_t>& ids, Buffer<vd_float4>& vmap,
                             Buffer<vd_float4>& nmap, Buffer<vd_float4>& bary)> kRasterResolve{"vd_raster_resolve"};

}  // namespace vd::ocl
