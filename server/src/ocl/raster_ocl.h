#pragma once
// The kernels of kernels/raster.cl, per-item math in shared/raster.h. One typed handle
// each (ocl/kernel.h), its parameters those of the __kernel in order; kFoo(ctx, items, args...)
// runs it over `items` work items (what one item is, above each).
#include <cstdint>

#include "ocl/kernel.h"
#include "shared/raster.h"

namespace vd::ocl {

// One item per triangle: depth_id = min(depth bits << 32 | triangle) per covered pixel, and each
// triangle's set-up for the resolve.
inline constexpr Kernel<void(const Buffer<vd_float4>& pos, const Buffer<int32_t>& tris, VdPose T, VdCamera cam,
                             Buffer<uint64_t>& depth_id, Buffer<VdRasterSetup>& setups)>
    kRasterPass{"vd_raster_pass"};
// One item per pixel: the triangle id, vertex, normal and barycentrics of the packed pixel.
inline constexpr Kernel<void(const Buffer<vd_float4>& pos, const Buffer<vd_float4>& nrm, const Buffer<int32_t>& tris,
                             const Buffer<VdRasterSetup>& setups, VdPose T, VdCamera cam,
                             const Buffer<uint64_t>& depth_id, Buffer<uint32_t>& ids, Buffer<vd_float4>& vmap,
                             Buffer<vd_float4>& nmap, Buffer<vd_float4>& bary)>
    kRasterResolve{"vd_raster_resolve"};

}  // namespace vd::ocl
