#include "odonav/dds/output_messages.hpp"

#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>

#include "odonav/dds/time.hpp"
#include "odonav/frames.hpp"

namespace odonav::dds {

namespace {

// The enumerations: the IDL constant and the name the output files use for it.
const std::pair<odonav::msg::MisalignmentState, const char*> kMisalignmentStates[] = {
    {odonav::msg::MISALIGNMENT_WAITING, "waiting"},
    {odonav::msg::MISALIGNMENT_CALIBRATING, "calibrating"},
    {odonav::msg::MISALIGNMENT_CONVERGED, "converged"},
    {odonav::msg::MISALIGNMENT_FROZEN, "frozen"}};
const std::pair<odonav::msg::KSource, const char*> kKSources[] = {{odonav::msg::K_SOURCE_NOMINAL, "nominal"},
                                                                  {odonav::msg::K_SOURCE_IDENTIFIED, "identified"},
                                                                  {odonav::msg::K_SOURCE_COMMANDED, "commanded"}};
const std::pair<odonav::msg::NavigationStatus, const char*> kNavigationStatuses[] = {
    {odonav::msg::NAVIGATION_STATUS_NOT_STARTED, "not_started"},
    {odonav::msg::NAVIGATION_STATUS_ANCHORED, "anchored"},
    {odonav::msg::NAVIGATION_STATUS_DEAD_RECKONING, "dead_reckoning"}};

// The field tables: one line per field both the row and the message have, in IDL order. Row and Msg
// are const on the side that is read; V is ToMessage or FromMessage below.
template <class Row, class Msg, class V>
void misalignment_fields(Row& r, Msg& m, V&& v) {
  v.stamp(r.t_s, m.header(), "body");
  v.number(r.heading_rad, m.heading_rad());
  v.number(r.pitch_rad, m.pitch_rad());
  v.unknown(r.heading_std_rad, m.heading_std_rad());
  v.unknown(r.pitch_std_rad, m.pitch_std_rad());
  v.count(r.samples_used, m.samples_used());
  v.flag(r.converged, m.converged());
  v.choice(r.state, m.state(), kMisalignmentStates);
}

template <class Row, class Msg, class V>
void scale_factor_fields(Row& r, Msg& m, V&& v) {
  v.stamp(r.t_s, m.header(), "odometer");
  v.value_or_zero(r.k_m_per_pulse, m.k_m_per_pulse());
  v.unknown(r.sigma_m_per_pulse, m.sigma_m_per_pulse());
  v.number(r.forgetting_factor, m.forgetting_factor());
  v.number(r.window_fill, m.window_fill());
  v.text(r.estimator, m.estimator());
  v.flag(r.converged, m.converged());
  v.count(r.samples_accepted, m.samples_accepted());
  v.count(r.samples_rejected, m.samples_rejected());
  v.number(r.gnss_latency_s, m.gnss_latency_s());
  v.unknown(r.gnss_latency_sigma_s, m.gnss_latency_sigma_s());
  v.number(r.turn_slip_s_per_rad, m.turn_slip_s_per_rad());
  v.unknown(r.turn_slip_sigma_s_per_rad, m.turn_slip_sigma_s_per_rad());
  v.flag(r.turn_slip_applies, m.turn_slip_applies());
}

// The position both dead-reckoning topics carry: WGS-84 and the local ENU of the DR origin.
template <class Row, class Msg, class V>
void position_fields(Row& r, Msg& m, V& v) {
  v.stamp(r.t_s, m.header(), "wgs84");
  v.degrees(r.lat_rad, m.latitude_deg());
  v.degrees(r.lon_rad, m.longitude_deg());
  v.number(r.height_m, m.height_m());
  v.number(r.east_m, m.enu_east_m());
  v.number(r.north_m, m.enu_north_m());
  v.number(r.up_m, m.enu_up_m());
}

template <class Row, class Msg, class V>
void dead_reckoning_fields(Row& r, Msg& m, V&& v) {
  position_fields(r, m, v);
  v.number(r.heading_rad, m.heading_rad());
  v.number(r.distance_m, m.distance_m());
  v.number(r.k_m_per_pulse, m.k_m_per_pulse());
  v.choice(r.k_source, m.k_source(), kKSources);
  v.unknown(r.horizontal_error_m, m.horizontal_error_m());
  v.unknown(r.error_percent, m.error_percent_distance());
  v.unknown(r.error_t_s, m.error_t_s());
}

template <class Row, class Msg, class V>
void navigation_position_fields(Row& r, Msg& m, V&& v) {
  position_fields(r, m, v);
  v.unknown(r.var_east_m2, m.position_covariance_east_m2());
  v.unknown(r.var_north_m2, m.position_covariance_north_m2());
  v.unknown(r.var_up_m2, m.position_covariance_up_m2());
  v.choice(r.status, m.status(), kNavigationStatuses);
  v.unknown(r.last_fix_t_s, m.last_fix_stamp_s());
  v.unknown(r.distance_since_fix_m, m.distance_since_fix_m());
}

// Row -> message.
struct ToMessage {
  void stamp(double t_s, std_msgs::msg::Header& h, const char* frame_id) const { h = make_header(t_s, frame_id); }
  void number(double r, double& m) const { m = r; }
  void degrees(double rad, double& deg) const { deg = rad_to_deg(rad); }
  void unknown(double r, double& m) const { m = std::isfinite(r) ? r : -1.0; }
  void unknown(const std::optional<double>& r, double& m) const { m = r && std::isfinite(*r) && *r >= 0.0 ? *r : -1.0; }
  void value_or_zero(const std::optional<double>& r, double& m) const { m = r ? *r : 0.0; }
  void flag(bool r, bool& m) const { m = r; }
  void text(const std::string& r, std::string& m) const { m = r; }
  void count(uint64_t r, uint32_t& m) const {
    m = static_cast<uint32_t>(std::min<uint64_t>(r, std::numeric_limits<uint32_t>::max()));
  }
  template <class E, std::size_t N>
  void choice(const std::string& r, E& m, const std::pair<E, const char*> (&names)[N]) const {
    for (const auto& [value, name] : names)
      if (r == name) {
        m = value;
        return;
      }
    throw std::invalid_argument("output_messages: '" + r + "' is no value of the topic's enumeration");
  }
};

// Message -> row.
struct FromMessage {
  static double known_or_nan(double v) {
    return std::isfinite(v) && v >= 0.0 ? v : std::numeric_limits<double>::quiet_NaN();
  }
  void stamp(double& t_s, const std_msgs::msg::Header& h, const char*) const { t_s = to_seconds(h.stamp()); }
  void number(double& r, double m) const { r = m; }
  void degrees(double& rad, double deg) const { rad = exact_radians_of(deg); }
  void unknown(double& r, double m) const { r = known_or_nan(m); }
  void unknown(std::optional<double>& r, double m) const {
    r = std::isfinite(m) && m >= 0.0 ? std::optional<double>(m) : std::nullopt;
  }
  void value_or_zero(std::optional<double>& r, double m) const {
    r = std::isfinite(m) && m > 0.0 ? std::optional<double>(m) : std::nullopt;
  }
  void flag(bool& r, bool m) const { r = m; }
  void text(std::string& r, const std::string& m) const { r = m; }
  void count(uint64_t& r, uint32_t m) const { r = m; }
  template <class E, std::size_t N>
  void choice(std::string& r, E m, const std::pair<E, const char*> (&names)[N]) const {
    r = names[0].second;
    for (const auto& [value, name] : names)
      if (m == value) r = name;
  }
};

}  // namespace

odonav::msg::Misalignment message_of(const results::MisalignmentRow& row) {
  odonav::msg::Misalignment m;
  misalignment_fields(row, m, ToMessage{});
  return m;
}

odonav::msg::ScaleFactor message_of(const results::ScaleFactorRow& row) {
  odonav::msg::ScaleFactor m;
  scale_factor_fields(row, m, ToMessage{});
  return m;
}

odonav::msg::DeadReckoning message_of(const results::DeadReckoningRow& row) {
  odonav::msg::DeadReckoning m;
  dead_reckoning_fields(row, m, ToMessage{});
  return m;
}

odonav::msg::NavigationPosition message_of(const results::NavigationPositionRow& row) {
  odonav::msg::NavigationPosition m;
  navigation_position_fields(row, m, ToMessage{});
  return m;
}

results::MisalignmentRow row_of(const odonav::msg::Misalignment& message) {
  results::MisalignmentRow r;
  misalignment_fields(r, message, FromMessage{});
  return r;
}

results::ScaleFactorRow row_of(const odonav::msg::ScaleFactor& message) {
  results::ScaleFactorRow r;
  scale_factor_fields(r, message, FromMessage{});
  r.k_by_estimator.emplace_back(r.estimator, r.k_m_per_pulse);
  if (r.estimator == "vff_lm_rls" && r.k_m_per_pulse) r.lambda_vff_lm_rls = r.forgetting_factor;
  return r;
}

results::DeadReckoningRow row_of(const odonav::msg::DeadReckoning& message) {
  results::DeadReckoningRow r;
  dead_reckoning_fields(r, message, FromMessage{});
  return r;
}

results::NavigationPositionRow row_of(const odonav::msg::NavigationPosition& message) {
  results::NavigationPositionRow r;
  navigation_position_fields(r, message, FromMessage{});
  return r;
}

}  // namespace odonav::dds
