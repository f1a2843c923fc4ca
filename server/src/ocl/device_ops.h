#pragma once
// Launchers of the OpenCL kernels: each mirrors a function of cpu_ref.h on device buffers.
// Scratch buffers are owned here and grow only, so nothing is allocated per frame once warm.
// Each method is defined in the <family>_ocl.cpp of the kernels it launches (IntegrateTsdf in
// tsdf_ocl.cpp, ...); allocation in device_ops.cpp.
#include <cstdint>

#include "ocl/ocl.h"
#include "shared/correspondence.h"
#include "shared/icp.h"
#include "shared/lattice.h"
#include "shared/raster.h"
#include "shared/tsdf.h"
#include "shared/vd_types.h"

namespace vd {
namespace ocl {
class BrickTable;
struct BrickPool;
}  // namespace ocl

// The unified grid (VolumeDeform section 4), structure of arrays. Bytes per grid point: 4 (D_i) +
// 4 (W_i) + 4 (C_i, RGBA8 with A = colour weight) = 12 for the geometry, + 16 (t_i, w = optimisation
// count) + 16 (R_i as a unit quaternion) = 44 with the deformation field (absent with rigid_only).
struct DeviceVolume {
  VdVolume vol{};
  ocl::Buffer<float> tsdf;
  ocl::Buffer<float> weight;
  ocl::Buffer<uint32_t> color;
  ocl::Buffer<vd_float4> def_pos;
  ocl::Buffer<vd_float4> def_rot;
  // Per 8^3 brick (shared/tsdf.h, vd_grid_brick), 0 only when none of its points holds weight: fusion
  // flags what it fuses, and marching cubes skips the rest of the box. Whoever writes weights from
  // the host calls DeviceOps::MarkTouched afterwards.
  ocl::Buffer<uint8_t> touched;
  bool has_deformation() const { return !def_pos.empty(); }
  size_t num_voxels() const { return static_cast<size_t>(vol.dim_x) * vol.dim_y * vol.dim_z; }
  size_t num_bricks() const { return static_cast<size_t>(vd_bricks_x(vol)) * vd_bricks_y(vol) * vd_bricks_z(vol); }
  // Grid rows (fixed y, z): the work items of the per-row kernels.
  size_t num_rows() const { return static_cast<size_t>(vol.dim_y) * vol.dim_z; }
};

struct DeviceMesh {
  // Marching-cubes output in grid units (cell and trilinear weights implicit).
  ocl::Buffer<vd_float4> positions_grid;
  // Positions the rasteriser and the viewers see (world metres, deformed in the non-rigid case).
  ocl::Buffer<vd_float4> positions;
  ocl::Buffer<vd_float4> normals;
  ocl::Buffer<uint32_t> colors;
  ocl::Buffer<int32_t> triangles;
  // Marching cubes over the bricks: the pool slot of each vertex's owning grid point, so that
  // deforming it reaches its cell through the neighbour table instead of probing the brick table.
  // Valid for the first num_brick_slots vertices (0 for any other mesh).
  ocl::Buffer<int32_t> brick_slots;
  size_t num_vertices = 0;
  size_t num_triangles = 0;
  size_t num_brick_slots = 0;
};

struct DeviceRaster {
  VdCamera cam{};
  // Per pixel, min(depth bits << 32 | triangle id) of the triangles covering it (shared/raster.h).
  ocl::Buffer<uint64_t> depth_id;
  ocl::Buffer<uint32_t> ids;
  ocl::Buffer<vd_float4> vertex;
  ocl::Buffer<vd_float4> normal;
  ocl::Buffer<vd_float4> bary;
};

// The active set M (grid points of the cells the isosurface crosses plus their one-ring).
struct DeviceActiveSet {
  // Grid indices of the members, in row-major grid order.
  ocl::Buffer<int32_t> list;
  // Dense grid -> compact index map, -1 outside M.
  ocl::Buffer<int32_t> compact;
  // 6 compact neighbour indices per member (-x, +x, -y, +y, -z, +z), -1 where not in M.
  ocl::Buffer<int32_t> neighbours;
  size_t count = 0;
  // The dense grid BuildActiveSet last mapped into compact, which then holds -1 everywhere but at
  // list's members: the next build on the same dims clears the old members and writes the new
  // ones instead of the whole map. dim_x 0: not kept (anyone else who writes compact or list).
  VdVolume kept{};
};

// The lattice the solver's points live on (shared/lattice.h): the dense grid, or the pool's bricks
// at one level of the hierarchy. The buffers are the brick table's, not owned; a dense grid passes
// empty ones (null pointers the kernels never read).
struct DeviceLattice {
  VdLattice lat{};
  // The 27 neighbour slots of each slot (BrickTable::neighbours) and each slot's key.
  const ocl::Buffer<int32_t>* nbr = nullptr;
  const ocl::Buffer<uint32_t>* slot_keys = nullptr;
  // Bricks: the table, whose hash finds a constraint's cell (null on a dense grid).
  const ocl::BrickTable* table = nullptr;

