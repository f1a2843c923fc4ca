#include "shared/solver.h"

/* The active set on its lattice (shared/solver.h VdActive): these five arguments, in this order, on
 * every kernel that names points by their place (the host's ocl::ActiveArgs). */
#define VD_ACTIVE_ARGS                                                                                  \
  VdLattice lat, __global const int *lat_nbr, __global const uint *slot_keys, __global const int *list, \
      __global const int *compact
#define VD_ACTIVE vd_active(lat, lat_nbr, slot_keys, list, compact)

/* Copies the deformation of the active points into compact arrays (x: position, rot: quaternion). */
__kernel void vd_solver_gather_state(__global const int* list, __global const float4* def_pos,
                                     __global const float4* def_rot, __global float4* x, __global float4* rot,
                                     int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int k = get_global_id(0);
  x[k] = def_pos[list[k]];
  rot[k] = def_rot[list[k]];
}

/* Writes the solved state back; w of the position counts the optimisations the point took part in. */
__kernel void vd_solver_scatter_state(__global const int* list, __global const float4* x, __global const float4* rot,
                                      __global float4* def_pos, __global float4* def_rot, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int k = get_global_id(0);
  int i = list[k];
  float4 p = x[k];
  p.w = def_pos[i].w + 1.0f;
  def_pos[i] = p;
  def_rot[i] = rot[k];
}

/* vd_count_optimisation for each listed point. */
__kernel void vd_solver_count_state(__global const int* list, __global float4* def_pos, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  vd_count_optimisation(get_global_id(0), list, def_pos);
}

/* Counting sort of the per-pixel constraints by cell: count, then (after a scan) scatter. */
__kernel void vd_constraint_count(__global const VdCorrespondence* corr, __global const int* compact, VdVolume vol,
                                  __global int* cell_of, __global uint* counts, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int i = get_global_id(0);
  int kc = vd_constraint_cell(corr[i], compact, vol);
  cell_of[i] = kc;
  if (kc >= 0) atomic_inc(&counts[kc]);
}

/* Each constraint takes a place in its cell's range of order[] (in whatever order the atomics
 * give; vd_constraint_order then fixes it). */
__kernel void vd_constraint_scatter(__global const int* cell_of, __global const uint* cell_start, __global uint* cursor,
                                    __global int* order, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int i = get_global_id(0);
  int kc = cell_of[i];
  if (kc < 0) return;
  order[cell_start[kc] + atomic_inc(&cursor[kc])] = i;
}

/* One item per cell: its constraints in input order, copied into place with their cell. */
__kernel void vd_constraint_order(__global const VdCorrespondence* corr, __global const uint* cell_start,
                                  __global int* order, __global VdCorrespondence* sorted, __global int* sorted_cell,
                                  int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  vd_constraint_order_cell(get_global_id(0), corr, cell_start, order, sorted, sorted_cell);
}

__kernel void vd_constraint_targets(__global const VdCorrespondence* cons, __global float* targets, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int c = get_global_id(0);
  targets[c] = vd_constraint_target(cons[c]);
}

__kernel void vd_constraint_residuals(__global const VdCorrespondence* cons, __global const int* sorted_cell,
                                      VD_ACTIVE_ARGS, __global const float4* d, __global float* r, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int c = get_global_id(0);
  r[c] = vd_constraint_apply(cons[c], sorted_cell[c], VD_ACTIVE, d);
}

/* Once per solve: the constraint-only part of b and the preconditioner. */
__kernel void vd_system_data_diag_kernel(VD_ACTIVE_ARGS, __global const int* neighbours, __global const float* edge_w,
                                         __global const VdCorrespondence* cons, __global const uint* cell_start,
                                         __global const float* targets, VdSolverWeights w, __global float4* data_rhs,
                                         __global VdMat3* diag_inv, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int k = get_global_id(0);
  VdMat3 inv;
  data_rhs[k] = vd_system_data_diag(k, VD_ACTIVE, neighbours, edge_w, cons, cell_start, targets, w, &inv);
  diag_inv[k] = inv;
}

/* Every position step: b from the current rotations. */
__kernel void vd_system_rhs_kernel(float spacing, __global const int* neighbours, __global const float* edge_w,
                                   __global const float4* rot, __global const float4* data_rhs,
                                   __global const float4* x_prev, VdSolverWeights w, __global float4* b, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int k = get_global_id(0);
  b[k] = vd_system_rhs(k, spacing, neighbours, edge_w, rot, data_rhs, x_prev, w);
}

