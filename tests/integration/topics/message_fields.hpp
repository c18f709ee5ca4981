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
#include <type_traits>
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

template <class E, class = std::enable_if_t<std::is_enum<E>::value>>
std::string text(E v) {
  return text(static_cast<std::uint32_t>(v));
}

/// v(name, member) for each (name, member reference) pair, in order.
template <class V>
void each(V&) {}
template <class V, class T, class... Rest>
void each(V& v, const char* name, T& member, Rest&&... rest) {
  v(std::string(name), member);
  each(v, std::forward<Rest>(rest)...);
}

// Every field of every message once, in .msg order: visit(m, v) calls v(path, reference to the
// member). One list serves reading (fields) and writing (the distinct sample makers).
template <class V>
void visit_header(std_msgs::msg::Header& h, V& v) {
  each(v, "header.stamp.sec", h.stamp().sec(), "header.stamp.nanosec", h.stamp().nanosec(), "header.frame_id",
       h.frame_id());
}

/// WGS84 position and its local ENU twin: the same six fields in DeadReckoning and NavigationPosition.
template <class M, class V>
void visit_position_enu(M& m, V& v) {
  each(v, "latitude_deg", m.latitude_deg(), "longitude_deg", m.longitude_deg(), "height_m", m.height_m(), "enu_east_m",
       m.enu_east_m(), "enu_north_m", m.enu_north_m(), "enu_up_m", m.enu_up_m());
}

template <class V>
void visit(odonav::msg::Odometer& m, V&& v) {
  visit_header(m.header(), v);
  each(v, "vehicle_id", m.vehicle_id(), "pulses", m.pulses(), "direction", m.direction(), "gnss_complete_known",
       m.gnss_complete_known(), "gnss_complete_through_s", m.gnss_complete_through_s(), "gnss_last_stamp_s",
       m.gnss_last_stamp_s());
}

template <class V>
void visit(odonav::msg::InsAttitude& m, V&& v) {
  visit_header(m.header(), v);
  each(v, "vehicle_id", m.vehicle_id(), "heading_rad", m.heading_rad(), "pitch_rad", m.pitch_rad(), "roll_rad",
       m.roll_rad(), "velocity_east_mps", m.velocity_east_mps(), "velocity_north_mps", m.velocity_north_mps(),
       "velocity_up_mps", m.velocity_up_mps(), "velocity_valid", m.velocity_valid(), "valid", m.valid(),
       "gnss_complete_known", m.gnss_complete_known(), "gnss_complete_through_s", m.gnss_complete_through_s(),
       "gnss_last_stamp_s", m.gnss_last_stamp_s());
}

template <class V>
void visit(odonav::msg::GnssFix& m, V&& v) {
  visit_header(m.header(), v);
  each(v, "vehicle_id", m.vehicle_id(), "latitude_deg", m.latitude_deg(), "longitude_deg", m.longitude_deg(),
       "height_m", m.height_m(), "velocity_east_mps", m.velocity_east_mps(), "velocity_north_mps",
       m.velocity_north_mps(), "velocity_up_mps", m.velocity_up_mps(), "fix_quality", m.fix_quality(), "position_std_m",
       m.position_std_m(), "velocity_std_mps", m.velocity_std_mps(), "valid", m.valid());
}

template <class V>
void visit(odonav::msg::Misalignment& m, V&& v) {
  visit_header(m.header(), v);
  each(v, "vehicle_id", m.vehicle_id(), "heading_rad", m.heading_rad(), "pitch_rad", m.pitch_rad(), "heading_std_rad",
       m.heading_std_rad(), "pitch_std_rad", m.pitch_std_rad(), "samples_used", m.samples_used(), "converged",
       m.converged(), "state", m.state());
}