  static DeviceLattice Dense(const VdVolume& vol);
  // The fine level on the bricks of `table` (after BuildNeighbours), voxels of voxel_size.
  static DeviceLattice Bricks(const ocl::BrickTable& table, float voxel_size);
  // Level `s` (a power of two, at most 8 on bricks) above this fine lattice: a dense grid of s times
  // the spacing over the same extent, enough points that every fine point lies in a coarse cell;
  // on bricks the same bricks with 8 / s points a side.
  DeviceLattice Level(int s) const;
  // Entries (the size of the per-point arrays: the grid's points, or `slots` bricks' points).
  size_t Entries(uint32_t slots) const;
};

// The deformation field S as the feature kernels read it (VD_FIELD_ARGS, shared/sparse_field.h):
// a dense grid's, or the brick pool's through its table's hash and neighbour table (after
// BuildNeighbours). The buffers are not owned; a dense grid passes empty brick buffers.
struct DeviceField {
  const ocl::Buffer<vd_float4>* def_pos = nullptr;
  // Dense: the grid. Bricks: the voxel size (points in global grid coordinates, origin 0).
  VdVolume vol{};
  const ocl::Buffer<uint32_t>* keys = nullptr;
  const ocl::Buffer<int32_t>* slots = nullptr;
  uint32_t capacity = 0;
  const ocl::Buffer<int32_t>* nbr = nullptr;

  static DeviceField Dense(const DeviceVolume& v);
  static DeviceField Bricks(const ocl::BrickTable& table, const ocl::BrickPool& pool, float voxel_size);
  bool valid() const { return def_pos != nullptr && def_pos->size() > 0; }
};

// The view the solver's points are limited to (EngineParams::solve_view_margin): the frame's
// camera at its pose, widened by `margin` times the image's size on each side.
struct SolveView {
  VdCamera cam{};
  VdPose world_to_cam{};
  float margin = 0.f;
};

class DeviceOps {
 public:
  explicit DeviceOps(ocl::Context* ctx) : ctx_(ctx) {}
  // Uploads the marching-cubes table.
  Status Init();
  ocl::Context& ctx() { return *ctx_; }

  Status DepthConvert(const ocl::Buffer<uint16_t>& raw, ocl::Buffer<float>& depth, int n, float inv_scale,
                      float min_depth, float max_depth);
  Status Bilateral(const ocl::Buffer<float>& in, ocl::Buffer<float>& out, int width, int height, int radius,
                   float sigma_space_px, float sigma_depth_m);
  Status PyrDown(const ocl::Buffer<float>& in, ocl::Buffer<float>& out, int width, int height, float max_diff);
  Status VertexMap(const ocl::Buffer<float>& depth, ocl::Buffer<vd_float4>& vmap, VdCamera cam);
  Status NormalMap(const ocl::Buffer<vd_float4>& vmap, ocl::Buffer<vd_float4>& nmap, int width, int height,
                   float max_jump);
  // The dense colour term's intensity image (shared/preprocess.h): the packed colour's luma at half
  // resolution, smoothed, through `tmp` (both (width / 2) x (height / 2)).
  Status Intensity(const ocl::Buffer<uint32_t>& rgba, ocl::Buffer<float>& tmp, ocl::Buffer<float>& out, int width,
                   int height);

