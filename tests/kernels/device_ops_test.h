#pragma once
// The base of the kernel tests that need the shared OpenCL context and a DeviceOps on it.
#include <gtest/gtest.h>

#include <optional>
#include <string>

#include "ocl/device_ops.h"
#include "test_scenes.h"

namespace vd::test {

// Skips without an OpenCL device, fails when one is there but does not work. A derived SetUp
// calls this first and returns when IsSkipped() or HasFatalFailure().
class DeviceOpsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ctx_ = SharedContext(&error_);
    if (!ctx_ && !error_.empty()) FAIL() << error_;
    if (!ctx_) GTEST_SKIP() << "no OpenCL device (install pocl-opencl-icd; set POCL_CACHE_DIR)";
    ops_.emplace(ctx_);
    ASSERT_TRUE(ops_->Init().ok());
  }
  // Why the shared context could not be made (empty: no device).
  std::string error_;
  ocl::Context* ctx_ = nullptr;
  std::optional<DeviceOps> ops_;
};

}  // namespace vd::test
