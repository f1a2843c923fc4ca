// The launchers of kernels/hierarchy.cl that HierarchicalSolver (core/hierarchy.cpp) calls.
#include "ocl/hierarchy_ocl.h"

namespace vd::ocl {

Status MarkLevel(Context& ctx, size_t n, const Buffer<int32_t>& list_f, VdVolume fine, int s, VdVolume coarse,
                 Buffer<uint8_t>& member) {
  return kLevelMark(ctx, n, list_f, fine, s, coarse, member);
}

Status CountLevelRows(Context& ctx, const Buffer<uint8_t>& member, VdVolume coarse, Buffer<uint32_t>& row_count) {
  return kLevelRowCount(ctx, size_t(coarse.dim_y) * coarse.dim_z, member, coarse, row_count);
}

Status RestrictState(Context& ctx, size_t n, const Buffer<int32_t>& list_c, VdVolume coarse, int s,
                     const Buffer<int32_t>& compact_f, VdVolume fine, const Buffer<vd_float4>& x_f,
                     const Buffer<vd_float4>& rot_f, Buffer<vd_float4>& x0_c, Buffer<vd_float4>& rot_c) {
  return kLevelRestrict(ctx, n, list_c, coarse, s, compact_f, fine, x_f, rot_f, x0_c, rot_c);
}

Status RestrictConstraints(Context& ctx, size_t n, const Buffer<VdCorrespondence>& cons_f,
                           const Buffer<int32_t>& compact_f, VdVolume fine, const Buffer<vd_float4>& x_f, int s,
                           const Buffer<int32_t>& compact_c, VdVolume coarse, const Buffer<vd_float4>& x0_c,
                           Buffer<VdCorrespondence>& cons_c) {
  return kLevelConstraints(ctx, n, cons_f, compact_f, fine, x_f, s, compact_c, coarse, x0_c, cons_c);
}

Status LevelMoments(Context& ctx, size_t n, const Buffer<int32_t>& list_c, VdVolume coarse, int s,
                    const Buffer<int32_t>& compact_f, VdVolume fine, const Buffer<VdCorrespondence>& cons,
                    const Buffer<uint32_t>& cell_start, const Buffer<vd_float4>& x_f, Buffer<float>& moments_c) {
  return kLevelMoments(ctx, n, list_c, coarse, s, compact_f, fine, cons, cell_start, x_f, moments_c);
}

Status ProlongateIncrement(Context& ctx, size_t n, const Buffer<int32_t>& list_f, VdVolume fine, int s,
                           const Buffer<int32_t>& compact_c, VdVolume coarse, const Buffer<vd_float4>& x_c,
                           const Buffer<vd_float4>& x0_c, Buffer<vd_float4>& x_f) {
  return kLevelProlongate(ctx, n, list_f, fine, s, compact_c, coarse, x_c, x0_c, x_f);
}

}  // namespace vd::ocl
