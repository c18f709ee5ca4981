#include "odonav/ground/standard_channels.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

#include "odonav/ground/cdr_writer.hpp"
#include "odonav/ground/ros2msg_schema.hpp"
#include "odonav/frames.hpp"
#include "odonav/printf_text.hpp"

namespace odonav::ground {

namespace {

void header(CdrWriter& w, double stamp_s, const std::string& frame_id) {
  // builtin_interfaces/Time: int32 sec, uint32 nanosec (nanosec in [0, 1e9)). A stamp outside the
  // int32 range or not finite is written as 0 rather than wrapped.
  std::int32_t sec = 0;
  std::uint32_t nsec = 0;
  if (std::isfinite(stamp_s) && stamp_s >= -2147483648.0 && stamp_s < 2147483647.0) {
    const double whole = std::floor(stamp_s);
    long long ns = std::llround((stamp_s - whole) * 1e9);
    long long s = static_cast<long long>(whole);
    if (ns >= 1000000000LL) {
      ns -= 1000000000LL;
      ++s;
    }
    sec = static_cast<std::int32_t>(s);
    nsec = static_cast<std::uint32_t>(ns);
  }
  w.i32(sec);
  w.u32(nsec);
  w.str(frame_id);
}

std::string number(double v) { return printf_text("%.9g", v); }

}  // namespace

std::string vehicle_topic(const std::string& vehicle_id, const std::string& topic_short_name) {
  return "/odonav/" + vehicle_id + "/" + topic_short_name;
}

std::string derived_topic(const std::string& vehicle_id, DerivedChannel channel) {
  switch (channel) {
    case DerivedChannel::kNavSatNavigation: return vehicle_topic(vehicle_id, "navsat/navigation");
    case DerivedChannel::kNavSatDeadReckoning: return vehicle_topic(vehicle_id, "navsat/dead_reckoning");
    case DerivedChannel::kNavSatGnss: return vehicle_topic(vehicle_id, "navsat/gnss");
    case DerivedChannel::kDiagnostics: return vehicle_topic(vehicle_id, "diagnostics");
    case DerivedChannel::kScaleFactorPlot: return vehicle_topic(vehicle_id, "k");
  }
  throw std::invalid_argument("derived_topic: unknown channel");
}

std::string derived_schema_name(DerivedChannel channel) {
  switch (channel) {
    case DerivedChannel::kDiagnostics: return kDiagnosticArrayType;
    case DerivedChannel::kScaleFactorPlot: return "odonav_ground/ScaleFactorPlot";
    default: return kNavSatFixType;
  }
}

std::string derived_encoding(DerivedChannel channel) {
  return channel == DerivedChannel::kScaleFactorPlot ? "json" : "cdr";
}

std::string derived_schema_encoding(DerivedChannel channel) {
  return channel == DerivedChannel::kScaleFactorPlot ? "jsonschema" : "ros2msg";
}

std::string derived_schema(DerivedChannel channel) {
  if (channel == DerivedChannel::kScaleFactorPlot) {
    const nlohmann::json number_or_null = {{"type", {"number", "null"}}};
    const nlohmann::json schema = {
        {"title", "odonav_ground/ScaleFactorPlot"},
        {"description", "Odometer scale factor K [m/pulse] with its one-sigma band (null: unknown)"},
        {"type", "object"},
        {"properties",
         {{"stamp_s", {{"type", "number"}}},
          {"vehicle_id", {{"type", "string"}}},
          {"k_m_per_pulse", {{"type", "number"}}},
          {"sigma_m_per_pulse", number_or_null},
          {"k_minus_sigma", number_or_null},
          {"k_plus_sigma", number_or_null},
          {"estimator", {{"type", "string"}}},
          {"converged", {{"type", "boolean"}}},
          {"frozen", {{"type", "boolean"}}},
          {"source", {{"type", "string"}}}}}};
    return schema.dump();
  }
  return ros2msg_schema(embedded_msg_library(), derived_schema_name(channel));
}

NavSatFixMsg navsat_from_dead_reckoning(const DeadReckoningView& dr) {
  NavSatFixMsg m;
  m.stamp_s = dr.row.t_s;
  m.frame_id = "wgs84";
  m.status = 0;
  m.service = 0;
  m.latitude_deg = rad_to_deg(dr.row.lat_rad);
  m.longitude_deg = rad_to_deg(dr.row.lon_rad);
  m.altitude_m = dr.row.height_m;
  m.position_covariance_type = 0;
  return m;
}

NavSatFixMsg navsat_from_navigation(const NavigationPositionView& nav) {
  const results::NavigationPositionRow& n = nav.row;
  NavSatFixMsg m;
  m.stamp_s = n.t_s;
  m.frame_id = "wgs84";
  m.status = n.status == "not_started" ? -1 : 0;
  m.service = n.status == "anchored" ? 1 : 0;
  m.latitude_deg = rad_to_deg(n.lat_rad);
  m.longitude_deg = rad_to_deg(n.lon_rad);
  m.altitude_m = n.height_m;
  if (std::isfinite(n.var_east_m2) && std::isfinite(n.var_north_m2) && std::isfinite(n.var_up_m2)) {
    m.position_covariance_m2 = {n.var_east_m2, 0, 0, 0, n.var_north_m2, 0, 0, 0, n.var_up_m2};
    m.position_covariance_type = 2;
  }
  return m;
}

NavSatFixMsg navsat_from_gnss(const GnssView& g) {
  NavSatFixMsg m;
  m.stamp_s = g.stamp_s;
  m.frame_id = "wgs84";
  switch (g.fix_quality) {
    case 1: m.status = 0; break;
    case 2: m.status = 1; break;
    case 4:
    case 5: m.status = 2; break;
    default: m.status = -1; break;
  }
  if (!g.valid) m.status = -1;
  m.service = 1;
  m.latitude_deg = g.latitude_deg;
  m.longitude_deg = g.longitude_deg;
  m.altitude_m = g.height_m;
  if (std::isfinite(g.position_std_m) && g.position_std_m > 0.0) {
    const double var = g.position_std_m * g.position_std_m;
    m.position_covariance_m2 = {var, 0, 0, 0, var, 0, 0, 0, var};
    m.position_covariance_type = 1;
  }
  return m;
}

DiagnosticArrayMsg diagnostics_from(const VehicleSnapshot& v) {
  DiagnosticArrayMsg a;
  a.frame_id = "";
  double newest = 0.0;
  for (const ComponentSnapshot& c : v.components) {
    const HealthView& h = c.health;
    if (std::isfinite(h.stamp_s) && h.stamp_s > newest) newest = h.stamp_s;
    DiagnosticStatusMsg s;
    s.name = v.vehicle_id + "/" + h.component;
    s.hardware_id = v.vehicle_id;
    s.level = c.stale ? 3 : static_cast<std::uint8_t>(h.level <= 3 ? h.level : 2);
    s.message = c.stale ? "STALE: no Health for " + number(std::round(c.age_s * 10.0) / 10.0) + " s; last: " + h.reason
                        : h.reason;
    s.values.emplace_back("state", health_state_name(h.state));
    s.values.emplace_back("level", health_level_name(h.level));
    s.values.emplace_back("stale", c.stale ? "true" : "false");
    s.values.emplace_back("age_s", number(c.age_s));
    s.values.emplace_back("last_command_id", std::to_string(h.last_command_id));
    s.values.emplace_back("last_command_result", command_result_name(h.last_command_result));
    s.values.emplace_back("last_command_detail", h.last_command_detail);
    for (const auto& [name, value] : h.counters) s.values.emplace_back(name, number(value));
    a.status.push_back(std::move(s));
  }
  a.stamp_s = newest;
  return a;
}

nlohmann::json scale_factor_plot(const ScaleFactorView& view) {
  const results::ScaleFactorRow& k = view.row;
  const double k_m_per_pulse = k.k_m_per_pulse.value_or(0.0);  // 0 on the topic while there is none
  const auto sigma = k.sigma_m_per_pulse;
  return {{"stamp_s", k.t_s},
          {"vehicle_id", view.vehicle_id},
          {"k_m_per_pulse", k_m_per_pulse},
          {"sigma_m_per_pulse", sigma ? nlohmann::json(*sigma) : nlohmann::json()},
          {"k_minus_sigma", sigma ? nlohmann::json(k_m_per_pulse - *sigma) : nlohmann::json()},
          {"k_plus_sigma", sigma ? nlohmann::json(k_m_per_pulse + *sigma) : nlohmann::json()},
          {"estimator", k.estimator},
          {"converged", k.converged},
          {"frozen", view.frozen},
          {"source", view.source}};
}

std::vector<std::uint8_t> encode_cdr(const NavSatFixMsg& m) {
  CdrWriter w;
  header(w, m.stamp_s, m.frame_id);
  w.i8(m.status);
  w.u16(m.service);
  w.f64(m.latitude_deg);
  w.f64(m.longitude_deg);
  w.f64(m.altitude_m);
  for (double c : m.position_covariance_m2) w.f64(c);
  w.u8(m.position_covariance_type);
  return w.take();
}

std::vector<std::uint8_t> encode_cdr(const DiagnosticArrayMsg& m) {
  CdrWriter w;
  header(w, m.stamp_s, m.frame_id);
  w.sequence_length(m.status.size());
  for (const DiagnosticStatusMsg& s : m.status) {
    w.u8(s.level);
    w.str(s.name);
    w.str(s.message);
    w.str(s.hardware_id);
    w.sequence_length(s.values.size());
    for (const auto& [key, value] : s.values) {
      w.str(key);
      w.str(value);
    }
  }
  return w.take();
}

}  // namespace odonav::ground
