// DeviceOps' allocation; its launchers are in the <family>_ocl.cpp of their kernels.
#include "ocl/device_ops.h"

#include "ocl/brick_hash_ocl.h"
#include "ocl/mc_table.h"

namespace vd {
namespace {
// What a dense lattice passes for the brick buffers.
const ocl::Buffer<int32_t> kNoNeighbours;
const ocl::Buffer<uint32_t> kNoKeys;
const ocl::Buffer<int32_t> kNoSlots;
}  // namespace

DeviceField DeviceField::Dense(const DeviceVolume& v) {
  DeviceField f;
  f.def_pos = &v.def_pos;
  f.vol = v.vol;
  f.keys = &kNoKeys;
  f.slots = &kNoSlots;
  f.nbr = &kNoNeighbours;
  return f;
}

DeviceField DeviceField::Bricks(const ocl::BrickTable& table, const ocl::BrickPool& pool, float voxel_size) {
  DeviceField f;
  f.def_pos = &pool.def_pos;
  f.vol.voxel_size = voxel_size;
  f.vol.origin = VD_F4(0.f, 0.f, 0.f, 1.f);
  f.keys = &table.keys();
  f.slots = &table.slots();
  f.capacity = table.capacity();
  f.nbr = &table.neighbours();
  return f;
}

DeviceLattice DeviceLattice::Dense(const VdVolume& vol) {
  DeviceLattice l;
  l.lat = vd_lattice_dense(vol);
  l.nbr = &kNoNeighbours;
  l.slot_keys = &kNoKeys;
  return l;
}

DeviceLattice DeviceLattice::Bricks(const ocl::BrickTable& table, float voxel_size) {
  DeviceLattice l;
  l.lat = vd_lattice_bricks(voxel_size, 1);
  l.nbr = &table.neighbours();
  l.slot_keys = &table.slot_keys();
  l.table = &table;
  return l;
}

DeviceLattice DeviceLattice::Level(int s) const {
  DeviceLattice l = *this;
  l.lat = vd_lattice_level(lat, s);
  return l;
}

size_t DeviceLattice::Entries(uint32_t slots) const {
  const size_t per = size_t(lat.dim_x) * lat.dim_y * lat.dim_z;
  return lat.bricks ? per * slots : per;
}

Status DeviceOps::Init() {
  const McTable& t = GetMcTable();
  VD_ASSIGN_OR_RETURN(mc_tri_table_, ctx_->Alloc<int8_t>(t.triangles.size()));
  VD_ASSIGN_OR_RETURN(mc_tri_counts_, ctx_->Alloc<uint8_t>(t.counts.size()));
  VD_RETURN_IF_ERROR(ctx_->Upload(mc_tri_table_, t.triangles.data(), t.triangles.size()));
  VD_RETURN_IF_ERROR(ctx_->Upload(mc_tri_counts_, t.counts.data(), t.counts.size()));
  return Status::Ok();
}

Status DeviceOps::AllocVolume(const VdVolume& vol, bool with_deformation, DeviceVolume* out) {
  out->vol = vol;
  const size_t n = out->num_voxels();
  VD_ASSIGN_OR_RETURN(out->tsdf, ctx_->Alloc<float>(n));
  VD_ASSIGN_OR_RETURN(out->weight, ctx_->Alloc<float>(n));
  VD_ASSIGN_OR_RETURN(out->color, ctx_->Alloc<uint32_t>(n));
  if (with_deformation) {
    VD_ASSIGN_OR_RETURN(out->def_pos, ctx_->Alloc<vd_float4>(n));
    VD_ASSIGN_OR_RETURN(out->def_rot, ctx_->Alloc<vd_float4>(n));
  } else {
    out->def_pos = ocl::Buffer<vd_float4>();
    out->def_rot = ocl::Buffer<vd_float4>();
  }
  return ResetVolume(*out);
}

}  // namespace vd
