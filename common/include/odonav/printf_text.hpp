#pragma once
// printf-style text of a few numbers, for health reasons, findings and the ground station's screen:
// the buffer handling in one place.
#include <cstddef>
#include <cstdio>
#include <string>

namespace odonav {

/// The text std::snprintf makes of `format` and `args` (numbers, C strings), whole: never cut at a
/// buffer's end. Empty when the format is refused.
template <class... Args>
std::string printf_text(const char* format, Args... args) {
  const int length = std::snprintf(nullptr, 0, format, args...);
  if (length <= 0) return std::string();
  std::string text(static_cast<std::size_t>(length), '\0');
  std::snprintf(text.data(), text.size() + 1, format, args...);
  return text;
}

}  // namespace odonav
