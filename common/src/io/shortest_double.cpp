// write_shortest_double: Dragonbox digits laid out as std::to_chars lays them out (shortest_double.hpp).
#include "odonav/shortest_double.hpp"

#include <fmt/format.h>

#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>

namespace odonav {
namespace {

constexpr char kPairs[] =
    "00010203040506070809101112131415161718192021222324252627282930313233343536373839"
    "40414243444546474849505152535455565758596061626364656667686970717273747576777879"
    "8081828384858687888990919293949596979899";

constexpr uint64_t kPowersOf10[20] = {1u,
                                      10u,
                                      100u,
                                      1000u,
                                      10000u,
                                      100000u,
                                      1000000u,
                                      10000000u,
                                      100000000u,
                                      1000000000u,
                                      10000000000u,
                                      100000000000u,
                                      1000000000000u,
                                      10000000000000u,
                                      100000000000000u,
                                      1000000000000000u,
                                      10000000000000000u,
                                      100000000000000000u,
                                      1000000000000000000u,
                                      10000000000000000000u};

// Decimal digits of v > 0: log10(2) ~ 1233 / 4096 from the bit length, then one comparison.
int digit_count(uint64_t v) {
  const int bits = 64 - __builtin_clzll(v);
  const int guess = (bits * 1233) >> 12;  // floor(log10(2^bits)), or one less than the count
  return guess + (v >= kPowersOf10[guess] ? 1 : 0);
}

// Exactly 8 digits of v < 10^8 (leading zeros included) at first: v / 10^6 as a 48-bit fixed-point
// number (the constant is 2^48 / 10^6 rounded up: exact for every such v, as the unit test checks),
// then two digits per multiplication of the fraction by 100.
void write_8_digits(uint32_t v, char* first) {
  constexpr uint64_t kMask = (uint64_t{1} << 48) - 1;
  uint64_t y = uint64_t{v} * 281474977u;
  std::memcpy(first, kPairs + 2 * (y >> 48), 2);
  y = (y & kMask) * 100;
  std::memcpy(first + 2, kPairs + 2 * (y >> 48), 2);
  y = (y & kMask) * 100;
  std::memcpy(first + 4, kPairs + 2 * (y >> 48), 2);
  y = (y & kMask) * 100;
  std::memcpy(first + 6, kPairs + 2 * (y >> 48), 2);
}

// The n decimal digits of v (n = digit_count(v)) at first..first + n.
void write_digits(uint64_t v, char* first, int n) {
  while (n > 8) {
    n -= 8;
    write_8_digits(static_cast<uint32_t>(v % 100000000), first + n);
    v /= 100000000;
  }
  auto rest = static_cast<uint32_t>(v);
  char* p = first + n;
  while (rest >= 100) {
    p -= 2;
    std::memcpy(p, kPairs + 2 * (rest % 100), 2);
    rest /= 100;
  }
  if (rest >= 10) {
    p -= 2;
    std::memcpy(p, kPairs + 2 * rest, 2);
  } else {
    *--p = static_cast<char>('0' + rest);
  }
}

char* fallback(char* first, double value) { return std::to_chars(first, first + kShortestDoubleMaxChars, value).ptr; }

}  // namespace

char* write_shortest_double(char* first, double value) {
  if (!std::isfinite(value) || value == 0.0) return fallback(first, value);
  // value = significand * 10^exponent with the fewest significand digits that read back to value
  // (the nearest such number to the exact value; ties to even), as Ryu (std::to_chars) finds them.
  const auto decimal = fmt::detail::dragonbox::to_decimal(value);
  uint64_t significand = decimal.significand;
  int exponent = decimal.exponent;
  while (significand % 10 == 0) {
    significand /= 10;
    ++exponent;
  }
  // An integer with trailing zeros and exponents beyond two digits: std::to_chars itself.
  if (exponent > 0) return fallback(first, value);
  const int n = digit_count(significand);
  const int scientific_exponent = n - 1 + exponent;
  if (scientific_exponent < -99 || scientific_exponent > 99) return fallback(first, value);

  // Lengths without the sign: d[.ddd]e±XX against ddd.ddd, ddd or 0.000ddd.
  const int scientific_length = n + (n > 1 ? 1 : 0) + 4;
  const int integer_digits = n + exponent;  // digits before the point (exponent <= 0)
  const int fixed_length = exponent == 0 ? n : (integer_digits > 0 ? n + 1 : 2 - exponent);

  char* p = first;
  if (value < 0) *p++ = '-';
  if (fixed_length <= scientific_length) {
    if (exponent == 0) {
      write_digits(significand, p, n);
      return p + n;
    }
    if (integer_digits > 0) {  // ddd.ddd: the digits one place on, then the integer part back
      write_digits(significand, p + 1, n);
      for (int i = 0; i < integer_digits; ++i) p[i] = p[i + 1];
      p[integer_digits] = '.';
      return p + n + 1;
    }
    *p++ = '0';
    *p++ = '.';
    for (int i = 0; i < -integer_digits; ++i) *p++ = '0';
    write_digits(significand, p, n);
    return p + n;
  }
  write_digits(significand, p + 1, n);  // d.ddde±XX: the first digit back before the point
  p[0] = p[1];
  if (n > 1) {
    p[1] = '.';
    p += n + 1;
  } else {
    p += 1;
  }
  *p++ = 'e';
  *p++ = scientific_exponent < 0 ? '-' : '+';
  const int magnitude = scientific_exponent < 0 ? -scientific_exponent : scientific_exponent;
  std::memcpy(p, kPairs + 2 * magnitude, 2);
  return p + 2;
}

}  // namespace odonav
