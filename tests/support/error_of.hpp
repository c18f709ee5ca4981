#pragma once
// The message of the exception (a std::runtime_error unless told) an expression throws: for tests of
// refusals whose text must name what was wrong.
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

namespace odonav::test {

/// Message text of the `Error` (a std::runtime_error by default) `make` throws; empty, and no test
/// failure, if none: for checks that some calls are refused and others are not.
template <class Error = std::runtime_error, class Make>
std::string message_if_thrown(Make make) {
  try {
    make();
  } catch (const Error& e) {
    return e.what();
  }
  return {};
}

/// Message text of the `Error` (a std::runtime_error by default) `make` throws; empty (and a test
/// failure) if none.
template <class Error = std::runtime_error, class Make>
std::string error_of(Make make) {
  try {
    make();
  } catch (const Error& e) {
    return e.what();
  }
  ADD_FAILURE() << "nothing thrown";
  return {};
}

}  // namespace odonav::test