  Status AllocVolume(const VdVolume& vol, bool with_deformation, DeviceVolume* out);
  Status ResetVolume(DeviceVolume& v);
  // Rebuilds v.touched from the weights: after the host wrote them (a restore, a test's grid).
  Status MarkTouched(DeviceVolume& v);
  // Projective TSDF fusion over the 8^3 bricks the depth's truncation band may touch (shared/tsdf.h):
  // the same update as IntegrateTsdfDense inside the band, free space beyond it left alone.
  Status IntegrateTsdf(DeviceVolume& v, VdCamera cam, VdPose world_to_cam, const ocl::Buffer<float>& depth,
                       const ocl::Buffer<uint32_t>& rgba);
  // Every grid point of the view (free space carved too); the reference and the benchmark peer.
  Status IntegrateTsdfDense(DeviceVolume& v, VdCamera cam, VdPose world_to_cam, const ocl::Buffer<float>& depth,
                            const ocl::Buffer<uint32_t>& rgba);
  // Bricks integrated by the last IntegrateTsdf call (tests, statistics).
  size_t last_integrated_bricks() const { return brick_count_; }
  // The brick flags of the last IntegrateTsdf call (tests).
  const ocl::Buffer<uint32_t>& brick_flags() const { return brick_flags_; }

  // Exclusive scan of in[0, n) into out[0, n], out[n] = total (out must hold n + 1).
  Status ScanExclusive(const ocl::Buffer<uint32_t>& in, size_t n, ocl::Buffer<uint32_t>& out, uint32_t* total);
  // Marching cubes; fills positions_grid, normals, colors, triangles (positions untouched).
  Status MarchingCubes(const DeviceVolume& v, DeviceMesh* mesh);
  // Marching cubes over every brick of a sparse volume (shared/sparse_mesh.h; builds the table's
  // neighbours): positions_grid in global grid coordinates (the bricks tile space from the world
  // origin), normals, colors, triangles.
  // Bricks without weight are skipped (no valid cell: shared/sparse_mesh.h vd_sparse_brick_weighted).
  Status MarchingCubes(ocl::BrickTable& table, const ocl::BrickPool& pool, DeviceMesh* mesh);
  // Per slot, whether the last MarchingCubes over bricks read it (tests).
  const ocl::Buffer<uint8_t>& bricks_weighted() const { return mc_brick_weighted_; }
  // positions = origin + voxel_size * positions_grid (the rigid placement).
  Status GridToWorld(const VdVolume& vol, DeviceMesh* mesh);
  // positions = S(positions_grid) through the grid's deformation field.
  Status DeformVertices(const DeviceVolume& v, DeviceMesh* mesh);
  // Per-pixel correspondences between the rasterised deformed mesh (`model`, rendered at the
  // current camera) and the observed maps; canonical positions from mesh.positions_grid.
  Status Correspondences(const DeviceRaster& model, const ocl::Buffer<vd_float4>& obs_v,
                         const ocl::Buffer<vd_float4>& obs_n, const DeviceMesh& mesh, const VdCorrParams& params,
                         ocl::Buffer<VdCorrespondence>& out);
  // The dense colour term's rows (shared/correspondence.h vd_photometric_pixel): rows[n + b] for
  // each 2x2 block b of the raster's n pixels (vd_photo_rows of them), from the depth row of its
  // first pixel (vd_photo_pixel), the model's colour from mesh.colors.
  Status PhotometricCorrespondences(const DeviceRaster& model, const ocl::Buffer<vd_float4>& obs_v,
                                    const DeviceMesh& mesh, const ocl::Buffer<float>& intensity,
                                    const VdPhotoParams& params, ocl::Buffer<VdCorrespondence>& rows);
  // Applies the rigid motion a (rotation q_a) to every optimised grid point's position and rotation.
  Status TransformField(DeviceVolume& v, const VdPose& a, vd_float4 q_a);
  // The same on a brick pool's field (every slot's voxels).
  Status TransformField(ocl::BrickPool& pool, const VdPose& a, vd_float4 q_a);
  // Initialises members of M never optimised from their optimised neighbours as rigid pieces.
  Status Extrapolate(DeviceVolume& v, const DeviceActiveSet& active);
  // The same on a sparse volume's field (M over the pool: BuildActiveSet(table, ...), which also
  // leaves the table's neighbours built).
  Status Extrapolate(const ocl::BrickTable& table, ocl::BrickPool& pool, const DeviceActiveSet& active,
                     float voxel_size);
  // positions = S(positions_grid) through a sparse volume's field (positions_grid in global grid
  // coordinates, as MarchingCubes(table, pool, ...) emits them; the table's neighbours built).
  Status DeformVertices(const ocl::BrickTable& table, const ocl::BrickPool& pool, float voxel_size, DeviceMesh* mesh);
  // Non-rigid fusion into the members of M optimised at least fp.k_min times (fp.k_min_new for those
  // never fused yet), at their deformed positions, with carving (shared/tsdf.h).
  Status IntegrateActive(DeviceVolume& v, const DeviceActiveSet& active, const VdFusionParams& fp, VdCamera cam,
                         VdPose world_to_cam, const ocl::Buffer<float>& depth, const ocl::Buffer<uint32_t>& rgba);
  // The same over M on the bricks (pool voxel indices); vol: voxel size, truncation and weight cap.
  Status IntegrateActive(ocl::BrickPool& pool, const DeviceActiveSet& active, const VdFusionParams& fp, VdVolume vol,
                         VdCamera cam, VdPose world_to_cam, const ocl::Buffer<float>& depth,
                         const ocl::Buffer<uint32_t>& rgba);
  // After a solve over the surface points of M (`solved` of the last BuildActiveSet), its ring points
  // follow their solved neighbours (shared/deformation.h vd_follow_point).
  Status Follow(DeviceVolume& v, const DeviceActiveSet& active);
  // The same over a sparse volume's M (the last BuildActiveSet(table, ...) with `solved`).
  Status Follow(const ocl::BrickTable& table, ocl::BrickPool& pool, const DeviceActiveSet& active, float voxel_size);
  // M from the cell codes of the last MarchingCubes() call on v; with `solved`, also the set of its
  // surface points alone (the corners of cells with triangles: the solver's unknowns), and with
  // `view` only those of them whose deformed position is in that view (vd_point_in_view).
  Status BuildActiveSet(const DeviceVolume& v, DeviceActiveSet* out, DeviceActiveSet* solved = nullptr,
                        const SolveView* view = nullptr);
  // M over a sparse volume from the last MarchingCubes() call on its bricks: list and compact hold
  // pool voxel indices (slot * 512 + local) for grid indices. def_pos: the pool's field (read with
  // `view` only).
  Status BuildActiveSet(const ocl::BrickTable& table, DeviceActiveSet* out, DeviceActiveSet* solved = nullptr,
                        const SolveView* view = nullptr, const ocl::Buffer<vd_float4>* def_pos = nullptr);
  // Bricks for the one-ring of the surface the last BuildActiveSet(table, ...) found, where their
  // brick is missing (BrickTable::AllocateRing); how many were added (0: M is whole).
  StatusOr<uint32_t> AllocateActiveRing(ocl::BrickTable& table);
  Status Rasterize(const DeviceMesh& mesh, VdPose world_to_cam, VdCamera cam, DeviceRaster* out);
  Status IcpReduce(const ocl::Buffer<vd_float4>& vmap, const ocl::Buffer<vd_float4>& nmap,
                   const ocl::Buffer<vd_float4>& model_v, const ocl::Buffer<vd_float4>& model_n, int n,
                   const VdIcpParams& params, double acc[VD_ICP_ACC]);

