#pragma once
// The text of a double in odonav's CSV files: the shortest decimal that reads back to exactly the
// same double, laid out as std::to_chars(first, last, value) lays it out (fixed or scientific,
// whichever is shorter, fixed on a tie; "-0", "inf", "nan" as it writes them), byte for byte, at a
// fraction of its cost: the digits come from the Dragonbox algorithm of the {fmt} library (Debian's
// libfmt, which spdlog already links), the rare forms (zero, non-finite, integers with trailing
// zeros, exponents of three digits) from std::to_chars itself.

namespace odonav {

/// Bytes write_shortest_double may write (the longest form, "-2.2250738585072014e-308", is 24).
inline constexpr int kShortestDoubleMaxChars = 32;

/// Writes the text of `value` at `first` (which must have kShortestDoubleMaxChars bytes of room)
/// and returns the end of what it wrote.
char* write_shortest_double(char* first, double value);

}  // namespace odonav
