// The launchers of kernels/features.cl that FeatureMatcher (core/features.cpp) calls.
#include "ocl/features_ocl.h"

namespace vd::ocl {

Status PredictFeatures(Context& ctx, size_t n, const Buffer<vd_float4>& canonical, const DeviceField& field,
                       Buffer<vd_float4>& out) {
  return kFeaturePredict(ctx, n, canonical, *field.def_pos, field.vol, *field.keys, *field.slots, field.capacity,
                         *field.nbr, out);
}

Status MatchBest(Context& ctx, const Buffer<uint8_t>& cur, int n_cur, const Buffer<uint8_t>& cand, int n_cand,
                 const Buffer<int32_t>& frames, int num_frames, Buffer<float>& dist, Buffer<VdMatchBest>& rows,
                 Buffer<VdMatchBest>& cols) {
  VD_RETURN_IF_ERROR(kMatchDistances(ctx, size_t(n_cand), cur, n_cur, cand, n_cand, dist));
  VD_RETURN_IF_ERROR(kMatchRows(ctx, size_t(n_cur) * num_frames, dist, n_cur, n_cand, frames, rows));
  return kMatchColumns(ctx, size_t(n_cand), dist, n_cur, n_cand, cols);
}

Status LiftFeatures(Context& ctx, size_t n, const Buffer<vd_float4>& points, const Buffer<int32_t>& pixels,
                    const Buffer<uint32_t>& ids, const Buffer<vd_float4>& bary, const Buffer<vd_float4>& raster_vertex,
                    const Buffer<vd_float4>& canon, const Buffer<int32_t>& tris, const DeviceField& field,
                    VdLiftParams prm, Buffer<vd_float4>& out) {
  return kFeatureLift(ctx, n, points, pixels, ids, bary, raster_vertex, canon, tris, *field.def_pos, field.vol,
                      *field.keys, *field.slots, field.capacity, *field.nbr, prm, out);
}

}  // namespace vd::ocl
