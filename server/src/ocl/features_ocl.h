#pragma once
// The kernels of kernels/features.cl, per-item math in shared/features.h. One typed handle
// each (ocl/kernel.h), its parameters those of the __kernel in order; kFoo(ctx, items, args...)
// runs it over `items` work items (what one item is, above each).
#include <cstdint>

#include "ocl/device_ops.h"
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
// The field's arguments are VD_FIELD_ARGS (shared/sparse_field.h): t_i, the volume, and on the
// bricks the table's hash (keys, slots, capacity) and neighbours; empty buffers on a dense grid.
inline constexpr Kernel<void(const Buffer<vd_float4>& canonical, const Buffer<vd_float4>& def_pos, VdVolume vol,
                             const Buffer<uint32_t>& keys, const Buffer<int32_t>& slots, uint32_t capacity,
                             const Buffer<int32_t>& nbr, Buffer<vd_float4>& out)>
    kFeaturePredict{"vd_feature_predict_kernel"};
// One item per keypoint.
inline constexpr Kernel<void(const Buffer<vd_float4>& points, const Buffer<int32_t>& pixels,
                             const Buffer<uint32_t>& ids, const Buffer<vd_float4>& bary,
                             const Buffer<vd_float4>& raster_vertex, const Buffer<vd_float4>& canon,
                             const Buffer<int32_t>& tris, const Buffer<vd_float4>& def_pos, VdVolume vol,
                             const Buffer<uint32_t>& keys, const Buffer<int32_t>& slots, uint32_t capacity,
                             const Buffer<int32_t>& nbr, VdLiftParams prm, Buffer<vd_float4>& out)>
    kFeatureLift{"vd_feature_lift_kernel"};

// Launchers of FeatureMatcher (core/features.cpp), which prunes the matches on the host.

// The n candidates' canonical positions deformed by the current field (w = 0 where it has none).
Status PredictFeatures(Context& ctx, size_t n, const Buffer<vd_float4>& canonical, const DeviceField& field,
                       Buffer<vd_float4>& out);
// Descriptor distances of every (current, candidate) pair, then each current feature's best
// candidate per frame (rows) and each candidate's best current feature (cols): mutual matches
// are where the two agree.
Status MatchBest(Context& ctx, const Buffer<uint8_t>& cur, int n_cur, const Buffer<uint8_t>& cand, int n_cand,
                 const Buffer<int32_t>& frames, int num_frames, Buffer<float>& dist, Buffer<VdMatchBest>& rows,
                 Buffer<VdMatchBest>& cols);
// Canonical positions of n keypoints by Newton on S(g) = f from the rendered surface's estimate.
Status LiftFeatures(Context& ctx, size_t n, const Buffer<vd_float4>& points, const Buffer<int32_t>& pixels,
                    const Buffer<uint32_t>& ids, const Buffer<vd_float4>& bary, const Buffer<vd_float4>& raster_vertex,
                    const Buffer<vd_float4>& canon, const Buffer<int32_t>& tris, const DeviceField& field,
                    VdLiftParams prm, Buffer<vd_float4>& out);

}  // namespace vd::ocl
