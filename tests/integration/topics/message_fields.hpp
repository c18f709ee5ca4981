#pragma once
// Test helpers: every message of the contract as an ordered list of (field path, value text), field
// names and order as in the ROS .msg twins (idl/<pkg>/msg/*.msg). Used two ways:
//  - round trip: fields(sent) == fields(received) compares every field, and names it on failure;
//  - layout: the .msg-driven CDR decoder must produce exactly fields(sample) from the bytes the
//    generated type serializes, which checks the .msg twins against the real wire layout.
// And sample makers that set every field to a distinctive non-default value (fixed seed).
#include <cstdint>
#include <cstdio>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "odonav/dds/types.hpp"

namespace odonav::test {

using Fields = std::vector<std::pair<std::string, std::string>>;

inline std::string text(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}
inline std::string text(bool v) { return v ? "true" : "false"; }
inline std::string text(std::int8_t v) { return std::to_string(static_cast<int>(v)); }
inline std::string text(std::uint8_t v) { return std::to_string(static_cast<unsigned>(v)); }
inline std::string text(std::int32_t v) { return std::to_string(v); }
inline std::string text(std::uint32_t v) { return std::to_string(v); }
inline std::string text(const std::string& v) { return "\"" + v + "\""; }

inline void add_header(Fields& f, const std_msgs::msg::Header& h) {
  f.emplace_back("header.stamp.sec", text(h.stamp().sec()));
  f.emplace_back("header.stamp.nanosec", text(h.stamp().nanosec()));
  f.emplace_back("header.frame_id", text(h.frame_id()));
}

inline Fields fields(const odonav::msg::Odometer& m) {
  Fields f;
  add_header(f, m.header());
  f.emplace_back("vehicle_id", text(m.vehicle_id()));
  f.emplace_back("pulses", text(m.pulses()));
  f.emplace_back("direction", text(m.direction()));
  f.emplace_back("gnss_complete_known", text(m.gnss_complete_known()));
  f.emplace_back("gnss_complete_through_s", text(m.gnss_complete_through_s()));
  f.emplace_back("gnss_last_stamp_s", text(m.gnss_last_stamp_s()));
  return f;
}

inline Fields fields(const odonav::msg::InsAttitude& m) {
  Fields f;
  add_header(f, m.header());
  f.emplace_back("vehicle_id", text(m.vehicle_id()));
  f.emplace_back("heading_rad", text(m.heading_rad()));
  f.emplace_back("pitch_rad", text(m.pitch_rad()));
  f.emplace_back("roll_rad", text(m.roll_rad()));
  f.emplace_back("velocity_east_mps", text(m.velocity_east_mps()));
  f.emplace_back("velocity_north_mps", text(m.velocity_north_mps()));
  f.emplace_back("velocity_up_mps", text(m.velocity_up_mps()));
  f.emplace_back("velocity_valid", text(m.velocity_valid()));
  f.emplace_back("valid", text(m.valid()));
  f.emplace_back("gnss_complete_known", text(m.gnss_complete_known()));
  f.emplace_back("gnss_complete_through_s", text(m.gnss_complete_through_s()));
  f.emplace_back("gnss_last_stamp_s", text(m.gnss_last_stamp_s()));
  return f;
}

inline Fields fields(const odonav::msg::GnssFix& m) {
  Fields f;
  add_header(f, m.header());
  f.emplace_back("vehicle_id", text(m.vehicle_id()));
  f.emplace_back("latitude_deg", text(m.latitude_deg()));
  f.emplace_back("longitude_deg", text(m.longitude_deg()));
  f.emplace_back("height_m", text(m.height_m()));
  f.emplace_back("velocity_east_mps", text(m.velocity_east_mps()));
  f.emplace_back("velocity_north_mps", text(m.velocity_north_mps()));
  f.emplace_back("velocity_up_mps", text(m.velocity_up_mps()));
  f.emplace_back("fix_quality", text(m.fix_quality()));
  f.emplace_back("position_std_m", text(m.position_std_m()));
  f.emplace_back("velocity_std_mps", text(m.velocity_std_mps()));
  f.emplace_back("valid", text(m.valid()));
  return f;
}

inline Fields fields(const odonav::msg::Misalignment& m) {
  Fields f;
  add_header(f, m.header());
  f.emplace_back("vehicle_id", text(m.vehicle_id()));
  f.emplace_back("heading_rad", text(m.heading_rad()));
  f.emplace_back("pitch_rad", text(m.pitch_rad()));
  f.emplace_back("heading_std_rad", text(m.heading_std_rad()));
  f.emplace_back("pitch_std_rad", text(m.pitch_std_rad()));
  f.emplace_back("samples_used", text(m.samples_used()));
  f.emplace_back("converged", text(m.converged()));
  f.emplace_back("state", text(static_cast<std::uint32_t>(m.state())));
  return f;
}

inline Fields fields(const odonav::msg::ScaleFactor& m) {
  Fields f;
  add_header(f, m.header());
  f.emplace_back("vehicle_id", text(m.vehicle_id()));
  f.emplace_back("k_m_per_pulse", text(m.k_m_per_pulse()));
  f.emplace_back("sigma_m_per_pulse", text(m.sigma_m_per_pulse()));
  f.emplace_back("forgetting_factor", text(m.forgetting_factor()));
  f.emplace_back("window_fill", text(m.window_fill()));
  f.emplace_back("estimator", text(m.estimator()));
  f.emplace_back("converged", text(m.converged()));
  f.emplace_back("samples_accepted", text(m.samples_accepted()));
  f.emplace_back("samples_rejected", text(m.samples_rejected()));
  f.emplace_back("frozen", text(m.frozen()));
  f.emplace_back("source", text(m.source()));
  f.emplace_back("source_priority", text(m.source_priority()));
  f.emplace_back("gnss_latency_s", text(m.gnss_latency_s()));
  f.emplace_back("gnss_latency_sigma_s", text(m.gnss_latency_sigma_s()));
  f.emplace_back("turn_slip_s_per_rad", text(m.turn_slip_s_per_rad()));
  f.emplace_back("turn_slip_sigma_s_per_rad", text(m.turn_slip_sigma_s_per_rad()));
  f.emplace_back("turn_slip_threshold_radps", text(m.turn_slip_threshold_radps()));
  f.emplace_back("turn_slip_applies", text(m.turn_slip_applies()));
  return f;
}

inline Fields fields(const odonav::msg::DeadReckoning& m) {
  Fields f;
  add_header(f, m.header());
  f.emplace_back("vehicle_id", text(m.vehicle_id()));
  f.emplace_back("latitude_deg", text(m.latitude_deg()));
  f.emplace_back("longitude_deg", text(m.longitude_deg()));
  f.emplace_back("height_m", text(m.height_m()));
  f.emplace_back("enu_east_m", text(m.enu_east_m()));
  f.emplace_back("enu_north_m", text(m.enu_north_m()));
  f.emplace_back("enu_up_m", text(m.enu_up_m()));
  f.emplace_back("origin_latitude_deg", text(m.origin_latitude_deg()));
  f.emplace_back("origin_longitude_deg", text(m.origin_longitude_deg()));
  f.emplace_back("origin_height_m", text(m.origin_height_m()));
  f.emplace_back("heading_rad", text(m.heading_rad()));
  f.emplace_back("distance_m", text(m.distance_m()));
  f.emplace_back("k_m_per_pulse", text(m.k_m_per_pulse()));
  f.emplace_back("k_source", text(static_cast<std::uint32_t>(m.k_source())));
  f.emplace_back("misalignment_heading_rad", text(m.misalignment_heading_rad()));
  f.emplace_back("misalignment_pitch_rad", text(m.misalignment_pitch_rad()));
  f.emplace_back("gnss_valid", text(m.gnss_valid()));
  f.emplace_back("horizontal_error_m", text(m.horizontal_error_m()));
  f.emplace_back("error_percent_distance", text(m.error_percent_distance()));
  f.emplace_back("error_t_s", text(m.error_t_s()));
  return f;
}

inline Fields fields(const odonav::msg::NavigationPosition& m) {
  Fields f;
  add_header(f, m.header());
  f.emplace_back("vehicle_id", text(m.vehicle_id()));
  f.emplace_back("latitude_deg", text(m.latitude_deg()));
  f.emplace_back("longitude_deg", text(m.longitude_deg()));
  f.emplace_back("height_m", text(m.height_m()));
  f.emplace_back("enu_east_m", text(m.enu_east_m()));
  f.emplace_back("enu_north_m", text(m.enu_north_m()));
  f.emplace_back("enu_up_m", text(m.enu_up_m()));
  f.emplace_back("position_covariance_east_m2", text(m.position_covariance_east_m2()));
  f.emplace_back("position_covariance_north_m2", text(m.position_covariance_north_m2()));
  f.emplace_back("position_covariance_up_m2", text(m.position_covariance_up_m2()));
  f.emplace_back("position_covariance_type", text(m.position_covariance_type()));
  f.emplace_back("status", text(static_cast<std::uint32_t>(m.status())));
  f.emplace_back("last_fix_stamp_s", text(m.last_fix_stamp_s()));
  f.emplace_back("distance_since_fix_m", text(m.distance_since_fix_m()));
  return f;
}

inline Fields fields(const odonav::msg::Health& m) {
  Fields f;
  add_header(f, m.header());
  f.emplace_back("vehicle_id", text(m.vehicle_id()));
  f.emplace_back("component", text(m.component()));
  f.emplace_back("state", text(static_cast<std::uint32_t>(m.state())));
  f.emplace_back("level", text(static_cast<std::uint32_t>(m.level())));
  f.emplace_back("reason", text(m.reason()));
  for (std::size_t i = 0; i < m.counters().size(); ++i) {
    const std::string at = "counters[" + std::to_string(i) + "].";
    f.emplace_back(at + "name", text(m.counters()[i].name()));
    f.emplace_back(at + "value", text(m.counters()[i].value()));
  }
  f.emplace_back("last_command_id", text(m.last_command_id()));
  f.emplace_back("last_command_result", text(static_cast<std::uint32_t>(m.last_command_result())));
  f.emplace_back("last_command_detail", text(m.last_command_detail()));
  return f;
}

inline Fields fields(const odonav::msg::Command& m) {
  Fields f;
  add_header(f, m.header());
  f.emplace_back("vehicle_id", text(m.vehicle_id()));
  f.emplace_back("target_component", text(m.target_component()));
  f.emplace_back("command", text(static_cast<std::uint32_t>(m.command())));
  f.emplace_back("value", text(m.value()));
  f.emplace_back("command_id", text(m.command_id()));
  return f;
}

/// Distinctive values: every double different from every other and from 0, fixed seed.
class Distinct {
 public:
  explicit Distinct(unsigned seed) : rng_(seed) {}
  double next() { return std::uniform_real_distribution<double>(-1000.0, 1000.0)(rng_) + 1e-3; }

