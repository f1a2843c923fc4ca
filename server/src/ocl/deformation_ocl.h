#pragma once
// The kernels of kernels/deformation.cl, per-item math in shared/deformation.h. One typed handle
// each (ocl/kernel.h), its parameters those of the __kernel in order; kFoo(ctx, items, args...)
// runs it over `items` work items (what one item is, above each).
#include <cstdint>

#include "ocl/kernel.h"
#include "shared/deformation.h"

namespace vd::ocl {

// One item per grid row (y, z).
inline constexpr Kernel<void(Buffer<vd_float4>& def_pos, Buffer<vd_float4>& def_rot,
                             VdVolume vol)> kDeformationReset{"vd_deformation_reset"};
// One item per vertex.
inline constexpr Kernel<void(const Buffer<vd_float4>& grid_pos, const Buffer<vd_float4>& def_pos, VdVolume vol,
                             Buffer<vd_float4>& out)> kDeformVertices{"vd_deform_vertices"};
// One item per grid point.
inline constexpr Kernel<void(Buffer<vd_float4>& def_pos, Buffer<vd_float4>& def_rot, VdPose a, vd_float4 q_a)>
    kFieldRigid{"vd_field_rigid"};
// One item per active point; writes the new state apart (ExtrapolateCommit copies it in).
inline constexpr Kernel<void(const Buffer<int32_t>& list, const Buffer<vd_float4>& def_pos,
                             const Buffer<vd_float4>& def_rot, VdVolume vol, Buffer<vd_float4>& pos_out,
                             Buffer<vd_float4>& rot_out)> kExtrapolate{"vd_extrapolate"};
// One item per member of M (the ring points write; surface: 1 at the solved points).
inline constexpr Kernel<void(const Buffer<int32_t>& list, const Buffer<uint8_t>& surface, Buffer<vd_float4>& def_pos,
                             Buffer<vd_float4>& def_rot, VdVolume vol)>
    kFollow{"vd_follow"};
// One item per active point.
inline constexpr Kernel<void(const Buffer<int32_t>& list, const Buffer<vd_float4>& pos_in,
                             const Buffer<vd_float4>& rot_in, Buffer<vd_float4>& def_pos,
                             Buffer<vd_float4>& def_rot)> kExtrapolateCommit{"vd_extrapolate_commit"};

}  // namespace vd::ocl
