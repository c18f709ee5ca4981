#include "odonav/wire_time.hpp"

#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>

namespace odonav {

namespace {
constexpr std::int64_t kNanosecondsPerSecond = 1000000000;

[[noreturn]] void throw_bad_seconds(double seconds, const char* why) {
  std::ostringstream msg;
  msg.precision(17);
  msg << "time " << seconds << " s " << why;
  throw std::invalid_argument(msg.str());
}

// The one split of a time into {sec, nanosec}; false (and why set) when it does not fit.
bool split_wire_time(double t_s, WireTime& out, const char*& why) {
  if (!std::isfinite(t_s)) {
    why = "is not finite";
    return false;
  }
  constexpr double kMinSec = std::numeric_limits<std::int32_t>::min();
  constexpr double kMaxSec = std::numeric_limits<std::int32_t>::max();
  double whole = std::floor(t_s);
  why = "does not fit int32 seconds";
  if (whole < kMinSec || whole > kMaxSec) return false;
  // t_s - floor(t_s) is exact in double (a multiple of ulp(t_s), below 1); the product by 1e9
  // rounds once, then to the nearest nanosecond.
  std::int64_t nanosec = std::llround((t_s - whole) * 1e9);
  if (nanosec >= kNanosecondsPerSecond) {
    nanosec -= kNanosecondsPerSecond;
    whole += 1.0;
    if (whole > kMaxSec) return false;
  }
  out = WireTime{static_cast<std::int32_t>(whole), static_cast<std::uint32_t>(nanosec)};
  return true;
}
}  // namespace

WireTime to_wire_time(double t_s) {
  WireTime w;
  const char* why = "";
  if (!split_wire_time(t_s, w, why)) throw_bad_seconds(t_s, why);
  return w;
}

bool fits_wire_time(double t_s) {
  WireTime w;
  const char* why = "";
  return split_wire_time(t_s, w, why);
}

double from_wire_time(std::int32_t sec, std::uint32_t nanosec) {
  if (nanosec >= kNanosecondsPerSecond) {
    throw std::invalid_argument("time {sec " + std::to_string(sec) + ", nanosec " + std::to_string(nanosec) +
                                "} is not normalized (nanosec must be < 1000000000)");
  }
  return static_cast<double>(sec) + static_cast<double>(nanosec) / 1e9;
}

double wire_time_s(double t_s) {
  const WireTime w = to_wire_time(t_s);
  return from_wire_time(w.sec, w.nanosec);
}

}  // namespace odonav
