// DeviceOps' launchers of kernels/icp.cl (class in ocl/device_ops.h).
#include "ocl/icp_ocl.h"

#include "ocl/device_ops.h"

namespace vd {
namespace {
// Elements per work item of the ICP reduction.
constexpr int kIcpChunk = 64;
}  // namespace

Status DeviceOps::IcpReduce(const ocl::Buffer<vd_float4>& vmap, const ocl::Buffer<vd_float4>& nmap,
                            const ocl::Buffer<vd_float4>& model_v, const ocl::Buffer<vd_float4>& model_n, int n,
                            const VdIcpParams& params, double acc[VD_ICP_ACC]) {
  const size_t groups = (static_cast<size_t>(n) + kIcpChunk - 1) / kIcpChunk;
  VD_RETURN_IF_ERROR(ctx_->Reserve(&icp_partials_, groups * VD_ICP_ACC));
  VD_RETURN_IF_ERROR(ocl::kIcpReduce(*ctx_, groups, vmap, nmap, model_v, model_n, n, kIcpChunk, params, icp_partials_));
  icp_host_.resize(groups * VD_ICP_ACC);
  VD_RETURN_IF_ERROR(ctx_->Download(icp_partials_, icp_host_.data(), icp_host_.size()));
  for (int k = 0; k < VD_ICP_ACC; ++k) acc[k] = 0.0;
  for (size_t g = 0; g < groups; ++g)
    for (int k = 0; k < VD_ICP_ACC; ++k) acc[k] += icp_host_[g * VD_ICP_ACC + k];
  return Status::Ok();
}

}  // namespace vd
