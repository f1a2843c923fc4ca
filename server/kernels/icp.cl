#include "shared/icp.h"

/* One work item sums `chunk` consecutive pixels into its own VD_ICP_ACC partial sums; the host
 * adds the partials in double precision. */
__kernel void vd_icp_reduce(__global const float4* vmap, __global const float4* nmap,
                            __global const float4* model_v, __global const float4* model_n, int n, int chunk,
                            VdIcpParams prm, __global float* partials, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int g = get_global_id(0);
  float acc[VD_ICP_ACC];
  for (int k = 0; k < VD_ICP_ACC; ++k) acc[k] = 0.0f;
  int b = g * chunk, e = min(b + chunk, n);
  for (int i = b; i < e; ++i) vd_icp_pixel(vmap, nmap, model_v, model_n, i, prm, acc);
  for (int k = 0; k < VD_ICP_ACC; ++k) partials[g * VD_ICP_ACC + k] = acc[k];
}
