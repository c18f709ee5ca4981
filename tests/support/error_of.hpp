#pragma once
// The message of the std::runtime_error an expression throws: for tests of refusals whose text
// must name what was wrong.
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

namespace odonav::test {

/// Message text of the std::runtime_error `make` throws; empty (and a test failure) if none.
template <class Make>
std::string error_of(Make make) {
  try {
    make();
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  ADD_FAILURE() << "no std::runtime_error thrown";
  return {};
}

}  // namespace odonav::test
