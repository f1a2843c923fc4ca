#include "shared/features.h"

/* Column b of the squared-distance matrix (one candidate descriptor against all current ones:
 * the current descriptors are few and stay in cache, the candidate is read once). */
__kernel void vd_match_distances(__global const uchar* cur, int n_cur, __global const uchar* cand, int n_cand,
                                 __global float* dist, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  vd_match_distances_column(get_global_id(0), cur, n_cur, cand, n_cand, dist);
}

/* Work item (frame f, current feature a) = f * n_cur + a; frames[f] = (begin, end) in the candidates. */
__kernel void vd_match_rows(__global const float* dist, int n_cur, int n_cand, __global const int2* frames,
                            __global VdMatchBest* out, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int i = get_global_id(0);
  int2 fr = frames[i / n_cur];
  out[i] = vd_match_row(i % n_cur, fr.x, fr.y, dist, n_cand);
}

__kernel void vd_match_columns(__global const float* dist, int n_cur, int n_cand, __global VdMatchBest* out,
                               int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int b = get_global_id(0);
  out[b] = vd_match_column(b, n_cur, dist, n_cand);
}

/* Earlier features moved by the current field (world). */
__kernel void vd_feature_predict_kernel(__global const float4* canonical, VD_FIELD_ARGS, __global float4* out,
                                        int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int i = get_global_id(0);
  out[i] = vd_feature_predict(canonical[i], VD_FIELD_PASS);
}

/* points[i] = observed world point (w = 1 valid), pixels[i] = its pixel index. */
__kernel void vd_feature_lift_kernel(__global const float4* points, __global const int* pixels,
                                     __global const uint* ids, __global const float4* bary,
                                     __global const float4* raster_vertex, __global const float4* canon,
                                     __global const int* tris, VD_FIELD_ARGS, VdLiftParams prm, __global float4* out,
                                     int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int i = get_global_id(0);
  out[i] = vd_feature_lift(points[i], pixels[i], ids, bary, raster_vertex, canon, tris, VD_FIELD_PASS, prm);
}
