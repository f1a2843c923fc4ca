// DeviceOps' launchers of kernels/scan.cl (class in ocl/device_ops.h).
#include "ocl/scan_ocl.h"

#include "ocl/device_ops.h"

namespace vd {
namespace {
// Elements per work item of the chunked scan.
constexpr uint32_t kScanChunk = 256;
}  // namespace

Status DeviceOps::ScanExclusive(const ocl::Buffer<uint32_t>& in, size_t n, ocl::Buffer<uint32_t>& out,
                                uint32_t* total) {
  if (out.size() < n + 1) return OutOfRange("scan output needs n + 1 entries");
  // Level l scans the chunk sums of level l - 1; recursion as a loop over cached scratch.
  std::vector<size_t> sizes{n};
  while (sizes.back() > kScanChunk) sizes.push_back((sizes.back() + kScanChunk - 1) / kScanChunk);
  const size_t levels = sizes.size() - 1;
  if (scan_sums_.size() < levels) {
    scan_sums_.resize(levels);
    scan_offsets_.resize(levels);
  }
  for (size_t l = 0; l < levels; ++l) {
    VD_RETURN_IF_ERROR(ctx_->Reserve(&scan_sums_[l], sizes[l + 1]));
    VD_RETURN_IF_ERROR(ctx_->Reserve(&scan_offsets_[l], sizes[l + 1] + 1));
  }
  // Down: chunk sums of every level.
  for (size_t l = 0; l < levels; ++l) {
    const ocl::Buffer<uint32_t>& src = l == 0 ? in : scan_sums_[l - 1];
    VD_RETURN_IF_ERROR(
        ocl::kScanSums(*ctx_, sizes[l + 1], src, static_cast<uint32_t>(sizes[l]), kScanChunk, scan_sums_[l]));
  }
  // Up: the top level fits in one chunk; each level below adds its chunk offsets.
  for (size_t l = levels + 1; l-- > 0;) {
    const ocl::Buffer<uint32_t>& src = l == 0 ? in : scan_sums_[l - 1];
    ocl::Buffer<uint32_t>& dst = l == 0 ? out : scan_offsets_[l - 1];
    const bool top = l == levels;
    const ocl::Buffer<uint32_t>& offsets = top ? dst : scan_offsets_[l];
    const size_t items = top ? 1 : sizes[l + 1];
    VD_RETURN_IF_ERROR(ocl::kScanApply(*ctx_, items, src, static_cast<uint32_t>(sizes[l]), kScanChunk, offsets,
                                       static_cast<uint32_t>(top ? 0 : 1), dst));
  }
  if (total) VD_RETURN_IF_ERROR(ctx_->Download(out, total, 1, n));
  return Status::Ok();
}

}  // namespace vd
