// DeviceOps' launchers of kernels/active_set.cl (class in ocl/device_ops.h).
#include "ocl/active_set_ocl.h"

#include <algorithm>

#include "ocl/device_ops.h"

namespace vd {

Status DeviceOps::BuildActiveSet(const DeviceVolume& v, DeviceActiveSet* out, DeviceActiveSet* solved,
                                 const SolveView* view) {
  const size_t n = v.num_voxels(), rows = v.num_rows();
  if (mc_codes_.size() < n) return FailedPrecondition("BuildActiveSet needs a MarchingCubes() run on this grid");
  VD_RETURN_IF_ERROR(ctx_->Reserve(&active_surface_, n));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&active_member_, n));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&active_row_count_, rows));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&active_row_offset_, rows + 1));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&active_row_surface_, rows));
  VD_RETURN_IF_ERROR(ocl::kActiveSurface(*ctx_, rows, mc_codes_, mc_tri_counts_, mc_row_tris_, mc_chunk_tris_, v.vol,
                                         active_surface_, active_row_surface_));
  VD_RETURN_IF_ERROR(
      ocl::kActiveDilate(*ctx_, rows, active_surface_, active_row_surface_, v.vol, active_member_, active_row_count_));
  VD_RETURN_IF_ERROR(CompactActiveSet(v.vol, active_member_, active_row_count_, out));
  solved_in_view_ = false;
  if (!solved) return Status::Ok();
  if (!view) return CompactActiveSet(v.vol, active_surface_, active_row_surface_, solved);
  if (v.def_pos.size() < n) return FailedPrecondition("a solve limited to the view needs the grid's field");
  VD_RETURN_IF_ERROR(ctx_->Reserve(&active_in_view_, n));
  VD_RETURN_IF_ERROR(ctx_->Reserve(&active_row_in_view_, rows));
  VD_RETURN_IF_ERROR(ocl::kActiveInView(*ctx_, rows, active_surface_, active_row_surface_, v.def_pos, v.vol.dim_x,
                                        view->cam, view->world_to_cam, view->margin, active_in_view_,
                                        active_row_in_view_));
  solved_in_view_ = true;
  return CompactActiveSet(v.vol, active_in_view_, active_row_in_view_, solved);
}

Status DeviceOps::CompactActiveSet(const VdVolume& vol, const ocl::Buffer<uint8_t>& member,
                                   const ocl::Buffer<uint32_t>& row_count, DeviceActiveSet* out) {
  const size_t n = size_t(vol.dim_x) * vol.dim_y * vol.dim_z, rows = size_t(vol.dim_y) * vol.dim_z;
  // The map of the last build on these dims is -1 but at its members: clear those (before the list
  // is reserved again, which may drop it). Otherwise start from a map of -1.
  const bool kept = out->kept.dim_x == vol.dim_x && out->kept.dim_y == vol.dim_y && out->kept.dim_z == vol.dim_z &&
                    out->compact.size() >= n;
  out->kept = VdVolume{};
  if (kept) {
    VD_RETURN_IF_ERROR(ocl::kActiveUnmark(*ctx_, out->count, out->list, out->compact));
  } else {
    VD_RETURN_IF_ERROR(ctx_->Reserve(&out->compact, n));
    VD_RETURN_IF_ERROR(ctx_->Fill(out->compact, int32_t{-1}, n));
  }
  VD_RETURN_IF_ERROR(SizeActiveSet(rows, row_count, out));
  VD_RETURN_IF_ERROR(ocl::kActiveCompact(*ctx_, rows, member, active_row_offset_, vol, 1, out->list, out->compact));
  VD_RETURN_IF_ERROR(ocl::kActiveNeighbours(*ctx_, out->count, out->list, out->compact, vol, out->neighbours));
  out->kept = vol;
  return Status::Ok();
}

Status DeviceOps::SizeActiveSet(size_t rows, const ocl::Buffer<uint32_t>& row_count, DeviceActiveSet* out) {
  uint32_t total = 0;
  VD_RETURN_IF_ERROR(ScanExclusive(row_count, rows, active_row_offset_, &total));
  out->count = total;
  VD_RETURN_IF_ERROR(ctx_->Reserve(&out->list, std::max<size_t>(total, 1)));
  return ctx_->Reserve(&out->neighbours, 6 * std::max<size_t>(total, 1));
}

namespace ocl {

Status CompactActiveSet(Context& ctx, const Buffer<uint8_t>& member, const Buffer<uint32_t>& row_offset, VdVolume vol,
                        DeviceActiveSet* out) {
  const size_t rows = size_t(vol.dim_y) * vol.dim_z;
  VD_RETURN_IF_ERROR(kActiveCompact(ctx, rows, member, row_offset, vol, 0, out->list, out->compact));
  return kActiveNeighbours(ctx, out->count, out->list, out->compact, vol, out->neighbours);
}

}  // namespace ocl
}  // namespace vd
