// DeviceOps' allocation; its launchers are in the <family>_ocl.cpp of their kernels.
#include "ocl/device_ops.h"

#include "ocl/mc_table.h"

namespace vd {

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
