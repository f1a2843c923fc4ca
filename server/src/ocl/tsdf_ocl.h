#pragma once
// The kernels of kernels/tsdf.cl, per-item math in shared/tsdf.h. One typed handle
// each (ocl/kernel.h), its parameters those of the __kernel in order; kFoo(ctx, items, args...)
// runs it over `items` work items (what one item is, above each).
#include <cstdint>

#include "ocl/kernel.h"
#include "shared/tsdf.h"

namespace vd::ocl {

// One item per grid row (y, z).
inline constexpr Kernel<void(Buffer<float>& tsdf, Buffer<float>& weight, Buffer<uint32_t>& color, VdVolume vol,
                             VdCamera cam, VdPose world_to_cam, const Buffer<float>& depth,
                             const Buffer<uint32_t>& rgba)> kTsdfIntegrate{"vd_tsdf_integrate"};
// One item per active point.
inline constexpr Kernel<void(Buffer<float>& tsdf, Buffer<float>& weight, Buffer<uint32_t>& color,
                             Buffer<uint8_t>& touched, int mark_touched, const Buffer<int32_t>& list,
                             const Buffer<vd_float4>& def_pos, VdFusionParams fp, VdVolume vol, VdCamera cam,
                             VdPose world_to_cam, const Buffer<float>& depth, const Buffer<uint32_t>& rgba)>
    kTsdfIntegrateActive{"vd_tsdf_integrate_active"};
// One item per 8x8 pixel tile.
inline constexpr Kernel<void(const Buffer<float>& depth, VdCamera cam,
                             Buffer<vd_float4>& tiles)> kDepthTiles{"vd_depth_tiles"};
// One item per brick.
inline constexpr Kernel<void(const Buffer<vd_float4>& tiles, VdCamera cam, VdPose world_to_cam, VdVolume vol,
                             Buffer<uint32_t>& flags, Buffer<uint32_t>& masks, Buffer<uint8_t>& touched)>
    kBrickMark{"vd_brick_mark"};
// One item per brick.
inline constexpr Kernel<void(const Buffer<float>& weight, VdVolume vol, Buffer<uint8_t>& touched)> kVolumeTouched{
    "vd_volume_touched"};
// One item per brick.
inline constexpr Kernel<void(const Buffer<uint32_t>& flags, const Buffer<uint32_t>& offsets, Buffer<uint32_t>& list)>
    kDenseBrickCompact{"vd_brick_compact"};
// VD_BRICK_ITEMS items per listed brick.
inline constexpr Kernel<void(const Buffer<uint32_t>& list, const Buffer<uint32_t>& masks, Buffer<float>& tsdf,
                             Buffer<float>& weight, Buffer<uint32_t>& color, VdVolume vol, VdCamera cam,
                             VdPose world_to_cam, const Buffer<float>& depth,
                             const Buffer<uint32_t>& rgba)> kTsdfIntegrateBricks{"vd_tsdf_integrate_bricks"};

}  // namespace vd::ocl
