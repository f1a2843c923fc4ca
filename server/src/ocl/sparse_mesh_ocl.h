#pragma once
// The kernels of kernels/sparse_mesh.cl (marching cubes over the brick pool), per-item math in
// shared/sparse_mesh.h. One item per row of 8 cells of a pool slot (slot * 64 + y + 8 z).
#include <cstdint>

#include "ocl/kernel.h"
#include "shared/sparse_mesh.h"

namespace vd::ocl {

// One item per slot: which slots hold a brick with weight (the others are skipped below).
inline constexpr Kernel<void(const Buffer<float>& weight, const Buffer<int32_t>& nbr, Buffer<uint8_t>& weighted)>
    kSparseMcWeighted{"vd_sparse_mc_weighted"};
inline constexpr Kernel<void(const Buffer<float>& tsdf, const Buffer<float>& weight, const Buffer<int32_t>& nbr,
                             const Buffer<uint8_t>& weighted, const Buffer<uint8_t>& tri_counts,
                             Buffer<uint16_t>& codes, Buffer<uint32_t>& row_tris)>
    kSparseMcClassify{"vd_sparse_mc_classify"};
inline constexpr Kernel<void(const Buffer<float>& tsdf, const Buffer<uint16_t>& codes, const Buffer<int32_t>& nbr,
                             const Buffer<uint8_t>& weighted, const Buffer<uint32_t>& row_tris, Buffer<uint8_t>& masks,
                             Buffer<uint32_t>& row_verts)>
    kSparseMcMasks{"vd_sparse_mc_masks"};
inline constexpr Kernel<void(const Buffer<float>& tsdf, const Buffer<uint32_t>& color, const Buffer<int32_t>& nbr,
                             const Buffer<uint32_t>& slot_keys, const Buffer<uint8_t>& masks,
                             const Buffer<uint32_t>& row_verts, const Buffer<uint32_t>& row_vert_offset,
                             Buffer<vd_float4>& positions, Buffer<vd_float4>& normals, Buffer<uint32_t>& colors,
                             Buffer<int32_t>& owners)>
    kSparseMcVertices{"vd_sparse_mc_vertices"};
inline constexpr Kernel<void(const Buffer<uint16_t>& codes, const Buffer<uint32_t>& row_tris,
                             const Buffer<uint32_t>& row_tri_offset, const Buffer<int8_t>& tri_table,
                             const Buffer<uint8_t>& masks, const Buffer<uint32_t>& row_vert_offset,
                             const Buffer<int32_t>& nbr, Buffer<int32_t>& tris)>
    kSparseMcTriangles{"vd_sparse_mc_triangles"};

// The active set over the pool: one item per row of 8 points of a slot, then one per member.
inline constexpr Kernel<void(const Buffer<uint16_t>& codes, const Buffer<uint8_t>& tri_counts,
                             const Buffer<uint32_t>& row_tris, const Buffer<int32_t>& nbr, Buffer<uint8_t>& surface)>
    kSparseActiveSurface{"vd_sparse_active_surface"};
inline constexpr Kernel<void(const Buffer<uint8_t>& surface, const Buffer<int32_t>& nbr, Buffer<uint8_t>& member)>
    kSparseActiveDilate{"vd_sparse_active_dilate"};
// One item per row of 8 points: its members.
inline constexpr Kernel<void(const Buffer<uint8_t>& member, Buffer<uint32_t>& row_count)> kSparseActiveRows{
    "vd_sparse_active_rows"};
inline constexpr Kernel<void(const Buffer<uint8_t>& member, const Buffer<uint32_t>& row_offset, Buffer<int32_t>& list,
                             Buffer<int32_t>& compact)>
    kSparseActiveCompact{"vd_sparse_active_compact"};
inline constexpr Kernel<void(const Buffer<int32_t>& list, const Buffer<int32_t>& compact, const Buffer<int32_t>& nbr,
                             Buffer<int32_t>& neighbours)>
    kSparseActiveNeighbours{"vd_sparse_active_neighbours"};

}  // namespace vd::ocl
