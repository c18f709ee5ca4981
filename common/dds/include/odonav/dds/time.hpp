#pragma once
// Seconds (double, the dataset's time base) <-> builtin_interfaces/msg/Time and std_msgs Header.
#include <string>

#include "builtin_interfaces/msg/Time.h"
#include "std_msgs/msg/Header.h"

namespace odonav::dds {

/// Converts a time in seconds to a ROS Time {sec, nanosec}: odonav::to_wire_time (odonav/wire_time.hpp),
/// the one rounding odonav-offline applies too. sec is floor(seconds) and nanosec the fraction rounded
/// to the nearest nanosecond, in [0, 1e9). So -0.25 s is {-1, 750000000}.
/// Exactness: a double holds a nanosecond exactly only while its ulp is below 1 ns, i.e. for
/// |seconds| < 2^22 s (48 days: GNSS time of week, seconds since start). There
/// to_time_msg(to_seconds(t)) == t for every t. UNIX times (~1.7e9 s) carry ~0.24 us resolution.
/// Valid range: finite seconds whose floor fits int32 ([-2147483648, 2147483647.9999999995]).
/// Throws std::invalid_argument, naming the value, outside it (NaN, infinity, beyond 2038).
builtin_interfaces::msg::Time to_time_msg(double seconds);

/// Converts a ROS Time to seconds: sec + nanosec * 1e-9, rounded once to the nearest double.
/// Throws std::invalid_argument if nanosec >= 1e9 (not a normalized Time, e.g. from a bad peer).
double to_seconds(const builtin_interfaces::msg::Time& time);

/// A Header with stamp = to_time_msg(stamp_s) (acquisition time, same rules and errors) and frame_id.
std_msgs::msg::Header make_header(double stamp_s, const std::string& frame_id);

}  // namespace odonav::dds
