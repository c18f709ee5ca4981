#pragma once
// Private helpers of odonav_io (not installed, not included outside common/src/io): strict,
// locale-independent number parsing and exact number formatting shared by the dataset reader/writer
// and the configuration parser.
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace odonav::io_detail {

/// Outcome of a strict number parse.
enum class NumberStatus {
  kOk,
  kEmpty,       ///< nothing but whitespace
  kNotNumber,   ///< text is not entirely a decimal number ("12abc", "0x10", "1.5" for an integer)
  kNotFinite,   ///< "nan", "inf", "infinity" (any case, any sign)
  kOutOfRange,  ///< a number, but outside the range of the target type ("1e999")
};

/// Removes spaces and tabs at both ends.
std::string_view trim(std::string_view text);

/// Parses a decimal floating-point number: the whole trimmed text must be consumed. Accepts an
/// optional leading '+' or '-', fixed or scientific notation. Independent of the C locale
/// (std::from_chars): the decimal separator is always '.'. NaN and infinities are kNotFinite.
NumberStatus parse_double(std::string_view text, double& out);

/// Parses a base-10 integer into int64: the whole trimmed text must be consumed ("1.0", "1e3" are
/// kNotNumber). Accepts an optional leading '+' or '-'. Values beyond int64 are kOutOfRange.
NumberStatus parse_int64(std::string_view text, int64_t& out);

/// Shortest decimal text that reads back to exactly `value` (std::to_chars round-trip form).
/// Finite values only; "nan"/"inf" otherwise.
std::string format_double(double value);

/// Human form of a number for messages and help: shortest round-trip text with the exponent
/// written without '+' and leading zeros ("1e6", "2.5e-5", "4").
std::string format_number(double value);

/// Splits a line on ',' (no quoting: the dataset format has no quoted fields).
std::vector<std::string_view> split_commas(std::string_view line);
/// The same into `fields` (cleared first), so a reader that splits every row of a file reuses one
/// vector instead of allocating one per row.
void split_commas(std::string_view line, std::vector<std::string_view>& fields);

/// Longest excerpt of user text quoted in a message (characters before the "...").
inline constexpr std::size_t kMaxQuotedChars = 80;
/// `text` for a message: at most kMaxQuotedChars bytes (then "... (N bytes)"), every byte outside
/// printable ASCII written as \xNN, so a NUL, an escape sequence or a 50 MB field cannot reach the
/// terminal as it is.
std::string printable_excerpt(std::string_view text);
/// The same for a text of `full_size` bytes of which `head` holds the first ones (at least
/// kMaxQuotedChars of them when full_size is larger): what a reader that does not keep a long line
/// whole quotes of it.
std::string printable_excerpt(std::string_view head, std::size_t full_size);

/// Joins with ", ".
std::string join(const std::vector<std::string>& parts, const std::string& separator = ", ");

}  // namespace odonav::io_detail
