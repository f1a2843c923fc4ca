#pragma once
// A scratch directory of this test alone: ctest runs every test case as its own process, two at a
// time, so a fixed name under TempDir() is shared (and removed) by cases running side by side.
#include <unistd.h>

#include <string>

#include <gtest/gtest.h>

namespace vd::test {

inline std::string TestTempDir(const std::string& stem) {
  const ::testing::TestInfo* info = ::testing::UnitTest::GetInstance()->current_test_info();
  return ::testing::TempDir() + "/" + stem + "_" + (info ? info->name() : "none") + "_" + std::to_string(getpid());
}

}  // namespace vd::test
