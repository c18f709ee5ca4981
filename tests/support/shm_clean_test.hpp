#pragma once
// The fixture of the multi-process tests: Fast DDS's unused shared-memory segments are removed
// before and after each test (leftovers of a crashed run must not reach the next one).
#include <gtest/gtest.h>

#include "child_process.hpp"

namespace odonav::test {

class ShmCleanTest : public ::testing::Test {
 protected:
  void SetUp() override { shm_clean(); }
  void TearDown() override { shm_clean(); }
};

}  // namespace odonav::test
