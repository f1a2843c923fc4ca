#pragma once
// CPU references of the feature kernels (server/kernels/features.cl): the same per-item functions
// of shared/features.h looped on the host.
#include <cstdint>
#include <vector>

#include "shared/features.h"

namespace vd::cpu {

// The squared-distance matrix (n_cur x n_cand, row-major) of two descriptor sets; cand_t in the
// transposed layout (vd_desc_transpose).
void MatchDistances(const uint8_t* cur, int n_cur, const uint8_t* cand_t, int n_cand, float* dist);
// Row scans per (frame f, current feature a), item f * n_cur + a; frames as (begin, end) pairs.
void MatchRows(const float* dist, int n_cur, int n_cand, const int32_t* frames, int num_frames, VdMatchBest* out);
void MatchColumns(const float* dist, int n_cur, int n_cand, VdMatchBest* out);
// The field (VD_FIELD_ARGS, shared/sparse_field.h): a dense grid's without keys; the brick pool's
// with the table's hash (keys, slots, capacity) and neighbour table.
void FeaturePredict(const vd_float4* canonical, int n, const vd_float4* def_pos, VdVolume vol, vd_float4* out,
                    const uint32_t* keys = nullptr, const int32_t* slots = nullptr, uint32_t capacity = 0,
                    const int32_t* nbr = nullptr);
void FeatureLift(const vd_float4* points, const int32_t* pixels, int n, const uint32_t* ids, const vd_float4* bary,
                 const vd_float4* raster_vertex, const vd_float4* canon, const int32_t* tris, const vd_float4* def_pos,
                 VdVolume vol, VdLiftParams params, vd_float4* out, const uint32_t* keys = nullptr,
                 const int32_t* slots = nullptr, uint32_t capacity = 0, const int32_t* nbr = nullptr);

}  // namespace vd::cpu
