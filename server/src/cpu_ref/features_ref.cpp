#include "cpu_ref/features_ref.h"

namespace vd::cpu {

void MatchDistances(const uint8_t* cur, int n_cur, const uint8_t* cand_t, int n_cand, float* dist) {
#pragma omp parallel for schedule(static)
  for (int b = 0; b < n_cand; ++b) vd_match_distances_column(b, cur, n_cur, cand_t, n_cand, dist);
}

void MatchRows(const float* dist, int n_cur, int n_cand, const int32_t* frames, int num_frames, VdMatchBest* out) {
  const int n = n_cur * num_frames;
#pragma omp parallel for schedule(static)
  for (int i = 0; i < n; ++i) {
    const int f = i / n_cur;
    out[i] = vd_match_row(i % n_cur, frames[2 * f], frames[2 * f + 1], dist, n_cand);
  }
}

void MatchColumns(const float* dist, int n_cur, int n_cand, VdMatchBest* out) {
#pragma omp parallel for schedule(static)
  for (int b = 0; b < n_cand; ++b) out[b] = vd_match_column(b, n_cur, dist, n_cand);
}

void FeaturePredict(const vd_float4* canonical, int n, const vd_float4* def_pos, VdVolume vol, vd_float4* out,
                    const uint32_t* keys, const int32_t* slots, uint32_t capacity, const int32_t* nbr) {
  for (int i = 0; i < n; ++i) out[i] = vd_feature_predict(canonical[i], def_pos, vol, keys, slots, capacity, nbr);
}

void FeatureLift(const vd_float4* points, const int32_t* pixels, int n, const uint32_t* ids, const vd_float4* bary,
                 const vd_float4* raster_vertex, const vd_float4* canon, const int32_t* tris, const vd_float4* def_pos,
                 VdVolume vol, VdLiftParams params, vd_float4* out, const uint32_t* keys, const int32_t* slots,
                 uint32_t capacity, const int32_t* nbr) {
  for (int i = 0; i < n; ++i)
    out[i] = vd_feature_lift(points[i], pixels[i], ids, bary, raster_vertex, canon, tris, def_pos, vol, keys, slots,
                             capacity, nbr, params);
}

}  // namespace vd::cpu
