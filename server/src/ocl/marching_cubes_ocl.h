#pragma once
// The kernels of kernels/marching_cubes.cl, per-item math in shared/marching_cubes.h. One typed handle
// each (ocl/kernel.h), its parameters those of the __kernel in order; kFoo(ctx, items, args...)
// runs it over `items` work items (what one item is, above each).
#include <cstdint>

#include "ocl/kernel.h"
#include "shared/marching_cubes.h"

namespace vd::ocl {

// One item per grid row (y, z), as for every marching-cubes pass.
inline constexpr Kernel<void(const Buffer<float>& tsdf, const Buffer<float>& weight, const Buffer<uint8_t>& touched,
                             VdVolume vol, const Buffer<uint8_t>& tri_counts, Buffer<uint16_t>& codes,
                             Buffer<uint32_t>& row_tris, Buffer<uint8_t>& chunk_tris)>
    kMcClassify{"vd_mc_classify"};
// One item per grid row.
inline constexpr Kernel<void(const Buffer<float>& tsdf, const Buffer<uint16_t>& codes, const Buffer<uint32_t>& row_tris,
                             const Buffer<uint8_t>& chunk_tris, VdVolume vol, Buffer<uint8_t>& masks,
                             Buffer<uint32_t>& row_verts)>
    kMcMasks{"vd_mc_masks"};
// One item per grid row.
inline constexpr Kernel<void(const Buffer<float>& tsdf, const Buffer<uint32_t>& color, VdVolume vol,
                             const Buffer<uint8_t>& masks, const Buffer<uint32_t>& row_verts,
                             const Buffer<uint32_t>& row_vert_offset, Buffer<uint32_t>& vert_offset,
                             Buffer<vd_float4>& positions, Buffer<vd_float4>& normals,
                             Buffer<uint32_t>& colors)> kMcVertices{"vd_mc_vertices"};
// One item per grid row.
inline constexpr Kernel<void(const Buffer<uint16_t>& codes, const Buffer<uint32_t>& row_tris,
                             const Buffer<uint32_t>& row_tri_offset, const Buffer<int8_t>& tri_table,
                             const Buffer<uint8_t>& masks, const Buffer<uint32_t>& vert_offset, VdVolume vol,
                             Buffer<int32_t>& tris)> kMcTriangles{"vd_mc_triangles"};
// One item per vertex.
inline constexpr Kernel<void(const Buffer<vd_float4>& grid_pos, VdVolume vol,
                             Buffer<vd_float4>& world)> kGridToWorld{"vd_grid_to_world"};

}  // namespace vd::ocl
