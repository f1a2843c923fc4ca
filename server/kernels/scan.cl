/* Exclusive prefix sum in two passes over fixed-size chunks: each work item sums one chunk, the
 * chunk sums are scanned (recursively, by the host launcher), then each work item writes its
 * chunk's prefix. Serial inner loops read contiguous memory, which suits CPU devices; a GPU
 * gets one work item per chunk, plenty for the multi-million element arrays scanned here. */
__kernel void vd_scan_sums(__global const uint* in, uint n, uint chunk, __global uint* sums, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  uint g = get_global_id(0);
  uint b = g * chunk, e = min(b + chunk, n);
  uint s = 0;
  for (uint i = b; i < e; ++i) s += in[i];
  sums[g] = s;
}

/* out has n + 1 entries: out[n] receives the total. offsets == 0 means no chunk offsets. */
__kernel void vd_scan_apply(__global const uint* in, uint n, uint chunk, __global const uint* offsets,
                            uint use_offsets, __global uint* out, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  uint g = get_global_id(0);
  uint b = g * chunk, e = min(b + chunk, n);
  uint s = use_offsets ? offsets[g] : 0u;
  for (uint i = b; i < e; ++i) {
    uint v = in[i];
    out[i] = s;
    s += v;
  }
  if (e == n) out[n] = s;
}