 private:
  // Marching cubes' scratch for `points` grid or pool points in `rows` rows of work; the per-point
  // first vertex index only with vertex_offsets (the dense grid's long rows; the bricks' rows of 8
  // count it from the masks).
  Status ReserveMarchingCubes(size_t points, size_t rows, bool vertex_offsets);
  // After the classification and mask passes: the scans, the mesh's counts and buffers; whether it
  // has anything to emit.
  StatusOr<bool> SizeMesh(size_t rows, DeviceMesh* mesh);
  // Both active-set builds: scans the per-row member counts into active_row_offset_, sets
  // out->count and reserves the list and the neighbour table for it.
  Status SizeActiveSet(size_t rows, const ocl::Buffer<uint32_t>& row_count, DeviceActiveSet* out);
  // The dense build's compaction of `member` (per-row counts row_count) into out: list, map and
  // neighbours; a map kept from the last build on these dims is cleared at its old members only.
  Status CompactActiveSet(const VdVolume& vol, const ocl::Buffer<uint8_t>& member,
                          const ocl::Buffer<uint32_t>& row_count, DeviceActiveSet* out);
  ocl::Context* ctx_;
  ocl::Buffer<int8_t> mc_tri_table_;
  // What IntegrateActive on the bricks passes for the touched flags it does not keep (never read).
  ocl::Buffer<uint8_t> no_touched_;
  ocl::Buffer<uint8_t> mc_tri_counts_;
  // Marching-cubes scratch, one entry per grid point: cell codes, vertex masks, first vertex index
  // (the dense grid only).
  ocl::Buffer<uint16_t> mc_codes_;
  ocl::Buffer<uint8_t> mc_masks_;
  ocl::Buffer<uint32_t> mc_vert_offset_;
  // Bricks only, per slot: 1 where the brick holds weight; the others (the active set's ring and
  // coarse corners) have no valid cell, so classification and masks skip them.
  ocl::Buffer<uint8_t> mc_brick_weighted_;
  // Per grid row: triangle and vertex totals and their exclusive prefix sums.
  // Per triangle of the last Rasterize, its set-up (shared/raster.h), read by the resolve.
  ocl::Buffer<VdRasterSetup> raster_setups_;
  ocl::Buffer<uint32_t> mc_row_tris_;
  // Dense grid only: per VD_MC_CHUNK cells of a row, whether one has triangles (shared/marching_cubes.h).
  ocl::Buffer<uint8_t> mc_chunk_tris_;
  ocl::Buffer<uint32_t> mc_row_verts_;
  ocl::Buffer<uint32_t> mc_row_tri_offset_;
  ocl::Buffer<uint32_t> mc_row_vert_offset_;
  // Scan scratch per recursion level.
  std::vector<ocl::Buffer<uint32_t>> scan_sums_;
  std::vector<ocl::Buffer<uint32_t>> scan_offsets_;
  ocl::Buffer<float> icp_partials_;
  ocl::Buffer<vd_float4> extrapolated_pos_;
  ocl::Buffer<vd_float4> extrapolated_rot_;
  // Active-set scratch: surface flags, membership flags, per-row counts and offsets.
  ocl::Buffer<uint8_t> active_surface_;
  ocl::Buffer<uint8_t> active_member_;
  ocl::Buffer<uint32_t> active_row_count_;
  // Surface points per grid row, so the dilation skips rows far from any.
  ocl::Buffer<uint32_t> active_row_surface_;
  // With a SolveView: the surface points in it and their per-row counts; solved_in_view_ says
  // whether the last build's solved set came from them (else from active_surface_).
  ocl::Buffer<uint8_t> active_in_view_;
  ocl::Buffer<uint32_t> active_row_in_view_;
  bool solved_in_view_ = false;
  // The flags of the last build's solved set (what Follow's ring follows).
  const ocl::Buffer<uint8_t>& SolvedFlags() const { return solved_in_view_ ? active_in_view_ : active_surface_; }
  ocl::Buffer<uint32_t> active_row_offset_;
  std::vector<float> icp_host_;
  // Brick integration scratch: per-brick flags of the current frame, their scan, the list.
  ocl::Buffer<vd_float4> depth_tiles_;
  ocl::Buffer<uint32_t> brick_flags_;
  // Per brick, the octants the band may touch (vd_brick_octants); integration skips the others.
  ocl::Buffer<uint32_t> brick_masks_;
  ocl::Buffer<uint32_t> brick_offsets_;
  ocl::Buffer<uint32_t> brick_list_;
  size_t brick_count_ = 0;
};

}  // namespace vd
