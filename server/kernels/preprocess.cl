#include "shared/preprocess.h"

__kernel void vd_depth_convert(__global const ushort* raw, __global float* depth, float inv_scale, float min_depth,
                               float max_depth, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int i = get_global_id(0);
  depth[i] = vd_depth_convert_pixel(raw[i], inv_scale, min_depth, max_depth);
}

/* vd_bilateral_pixel for VD_LANES consecutive pixels per work item (a kLaned launch), the taps of
 * all lanes at once. Where the lanes lie in one row with the whole window inside the image (all
 * but the image's edges), each tap is one contiguous load; elsewhere each lane gathers its own and
 * taps outside the image weigh 0, as the per-pixel loop's clamped window leaves them out. The sums
 * add the same terms in the same order (plus exact zeros), so both paths agree with the reference
 * up to exp(). With one lane, the reference's own loop. */
__kernel void vd_bilateral(__global const float* in, __global float* out, int width, int height, int radius,
                           float inv_2sigma_space2, float inv_2sigma_depth2, int vd_items) {
#if VD_LANES == 1
  /* One lane (a GPU): the per-pixel loop over the clamped window. */
  if ((int)get_global_id(0) >= vd_items) return;
  int i = get_global_id(0);
  out[i] = vd_bilateral_pixel(in, width, height, i % width, i / width, radius, inv_2sigma_space2, inv_2sigma_depth2);
#else
  int base = (int)get_global_id(0) * VD_LANES;
  if (base >= vd_items) return;
  int xs[VD_LANES], ys[VD_LANES];
  float v[VD_LANES];
  VD_UNROLL
  for (int l = 0; l < VD_LANES; ++l) {
    int i = min(base + l, vd_items - 1); /* lanes past the end repeat the last pixel, unstored */
    xs[l] = i % width;
    ys[l] = i / width;
    v[l] = in[i];
  }
  vd_lf d0 = vd_lload(v);
  int full = base + VD_LANES <= vd_items;
  /* No valid centre among the lanes (background, holes): every output is 0, as below; no taps. */
  if (full && !any(d0 > 0.0f)) {
    vd_lstore((vd_lf)0.0f, out + base);
    return;
  }
  int row = ys[0];
  int contiguous = full && ys[VD_LANES - 1] == row && xs[0] - radius >= 0 && xs[VD_LANES - 1] + radius < width;
  vd_lf sum = 0.0f, wsum = 0.0f;
  for (int dy = -radius; dy <= radius; ++dy) {
    for (int dx = -radius; dx <= radius; ++dx) {
      vd_lf d;
      if (contiguous) {
        int yy = row + dy;
        if (yy < 0 || yy >= height) continue; /* the whole row is outside: all weights 0 */
        d = vd_lload(in + yy * width + xs[0] + dx);
      } else {
        VD_UNROLL
        for (int l = 0; l < VD_LANES; ++l) {
          int xx = xs[l] + dx, yy = ys[l] + dy;
          v[l] = xx >= 0 && xx < width && yy >= 0 && yy < height ? in[yy * width + xx] : 0.0f;
        }
        d = vd_lload(v);
      }
      vd_lf w = vd_lsel((vd_lf)0.0f,
                        VD_BILATERAL_WEIGHT(d - d0, (float)(dx * dx + dy * dy), inv_2sigma_space2, inv_2sigma_depth2),
                        d > 0.0f);
      sum += w * d;
      wsum += w;
    }
  }
  vd_lf r = vd_lsel((vd_lf)0.0f, sum / wsum, d0 > 0.0f);
  if (full) {
    vd_lstore(r, out + base);
  } else {
    vd_lstore(r, v);
    for (int l = 0; base + l < vd_items; ++l) out[base + l] = v[l];
  }
#endif
}

__kernel void vd_pyr_down(__global const float* in, __global float* out, int in_width, int out_width, float max_diff,
                          int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int i = get_global_id(0);
  out[i] = vd_pyr_down_pixel(in, in_width, i % out_width, i / out_width, max_diff);
}

__kernel void vd_vertex_map(__global const float* depth, __global float4* vmap, VdCamera cam, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int i = get_global_id(0);
  vmap[i] = vd_vertex_pixel(depth, cam, i % cam.width, i / cam.width);
}

__kernel void vd_normal_map(__global const float4* vmap, __global float4* nmap, int width, int height, float max_jump,
                            int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int i = get_global_id(0);
  nmap[i] = vd_normal_pixel(vmap, width, height, i % width, i / width, max_jump);
}

__kernel void vd_luma_half(__global const uint* rgba, __global float* out, int in_width, int out_width, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int i = get_global_id(0);
  out[i] = vd_luma_half_pixel(rgba, in_width, i % out_width, i / out_width);
}

__kernel void vd_vblur(__global const float* in, __global float* out, int width, int height, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int i = get_global_id(0);
  out[i] = vd_vblur_pixel(in, width, height, i % width, i / width);
}

__kernel void vd_hblur(__global const float* in, __global float* out, int width, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int i = get_global_id(0);
  out[i] = vd_hblur_pixel(in, width, i % width, i / width);
}
