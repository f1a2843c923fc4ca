#pragma once
// The kernels of kernels/features.cl, per-item math in shared/features.h. One typed handle
// each (ocl/kernel.h), its parameters those of the __kernel in order; kFoo(ctx, items, args...)
// runs it over `items` work items (what one item is, above each).
#include <cstdint>

#include "ocl/kernel.h"
#include "shared/features.h"

namespace vd::ocl {

// One item per candidate: a column of the squared-distance matrix.
inline constexpr Kernel<void(const Buffer<uint8_t>& cur, int n_cur, const Buffer<uint8_t>& cand, int n_cand,
                             Buffer<float>& dist)> kMatchDistances{"vd_match_distances"};
// One item per (frame, current feature); frames holds (begin, end) pairs (int2 in the kernel).
inline constexpr Kernel<void(const Buffer<float>& dist, int n_cur, int n_cand, const Buffer<int32_t>& frames,
                             Buffer<VdMatchBest>& out)> kMatchRows{"vd_match_rows"};
// One item per candidate.
inline constexpr Kernel<void(const Buffer<float>& dist, int n_cur, int n_cand,
                             Buffer<VdMatchBest>& out)> kMatchColumns{"vd_match_columns"};
// One item per feature.
inline constexpr Kernel<void(const Buffer<vd_float4>& canonical, const Buffer<vd_float4>& def_pos, VdVolume vol,
                             Buffer<vd_float4>& out)> kFeaturePredict{"vd_feature_predict_kernel"};
// One item per keypoint.
inline constexpr Kernel<void(const Buffer<vd_float4>& points, const Buffer<int32_t>& pixels,
                             const Buffer<uint32_t>& ids, const Buffer<vd_float4>& bary,
                             const Buffer<vd_float4>& raster_vertex, const Buffer<vd_float4>& canon,
                             const Buffer<int32_t>& tris, const Buffer<vd_float4>& def_pos, VdVolume vol,
                             VdLiftParams prm, Buffer<vd_float4>& out)> kFeatureLift{"vd_feature_lift_kernel"};

}  // namespace vd::ocl
