#include "odonav/dds/time.hpp"

#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace odonav::dds {

namespace {
constexpr std::int64_t kNanosecondsPerSecond = 1000000000;

[[noreturn]] void throw_bad_seconds(double seconds, const char* why) {
  std::ostringstream msg;
  msg.precision(17);
  msg << "odonav::dds::to_time_msg: time " << seconds << " s " << why;
  throw std::invalid_argument(msg.str());
}
}  // namespace

builtin_interfaces::msg::Time to_time_msg(double seconds) {
  if (!std::isfinite(seconds)) throw_bad_seconds(seconds, "is not finite");
  constexpr double kMinSec = std::numeric_limits<std::int32_t>::min();
  constexpr double kMaxSec = std::numeric_limits<std::int32_t>::max();
  double whole = std::floor(seconds);
  if (whole < kMinSec || whole > kMaxSec) throw_bad_seconds(seconds, "does not fit int32 seconds");
  // seconds - floor(seconds) is exact in double (a multiple of ulp(seconds), below 1); the product
  // by 1e9 rounds once, then to the nearest nanosecond.
  std::int64_t nanosec = std::llround((seconds - whole) * 1e9);
  if (nanosec >= kNanosecondsPerSecond) {
    nanosec -= kNanosecondsPerSecond;
    whole += 1.0;
    if (whole > kMaxSec) throw_bad_seconds(seconds, "does not fit int32 seconds");
  }
  builtin_interfaces::msg::Time time;
  time.sec(static_cast<std::int32_t>(whole));
  time.nanosec(static_cast<std::uint32_t>(nanosec));
  return time;
}

double to_seconds(const builtin_interfaces::msg::Time& time) {
  if (time.nanosec() >= kNanosecondsPerSecond) {
    throw std::invalid_argument("odonav::dds::to_seconds: Time {sec " + std::to_string(time.sec()) + ", nanosec " +
                                std::to_string(time.nanosec()) + "} is not normalized (nanosec must be < 1000000000)");
  }
  return static_cast<double>(time.sec()) + static_cast<double>(time.nanosec()) / 1e9;
}

std_msgs::msg::Header make_header(double stamp_s, const std::string& frame_id) {
  std_msgs::msg::Header header;
  header.stamp(to_time_msg(stamp_s));
  header.frame_id(frame_id);
  return header;
}

}  // namespace odonav::dds
