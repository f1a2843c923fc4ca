#pragma once
// The kernels of kernels/preprocess.cl, per-item math in shared/preprocess.h. One typed handle
// each (ocl/kernel.h), its parameters those of the __kernel in order; kFoo(ctx, items, args...)
// runs it over `items` work items (what one item is, above each).
#include <cstdint>

#include "ocl/kernel.h"
#include "shared/preprocess.h"

namespace vd::ocl {

// One item per pixel.
inline constexpr Kernel<void(const Buffer<uint16_t>& raw, Buffer<float>& depth, float inv_scale, float min_depth,
                             float max_depth)> kDepthConvert{"vd_depth_convert"};
// Laned, one lane per pixel.
inline constexpr Kernel<void(const Buffer<float>& in, Buffer<float>& out, int width, int height, int radius,
                             float inv_2sigma_space2, float inv_2sigma_depth2)> kBilateral{"vd_bilateral", kLaned};
// One item per output pixel.
inline constexpr Kernel<void(const Buffer<float>& in, Buffer<float>& out, int in_width, int out_width,
                             float max_diff)> kPyrDown{"vd_pyr_down"};
// One item per pixel.
inline constexpr Kernel<void(const Buffer<float>& depth, Buffer<vd_float4>& vmap,
                             VdCamera cam)> kVertexMap{"vd_vertex_map"};
// One item per pixel.
inline constexpr Kernel<void(const Buffer<vd_float4>& vmap, Buffer<vd_float4>& nmap, int width, int height,
                             float max_jump)> kNormalMap{"vd_normal_map"};
// One item per half-resolution pixel: the intensity image's luma of each 2x2 block.
inline constexpr Kernel<void(const Buffer<uint32_t>& rgba, Buffer<float>& out, int in_width, int out_width)> kLumaHalf{
    "vd_luma_half"};
// One item per pixel: the horizontal binomial pass.
inline constexpr Kernel<void(const Buffer<float>& in, Buffer<float>& out, int width)> kHBlur{"vd_hblur"};
// One item per pixel: the vertical pass.
inline constexpr Kernel<void(const Buffer<float>& in, Buffer<float>& out, int width, int height)> kVBlur{"vd_vblur"};

}  // namespace vd::ocl
