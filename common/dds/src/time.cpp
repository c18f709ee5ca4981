#include "odonav/dds/time.hpp"

#include <stdexcept>
#include <string>

#include "odonav/wire_time.hpp"

namespace odonav::dds {

builtin_interfaces::msg::Time to_time_msg(double seconds) {
  WireTime w;
  try {
    w = to_wire_time(seconds);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("odonav::dds::to_time_msg: ") + e.what());
  }
  builtin_interfaces::msg::Time time;
  time.sec(w.sec);
  time.nanosec(w.nanosec);
  return time;
}

double to_seconds(const builtin_interfaces::msg::Time& time) {
  try {
    return from_wire_time(time.sec(), time.nanosec());
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("odonav::dds::to_seconds: ") + e.what());
  }
}

std_msgs::msg::Header make_header(double stamp_s, const std::string& frame_id) {
  std_msgs::msg::Header header;
  header.stamp(to_time_msg(stamp_s));
  header.frame_id(frame_id);
  return header;
}

}  // namespace odonav::dds