template <class V>
void visit(odonav::msg::ScaleFactor& m, V&& v) {
  visit_header(m.header(), v);
  each(v, "vehicle_id", m.vehicle_id(), "k_m_per_pulse", m.k_m_per_pulse(), "sigma_m_per_pulse", m.sigma_m_per_pulse(),
       "forgetting_factor", m.forgetting_factor(), "window_fill", m.window_fill(), "estimator", m.estimator(),
       "converged", m.converged(), "samples_accepted", m.samples_accepted(), "samples_rejected", m.samples_rejected(),
       "frozen", m.frozen(), "source", m.source(), "source_priority", m.source_priority(), "gnss_latency_s",
       m.gnss_latency_s(), "gnss_latency_sigma_s", m.gnss_latency_sigma_s(), "turn_slip_s_per_rad",
       m.turn_slip_s_per_rad(), "turn_slip_sigma_s_per_rad", m.turn_slip_sigma_s_per_rad(), "turn_slip_threshold_radps",
       m.turn_slip_threshold_radps(), "turn_slip_applies", m.turn_slip_applies());
}

template <class V>
void visit(odonav::msg::DeadReckoning& m, V&& v) {
  visit_header(m.header(), v);
  each(v, "vehicle_id", m.vehicle_id());
  visit_position_enu(m, v);
  each(v, "origin_latitude_deg", m.origin_latitude_deg(), "origin_longitude_deg", m.origin_longitude_deg(),
       "origin_height_m", m.origin_height_m(), "heading_rad", m.heading_rad(), "distance_m", m.distance_m(),
       "k_m_per_pulse", m.k_m_per_pulse(), "k_source", m.k_source(), "misalignment_heading_rad",
       m.misalignment_heading_rad(), "misalignment_pitch_rad", m.misalignment_pitch_rad(), "gnss_valid", m.gnss_valid(),
       "horizontal_error_m", m.horizontal_error_m(), "error_percent_distance", m.error_percent_distance(), "error_t_s",
       m.error_t_s());
}

template <class V>
void visit(odonav::msg::NavigationPosition& m, V&& v) {
  visit_header(m.header(), v);
  each(v, "vehicle_id", m.vehicle_id());
  visit_position_enu(m, v);
  each(v, "position_covariance_east_m2", m.position_covariance_east_m2(), "position_covariance_north_m2",
       m.position_covariance_north_m2(), "position_covariance_up_m2", m.position_covariance_up_m2(),
       "position_covariance_type", m.position_covariance_type(), "status", m.status(), "last_fix_stamp_s",
       m.last_fix_stamp_s(), "distance_since_fix_m", m.distance_since_fix_m());
}

template <class V>
void visit(odonav::msg::Health& m, V&& v) {
  visit_header(m.header(), v);
  each(v, "vehicle_id", m.vehicle_id(), "component", m.component(), "state", m.state(), "level", m.level(), "reason",
       m.reason());
  for (std::size_t i = 0; i < m.counters().size(); ++i) {
    const std::string at = "counters[" + std::to_string(i) + "].";
    v(at + "name", m.counters()[i].name());
    v(at + "value", m.counters()[i].value());
  }
  each(v, "last_command_id", m.last_command_id(), "last_command_result", m.last_command_result(), "last_command_detail",
       m.last_command_detail());
}

template <class V>
void visit(odonav::msg::Command& m, V&& v) {
  visit_header(m.header(), v);
  each(v, "vehicle_id", m.vehicle_id(), "target_component", m.target_component(), "command", m.command(), "value",
       m.value(), "command_id", m.command_id());
}