__kernel void vd_system_apply_kernel(VD_ACTIVE_ARGS, __global const int* neighbours, __global const float* edge_w,
                                     __global const VdCorrespondence* cons, __global const uint* cell_start,
                                     __global const float* r, __global const float4* d, VdSolverWeights w,
                                     __global float4* q, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int k = get_global_id(0);
  q[k] = vd_system_apply(k, VD_ACTIVE, neighbours, edge_w, cons, cell_start, r, d, w);
}

/* Cached B^T B: built once per solve (moments per cell, then per point), applied every PCG
 * iteration. vd_cell_moments_kernel: one item per active point, as the first corner of a cell. */
__kernel void vd_cell_moments_kernel(VD_ACTIVE_ARGS, __global const VdCorrespondence* cons,
                                     __global const uint* cell_start, __global float* moments, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  vd_cell_moments(get_global_id(0), VD_ACTIVE, cons, cell_start, moments);
}

__kernel void vd_btb_assemble_kernel(VD_ACTIVE_ARGS, __global const int* neighbours, __global const float* edge_w,
                                     __global const float* moments, VdSolverWeights w, __global const float4* x0,
                                     int shift, __global float* blocks, __global int* nbr, __global float4* data_rhs,
                                     __global VdMat3* diag_inv, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int k = get_global_id(0);
  VdMat3 inv;
  data_rhs[k] = vd_btb_assemble(k, VD_ACTIVE, neighbours, edge_w, moments, w, x0, shift, blocks, nbr, &inv);
  diag_inv[k] = inv;
}

__kernel void vd_system_apply_cached_kernel(__global const float* blocks, __global const int* nbr,
                                            __global const float4* d, __global float4* q, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int k = get_global_id(0);
  q[k] = vd_system_apply_cached(k, blocks, nbr, d);
}

/* PCG vector updates. */
__kernel void vd_pcg_precondition(__global const VdMat3* diag_inv, __global const float4* r, __global float4* z,
                                  int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int k = get_global_id(0);
  z[k] = vd_mat3_apply(diag_inv[k], r[k]);
}

/* y = a * x + y (xyz only). */
__kernel void vd_axpy4(float a, __global const float4* x, __global float4* y, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int k = get_global_id(0);
  float4 v = y[k] + a * x[k];
  v.w = y[k].w;
  y[k] = v;
}

/* y = b - y (xyz only): the initial residual from b and A x0. */
__kernel void vd_sub_from4(__global const float4* b, __global float4* y, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int k = get_global_id(0);
  float4 v = b[k] - y[k];
  v.w = 0.0f;
  y[k] = v;
}

/* Chunked partial sums of dot3(a, b); the host adds the partials in double precision. */
__kernel void vd_dot4_partial(__global const float4* a, __global const float4* b, int n, int chunk,
                              __global float* partials, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int g = get_global_id(0);
  float s = 0.0f;
  for (int k = g * chunk; k < min(n, (g + 1) * chunk); ++k) s += vd_dot3(a[k], b[k]);
  partials[g] = s;
}

/* One item: the PCG scalars from partial sums (shared/solver.h, VD_PCG_SET_*). */
__kernel void vd_pcg_scalars_kernel(__global const float* partials, int groups, int mode, float tolerance,
                                    __global float* scal, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  vd_pcg_scalars(partials, groups, mode, tolerance, scal);
}

/* Work-group sums of n (1 or 3) values per item at partials[n g + i], item 0 adding the group's
 * items in order (the CPU references add them in the same order). Every item of the group reaches
 * the barrier: items past the range contribute zeros. */
void vd_pcg_group_sums(__local float* buf, const float* v, int n, __global float* partials) {
  int l = get_local_id(0);
  for (int i = 0; i < n; ++i) buf[n * l + i] = v[i];
  barrier(CLK_LOCAL_MEM_FENCE);
  if (l != 0) return;
  float acc[3] = {0.0f, 0.0f, 0.0f};
  for (int j = 0; j < VD_PCG_GROUP; ++j)
    for (int i = 0; i < n; ++i) acc[i] += buf[n * j + i];
  for (int i = 0; i < n; ++i) partials[n * get_group_id(0) + i] = acc[i];
}

/* w = A u from the cached blocks and the group sums of (r.u, w.u, r.r): the product and the
 * iteration's one reduction in one pass. */
__kernel __attribute__((reqd_work_group_size(VD_PCG_GROUP, 1, 1))) void vd_pcg_apply_dots_kernel(
    __global const float* scal, __global const float* blocks, __global const int* nbr, __global const float4* r,
    __global const float4* u, __global float4* w, __global float* partials, int vd_items) {
  __local float buf[3 * VD_PCG_GROUP];
  if (vd_pcg_done(scal)) return; /* the same for every item: no barrier is left waiting */
  int k = get_global_id(0);
  float v[3] = {0.0f, 0.0f, 0.0f};
  if (k < vd_items) {
    w[k] = vd_system_apply_cached(k, blocks, nbr, u);
    vd_pcg_dots(k, r, u, w, v);
  }
  vd_pcg_group_sums(buf, v, 3, partials);
}

