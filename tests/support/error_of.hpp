#pragma once
// The message of the exception (a std::runtime_error unless told) an expression throws: for tests of
// refusals whose text must name what was wrong.
#include <gtest/gtest.h>

#include <optional>
#include <stdexcept>
#include <string>

namespace odonav::test {

/// Message text of the `Error` (a std::runtime_error by default) `make` throws; nullopt if none.
template <class Error = std::runtime_error, class Make>
std::optional<std::string> thrown_message(Make make) {
  try {
    make();
  } catch (const Error& e) {
    return std::string(e.what());
  }
  return std::nullopt;
}

/// Message text of the `Error` `make` throws; empty, and no test failure, if none: for checks that
/// some calls are refused and others are not.
template <class Error = std::runtime_error, class Make>
std::string message_if_thrown(Make make) {
  return thrown_message<Error>(make).value_or("");
}

/// Message text of the `Error` (a std::runtime_error by default) `make` throws; empty (and a test
/// failure) if none.
template <class Error = std::runtime_error, class Make>
std::string error_of(Make make) {
  const std::optional<std::string> message = thrown_message<Error>(make);
  if (!message) ADD_FAILURE() << "nothing thrown";
  return message.value_or("");
}

}  // namespace odonav::test