 private:
  std::mt19937 rng_;
};

inline std_msgs::msg::Header distinct_header(const std::string& frame_id) {
  std_msgs::msg::Header h;
  h.stamp().sec(1700000123);
  h.stamp().nanosec(987654321);
  h.frame_id(frame_id);
  return h;
}

inline odonav::msg::Odometer make_odometer() {
  odonav::msg::Odometer m;
  m.header(distinct_header("odometer"));
  m.vehicle_id("vehicle-odometer-7");
  m.pulses(4294967295u);  // the top of the wrapping counter
  m.direction(-1);
  m.gnss_complete_known(true);
  m.gnss_complete_through_s(1234.5678901);
  m.gnss_last_stamp_s(1234.4678901);
  return m;
}

inline odonav::msg::InsAttitude make_ins_attitude() {
  Distinct d(101);
  odonav::msg::InsAttitude m;
  m.header(distinct_header("body"));
  m.vehicle_id("vehicle-ins-7");
  m.heading_rad(d.next());
  m.pitch_rad(d.next());
  m.roll_rad(d.next());
  m.velocity_east_mps(d.next());
  m.velocity_north_mps(d.next());
  m.velocity_up_mps(d.next());
  m.velocity_valid(true);
  m.valid(true);
  m.gnss_complete_known(true);
  m.gnss_complete_through_s(d.next());
  m.gnss_last_stamp_s(d.next());
  return m;
}

inline odonav::msg::GnssFix make_gnss_fix() {
  Distinct d(102);
  odonav::msg::GnssFix m;
  m.header(distinct_header("wgs84"));
  m.vehicle_id("vehicle-gnss-7");
  m.latitude_deg(d.next());
  m.longitude_deg(d.next());
  m.height_m(d.next());
  m.velocity_east_mps(d.next());
  m.velocity_north_mps(d.next());
  m.velocity_up_mps(d.next());
  m.fix_quality(5);
  m.position_std_m(d.next());
  m.velocity_std_mps(d.next());
  m.valid(true);
  return m;
}

inline odonav::msg::Misalignment make_misalignment() {
  Distinct d(103);
  odonav::msg::Misalignment m;
  m.header(distinct_header("body"));
  m.vehicle_id("vehicle-mis-7");
  m.heading_rad(d.next());
  m.pitch_rad(d.next());
  m.heading_std_rad(d.next());
  m.pitch_std_rad(d.next());
  m.samples_used(600123);
  m.converged(true);
  m.state(odonav::msg::MISALIGNMENT_FROZEN);
  return m;
}

inline odonav::msg::ScaleFactor make_scale_factor() {
  Distinct d(104);
  odonav::msg::ScaleFactor m;
  m.header(distinct_header("odometer"));
  m.vehicle_id("vehicle-k-7");
  m.k_m_per_pulse(d.next());
  m.sigma_m_per_pulse(d.next());
  m.forgetting_factor(d.next());
  m.window_fill(d.next());
  m.estimator("vff-lm-rls");
  m.converged(true);
  m.samples_accepted(123457);
  m.samples_rejected(8765);
  m.frozen(true);
  m.source("identification/standby-7");
  m.source_priority(4000000007u);
  m.gnss_latency_s(d.next());
  m.gnss_latency_sigma_s(d.next());
  m.turn_slip_s_per_rad(d.next());
  m.turn_slip_sigma_s_per_rad(d.next());
  m.turn_slip_threshold_radps(d.next());
  m.turn_slip_applies(true);
  return m;
}

inline odonav::msg::DeadReckoning make_dead_reckoning() {
  Distinct d(105);
  odonav::msg::DeadReckoning m;
  m.header(distinct_header("wgs84"));
  m.vehicle_id("vehicle-dr-7");
  m.latitude_deg(d.next());
  m.longitude_deg(d.next());
  m.height_m(d.next());
  m.enu_east_m(d.next());
  m.enu_north_m(d.next());
  m.enu_up_m(d.next());
  m.origin_latitude_deg(d.next());
  m.origin_longitude_deg(d.next());
  m.origin_height_m(d.next());
  m.heading_rad(d.next());
  m.distance_m(d.next());
  m.k_m_per_pulse(d.next());
  m.k_source(odonav::msg::K_SOURCE_COMMANDED);
  m.misalignment_heading_rad(d.next());
  m.misalignment_pitch_rad(d.next());
  m.gnss_valid(true);
  m.horizontal_error_m(d.next());
  m.error_percent_distance(d.next());
  m.error_t_s(d.next());
  return m;
}

inline odonav::msg::NavigationPosition make_navigation_position() {
  Distinct d(108);
  odonav::msg::NavigationPosition m;
  m.header(distinct_header("wgs84"));
  m.vehicle_id("vehicle-nav-7");
  m.latitude_deg(d.next());
  m.longitude_deg(d.next());
  m.height_m(d.next());
  m.enu_east_m(d.next());
  m.enu_north_m(d.next());
  m.enu_up_m(d.next());
  m.position_covariance_east_m2(d.next());
  m.position_covariance_north_m2(d.next());
  m.position_covariance_up_m2(d.next());
  m.position_covariance_type(2);
  m.status(odonav::msg::NAVIGATION_STATUS_DEAD_RECKONING);
  m.last_fix_stamp_s(d.next());
  m.distance_since_fix_m(d.next());
  return m;
}

inline odonav::msg::Health make_health_sample() {
  Distinct d(106);
  odonav::msg::Health m;
  m.header(distinct_header("health-frame"));
  m.vehicle_id("vehicle-health-7");
  m.component("odonav-identification");
  m.state(odonav::msg::HEALTH_STATE_DEGRADED);
  m.level(odonav::msg::HEALTH_LEVEL_STALE);
  m.reason("GNSS lost for 12.5 s");
  for (const char* name : {"samples_accepted", "bad_rows", "queue_depth"}) {
    odonav::msg::Counter c;
    c.name(name);
    c.value(d.next());
    m.counters().push_back(c);
  }
  m.last_command_id(4242);
  m.last_command_result(odonav::msg::COMMAND_RESULT_REJECTED);
  m.last_command_detail("value 0 is not a valid K");
  return m;
}

inline odonav::msg::Command make_command() {
  odonav::msg::Command m;
  m.header(distinct_header("ground"));
  m.vehicle_id("vehicle-cmd-7");
  m.target_component("odonav-identification");
  m.command(odonav::msg::COMMAND_UNFREEZE_ESTIMATION);
  m.value(0.0125001234);
  m.command_id(3999999999u);
  return m;
}

}  // namespace odonav::test
