#pragma once
// The kernels of kernels/correspondence.cl, per-item math in shared/correspondence.h. One typed handle
// each (ocl/kernel.h), its parameters those of the __kernel in order; kFoo(ctx, items, args...)
// runs it over `items` work items (what one item is, above each).
#include <cstdint>

#include "ocl/kernel.h"
#include "shared/correspondence.h"

namespace vd::ocl {

// One item per pixel; owners: the mesh's DeviceMesh::brick_slots, or empty (no hints).
inline constexpr Kernel<void(const Buffer<vd_float4>& model_v, const Buffer<vd_float4>& model_n,
                             const Buffer<uint32_t>& ids, const Buffer<vd_float4>& bary, const Buffer<vd_float4>& obs_v,
                             const Buffer<vd_float4>& obs_n, const Buffer<vd_float4>& canon,
                             const Buffer<int32_t>& tris, const Buffer<int32_t>& owners, VdCorrParams prm,
                             Buffer<VdCorrespondence>& out)>
    kCorrespondences{"vd_correspondences"};
// One item per 2x2 block b of the n pixels: writes out[n + b] from its first pixel's depth row
// (shared/correspondence.h vd_photo_pixel).
inline constexpr Kernel<void(const Buffer<vd_float4>& model_v, const Buffer<vd_float4>& obs_v,
                             const Buffer<uint32_t>& ids, const Buffer<vd_float4>& bary, const Buffer<uint32_t>& colors,
                             const Buffer<int32_t>& tris, const Buffer<float>& intensity, VdPhotoParams prm,
                             Buffer<VdCorrespondence>& out)>
    kPhotometricCorrespondences{"vd_photometric_correspondences"};

}  // namespace vd::ocl