/* The same group sums after a product applied elsewhere (the constraints' path). */
__kernel __attribute__((reqd_work_group_size(VD_PCG_GROUP, 1, 1))) void vd_pcg_dots_kernel(__global const float4* r,
                                                                                           __global const float4* u,
                                                                                           __global const float4* w,
                                                                                           __global float* partials,
                                                                                           int vd_items) {
  __local float buf[3 * VD_PCG_GROUP];
  int k = get_global_id(0);
  float v[3] = {0.0f, 0.0f, 0.0f};
  if (k < vd_items) vd_pcg_dots(k, r, u, w, v);
  vd_pcg_group_sums(buf, v, 3, partials);
}

/* The start of a position step (vd_pcg_start), with the group sums of b.b. */
__kernel __attribute__((reqd_work_group_size(VD_PCG_GROUP, 1, 1))) void vd_pcg_start_kernel(
    float spacing, __global const int* neighbours, __global const float* edge_w, __global const float4* rot,
    __global const float4* data_rhs, VdSolverWeights w, __global const float* blocks, __global const int* nbr,
    __global const VdMat3* diag_inv, __global const float4* x, __global float4* r, __global float4* u,
    __global float* partials, int vd_items) {
  __local float buf[VD_PCG_GROUP];
  int k = get_global_id(0);
  float bb = 0.0f;
  if (k < vd_items) bb = vd_pcg_start(k, spacing, neighbours, edge_w, rot, data_rhs, w, blocks, nbr, diag_inv, x, r, u);
  vd_pcg_group_sums(buf, &bb, 1, partials);
}

/* One update per point, with the group sums of the new r.r. */
__kernel __attribute__((reqd_work_group_size(VD_PCG_GROUP, 1, 1))) void vd_pcg_cg_update_kernel(
    __global const float* scal, __global const VdMat3* diag_inv, __global const float4* w, __global float4* p,
    __global float4* s, __global float4* x, __global float4* r, __global float4* u, __global float* partials,
    int vd_items) {
  __local float buf[VD_PCG_GROUP];
  if (vd_pcg_done(scal)) return; /* the same for every item */
  int k = get_global_id(0);
  float rr = 0.0f;
  if (k < vd_items) rr = vd_pcg_cg_update(k, scal, diag_inv, w, p, s, x, r, u);
  vd_pcg_group_sums(buf, &rr, 1, partials);
}

/* Energy partial sums: dense term per chunk of constraints, ARAP per chunk of points. */
__kernel void vd_energy_dense_partial(__global const VdCorrespondence* cons, __global const int* sorted_cell, int n,
                                      int chunk, VD_ACTIVE_ARGS, __global const float4* x, __global float* partials,
                                      int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int g = get_global_id(0);
  float s = 0.0f;
  for (int c = g * chunk; c < min(n, (g + 1) * chunk); ++c)
    s += vd_constraint_energy(cons[c], sorted_cell[c], VD_ACTIVE, x);
  partials[g] = s;
}

__kernel void vd_energy_arap_partial(__global const int* neighbours, __global const float* edge_w, float spacing,
                                     __global const float4* x, __global const float4* rot, int n, int chunk,
                                     __global float* partials, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  int g = get_global_id(0);
  float s = 0.0f;
  for (int k = g * chunk; k < min(n, (g + 1) * chunk); ++k) s += vd_arap_energy(k, neighbours, edge_w, spacing, x, rot);
  partials[g] = s;
}

/* Rest (undeformed) positions of the active points, for the rotation step. */
__kernel void vd_solver_rest(VD_ACTIVE_ARGS, __global float4* t_hat, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  t_hat[get_global_id(0)] = vd_active_rest(VD_ACTIVE, get_global_id(0));
}

/* Adaptive rigidity: the ARAP weights of each active point's six edges from the field's strain. */
__kernel void vd_arap_edge_weights_kernel(__global const int* neighbours, __global const float4* x,
                                          __global const float4* rot, __global const float4* t_hat, float scale2,
                                          float floor_w, __global float* edge_w, int vd_items) {
  if ((int)get_global_id(0) >= vd_items) return;
  vd_arap_edge_weights(get_global_id(0), neighbours, x, rot, t_hat, scale2, floor_w, edge_w);
}
