// io_detail::parse_double (odonav_io's private number parser): its own path for plain decimals must
// give what std::from_chars gives, to the bit, and leave every other text to from_chars and its
// checks (the dataset reader's messages name the same problems as before).
#include <gtest/gtest.h>

#include <charconv>
#include <cmath>
#include <cstring>
#include <random>
#include <string>

#include "../../../common/src/io/text_util.hpp"

using odonav::io_detail::NumberStatus;
using odonav::io_detail::parse_double;

namespace {
// parse_double as it was before its plain-decimal path: trim, one leading '+', std::from_chars.
NumberStatus reference_parse(std::string_view text, double& out) {
  text = odonav::io_detail::trim(text);
  if (text.empty()) return NumberStatus::kEmpty;
  if (text.front() == '+') {
    text.remove_prefix(1);
    if (text.empty() || text.front() == '-' || text.front() == '+') return NumberStatus::kNotNumber;
  }
  const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), out, std::chars_format::general);
  if (ec == std::errc::result_out_of_range) return NumberStatus::kOutOfRange;
  if (ec != std::errc() || ptr != text.data() + text.size()) return NumberStatus::kNotNumber;
  return std::isfinite(out) ? NumberStatus::kOk : NumberStatus::kNotFinite;
}
}  // namespace

TEST(NumberText, PlainDecimalsReadToTheBitsStdFromCharsGives) {
  std::mt19937_64 rng(11);
  const char kAlphabet[] = "0123456789.-+e ";
  std::size_t differing = 0;
  for (int i = 0; i < 1000000; ++i) {
    std::string text;
    if (i % 3 == 0) {  // any short mix of number characters
      const int length = static_cast<int>(rng() % 12) + 1;
      for (int k = 0; k < length; ++k) text += kAlphabet[rng() % (sizeof kAlphabet - 1)];
    } else {  // a decimal of 1 to 18 integer digits and 0 to 19 decimals, signed or not
      if (rng() % 3 == 0) text += (rng() % 2) ? '-' : '+';
      const int integer_digits = static_cast<int>(rng() % 18) + 1;
      for (int k = 0; k < integer_digits; ++k) text += static_cast<char>('0' + rng() % 10);
      if (rng() % 4) {
        text += '.';
        const int decimals = static_cast<int>(rng() % 20);
        for (int k = 0; k < decimals; ++k) text += static_cast<char>('0' + rng() % 10);
      }
    }
    double expected = 0.0, got = 0.0;
    const NumberStatus expected_status = reference_parse(text, expected);
    const NumberStatus status = parse_double(text, got);
    const bool same = expected_status == NumberStatus::kOk
                          ? status == NumberStatus::kOk && std::memcmp(&expected, &got, sizeof got) == 0
                          : status != NumberStatus::kOk;
    if (!same && ++differing <= 10) ADD_FAILURE() << "'" << text << "': " << expected << " but " << got;
  }
  EXPECT_EQ(differing, 0u);
  double v = 0.0;
  ASSERT_EQ(parse_double("-0", v), NumberStatus::kOk);
  EXPECT_TRUE(std::signbit(v));
  ASSERT_EQ(parse_double(" 52.50000658205023\t", v), NumberStatus::kOk);
  EXPECT_EQ(v, 52.50000658205023);
  EXPECT_EQ(parse_double("1.", v), NumberStatus::kOk);  // from_chars' forms stay accepted
  EXPECT_EQ(v, 1.0);
  EXPECT_EQ(parse_double("+-1", v), NumberStatus::kNotNumber);
  EXPECT_EQ(parse_double("nan", v), NumberStatus::kNotFinite);
  EXPECT_EQ(parse_double("1e999", v), NumberStatus::kOutOfRange);
}