/// Every field as (path, value text), in .msg order.
template <class M>
Fields fields(const M& m) {
  M copy = m;  // visit hands out references to write through; reading goes through a copy
  Fields f;
  visit(copy, [&f](const std::string& path, const auto& value) { f.emplace_back(path, text(value)); });
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

/// A sample with the distinct header, the vehicle, every double drawn from Distinct(seed) in .msg
/// order and every bool true; integers, enums and other strings are for the caller to set.
template <class M>
M distinct_sample(M m, unsigned seed, const std::string& frame_id, const std::string& vehicle_id) {
  m.header(distinct_header(frame_id));
  m.vehicle_id(vehicle_id);
  Distinct d(seed);
  visit(m, [&d](const std::string&, auto& value) {
    using T = std::decay_t<decltype(value)>;
    if constexpr (std::is_same<T, double>::value) value = d.next();
    if constexpr (std::is_same<T, bool>::value) value = true;
  });
  return m;
}

inline odonav::msg::Odometer make_odometer() {
  odonav::msg::Odometer m = distinct_sample(odonav::msg::Odometer{}, 0, "odometer", "vehicle-odometer-7");
  m.pulses(4294967295u);  // the top of the wrapping counter
  m.direction(-1);
  m.gnss_complete_through_s(1234.5678901);
  m.gnss_last_stamp_s(1234.4678901);
  return m;
}

inline odonav::msg::InsAttitude make_ins_attitude() {
  return distinct_sample(odonav::msg::InsAttitude{}, 101, "body", "vehicle-ins-7");
}

inline odonav::msg::GnssFix make_gnss_fix() {
  odonav::msg::GnssFix m = distinct_sample(odonav::msg::GnssFix{}, 102, "wgs84", "vehicle-gnss-7");
  m.fix_quality(5);
  return m;
}

inline odonav::msg::Misalignment make_misalignment() {
  odonav::msg::Misalignment m = distinct_sample(odonav::msg::Misalignment{}, 103, "body", "vehicle-mis-7");
  m.samples_used(600123);
  m.state(odonav::msg::MISALIGNMENT_FROZEN);
  return m;
}

inline odonav::msg::ScaleFactor make_scale_factor() {
  odonav::msg::ScaleFactor m = distinct_sample(odonav::msg::ScaleFactor{}, 104, "odometer", "vehicle-k-7");
  m.estimator("vff-lm-rls");
  m.samples_accepted(123457);
  m.samples_rejected(8765);
  m.source("identification/standby-7");
  m.source_priority(4000000007u);
  return m;
}

inline odonav::msg::DeadReckoning make_dead_reckoning() {
  odonav::msg::DeadReckoning m = distinct_sample(odonav::msg::DeadReckoning{}, 105, "wgs84", "vehicle-dr-7");
  m.k_source(odonav::msg::K_SOURCE_COMMANDED);
  return m;
}

inline odonav::msg::NavigationPosition make_navigation_position() {
  odonav::msg::NavigationPosition m = distinct_sample(odonav::msg::NavigationPosition{}, 108, "wgs84", "vehicle-nav-7");
  m.position_covariance_type(2);
  m.status(odonav::msg::NAVIGATION_STATUS_DEAD_RECKONING);
  return m;
}

inline odonav::msg::Health make_health_sample() {
  odonav::msg::Health m;
  for (const char* name : {"samples_accepted", "bad_rows", "queue_depth"}) {
    odonav::msg::Counter c;
    c.name(name);
    m.counters().push_back(c);  // the values come from Distinct below
  }
  m = distinct_sample(m, 106, "health-frame", "vehicle-health-7");
  m.component("odonav-identification");
  m.state(odonav::msg::HEALTH_STATE_DEGRADED);
  m.level(odonav::msg::HEALTH_LEVEL_STALE);
  m.reason("GNSS lost for 12.5 s");
  m.last_command_id(4242);
  m.last_command_result(odonav::msg::COMMAND_RESULT_REJECTED);
  m.last_command_detail("value 0 is not a valid K");
  return m;
}

inline odonav::msg::Command make_command() {
  odonav::msg::Command m = distinct_sample(odonav::msg::Command{}, 0, "ground", "vehicle-cmd-7");
  m.target_component("odonav-identification");
  m.command(odonav::msg::COMMAND_UNFREEZE_ESTIMATION);
  m.value(0.0125001234);
  m.command_id(3999999999u);
  return m;
}

}  // namespace odonav::test
