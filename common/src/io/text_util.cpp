// Strict number parsing and exact number formatting for odonav_io (see text_util.hpp).
#include "text_util.hpp"

#include "odonav/shortest_double.hpp"

#include <algorithm>

#include <charconv>
#include <cmath>
#include <limits>
#include <system_error>

namespace odonav::io_detail {

std::string_view trim(std::string_view text) {
  const auto is_space = [](char c) { return c == ' ' || c == '\t'; };
  while (!text.empty() && is_space(text.front())) text.remove_prefix(1);
  while (!text.empty() && is_space(text.back())) text.remove_suffix(1);
  return text;
}

// std::from_chars takes no leading '+'; a single '+' in front of a digit or '.' is allowed here
// because users write "+1" for a forward direction. "+-1" stays invalid.
static bool strip_plus(std::string_view& text) {
  if (!text.empty() && text.front() == '+') {
    text.remove_prefix(1);
    if (text.empty() || text.front() == '-' || text.front() == '+') return false;
  }
  return true;
}

static bool looks_like_nan_or_inf(std::string_view text) {
  if (!text.empty() && (text.front() == '-' || text.front() == '+')) text.remove_prefix(1);
  // Fast path, taken by every ordinary number: NaN and infinity spellings start with a letter, so a
  // leading digit or '.' rules them out without building the lower-case copy below (this check runs
  // once per field of every dataset row, and the copy was a heap allocation per field).
  if (text.empty() || (text.front() >= '0' && text.front() <= '9') || text.front() == '.') return false;
  std::string lower;
  for (char c : text) lower += static_cast<char>((c >= 'A' && c <= 'Z') ? c - 'A' + 'a' : c);
  return lower == "nan" || lower == "inf" || lower == "infinity" || lower.rfind("nan(", 0) == 0;
}

NumberStatus parse_double(std::string_view text, double& out) {
  text = trim(text);
  if (text.empty()) return NumberStatus::kEmpty;
  if (looks_like_nan_or_inf(text)) return NumberStatus::kNotFinite;
  if (!strip_plus(text)) return NumberStatus::kNotNumber;
  double value = 0.0;
  const char* const end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, value, std::chars_format::general);
  if (ec == std::errc::result_out_of_range) return NumberStatus::kOutOfRange;
  if (ec != std::errc() || ptr != end) return NumberStatus::kNotNumber;
  if (!std::isfinite(value)) return NumberStatus::kNotFinite;
  out = value;
  return NumberStatus::kOk;
}

NumberStatus parse_int64(std::string_view text, int64_t& out) {
  text = trim(text);
  if (text.empty()) return NumberStatus::kEmpty;
  if (!strip_plus(text)) return NumberStatus::kNotNumber;
  int64_t value = 0;
  const char* const end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, value, 10);
  if (ec == std::errc::result_out_of_range && ptr == end) return NumberStatus::kOutOfRange;
  if (ec != std::errc() || ptr != end) return NumberStatus::kNotNumber;
  out = value;
  return NumberStatus::kOk;
}

std::string format_double(double value) {
  char buffer[kShortestDoubleMaxChars];
  return std::string(buffer, write_shortest_double(buffer, value));
}

std::string format_number(double value) {
  std::string text = format_double(value);
  const std::size_t e = text.find('e');
  if (e == std::string::npos) return text;
  std::string mantissa = text.substr(0, e);
  std::string exponent = text.substr(e + 1);
  std::string sign;
  if (!exponent.empty() && (exponent.front() == '+' || exponent.front() == '-')) {
    if (exponent.front() == '-') sign = "-";
    exponent.erase(0, 1);
  }
  while (exponent.size() > 1 && exponent.front() == '0') exponent.erase(0, 1);
  return mantissa + "e" + sign + exponent;
}

std::vector<std::string_view> split_commas(std::string_view line) {
  std::vector<std::string_view> fields;
  split_commas(line, fields);
  return fields;
}

void split_commas(std::string_view line, std::vector<std::string_view>& fields) {
  fields.clear();
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = line.find(',', start);
    if (comma == std::string_view::npos) {
      fields.push_back(line.substr(start));
      return;
    }
    fields.push_back(line.substr(start, comma - start));
    start = comma + 1;
  }
}

std::string join(const std::vector<std::string>& parts, const std::string& separator) {
  std::string text;
  for (std::size_t i = 0; i < parts.size(); ++i) {
    if (i) text += separator;
    text += parts[i];
  }
  return text;
}

std::string printable_excerpt(std::string_view text) { return printable_excerpt(text, text.size()); }

std::string printable_excerpt(std::string_view text, std::size_t full_size) {
  std::string out;
  const std::size_t n = std::min({text.size(), full_size, kMaxQuotedChars});
  out.reserve(n + 24);
  static const char* kHex = "0123456789abcdef";
  for (std::size_t i = 0; i < n; ++i) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    if (c >= 0x20 && c < 0x7f) {
      out += static_cast<char>(c);
    } else {
      out += "\\x";
      out += kHex[c >> 4];
      out += kHex[c & 15];
    }
  }
  if (full_size > n) out += "... (" + std::to_string(full_size) + " bytes)";
  return out;
}

}  // namespace odonav::io_detail
