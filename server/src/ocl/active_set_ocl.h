#pragma once
// The kernels of kernels/active_set.cl, per-item math in shared/active_set.h. One typed handle
// each (ocl/kernel.h), its parameters those of the __kernel in order; kFoo(ctx, items, args...)
// runs it over `items` work items (what one item is, above each).
#include <cstdint>

#include "ocl/kernel.h"
#include "shared/active_set.h"

namespace vd {
struct DeviceActiveSet;
}  // namespace vd

namespace vd::ocl {

// One item per grid row (y, z).
inline constexpr Kernel<void(const Buffer<uint16_t>& codes, const Buffer<uint8_t>& tri_counts,
                             const Buffer<uint32_t>& row_tris, const Buffer<uint8_t>& chunk_tris, VdVolume vol,
                             Buffer<uint8_t>& surface, Buffer<uint32_t>& row_surface)>
    kActiveSurface{"vd_active_surface"};
// One item per row of row_len points (a dense grid row, or 8 points of a brick).
inline constexpr Kernel<void(const Buffer<uint8_t>& surface, const Buffer<uint32_t>& row_surface,
                             const Buffer<vd_float4>& def_pos, int32_t row_len, VdCamera cam, VdPose world_to_cam,
                             float margin, Buffer<uint8_t>& solved, Buffer<uint32_t>& row_solved)>
    kActiveInView{"vd_active_in_view"};
// One item per grid row.
inline constexpr Kernel<void(const Buffer<uint8_t>& surface, const Buffer<uint32_t>& row_surface, VdVolume vol,
                             Buffer<uint8_t>& member, Buffer<uint32_t>& row_count)> kActiveDilate{"vd_active_dilate"};
// One item per grid row.
inline constexpr Kernel<void(const Buffer<uint8_t>& member, const Buffer<uint32_t>& row_offset, VdVolume vol,
                             int members_only, Buffer<int32_t>& list, Buffer<int32_t>& compact)>
    kActiveCompact{"vd_active_compact"};
// One item per member of the previous active set.
inline constexpr Kernel<void(const Buffer<int32_t>& list, Buffer<int32_t>& compact)> kActiveUnmark{"vd_active_unmark"};
// One item per active point.
inline constexpr Kernel<void(const Buffer<int32_t>& list, const Buffer<int32_t>& compact, VdVolume vol,
                             Buffer<int32_t>& neighbours)> kActiveNeighbours{"vd_active_neighbours"};


// The member list, dense -> compact map and neighbour table of the active set `out` of grid `vol`
// from its membership flags and their per-row exclusive scan; out->count already holds the total.
// DeviceOps::BuildActiveSet and each level of the hierarchy (core/hierarchy.cpp) end with it.
Status CompactActiveSet(Context& ctx, const Buffer<uint8_t>& member, const Buffer<uint32_t>& row_offset, VdVolume vol,
                        DeviceActiveSet* out);

}  // namespace vd::ocl
