#pragma once
// The standard ROS 2 channels the ground station derives from the odonav topics, for tools that
// understand them without configuration (Foxglove's Map and Diagnostics panels, PlotJuggler), the
// same in `odonav-ground serve` (live) and `odonav-ground record` (MCAP):
//
//   /odonav/<vehicle>/navsat/navigation      sensor_msgs/msg/NavSatFix   GNSS-anchored position (NavigationPosition)
//   /odonav/<vehicle>/navsat/dead_reckoning  sensor_msgs/msg/NavSatFix   pure dead reckoning (DeadReckoning)
//   /odonav/<vehicle>/navsat/gnss            sensor_msgs/msg/NavSatFix   the GNSS receiver's fix (GnssFix)
//   /odonav/<vehicle>/diagnostics            diagnostic_msgs/msg/DiagnosticArray   one status per component
//   /odonav/<vehicle>/k                      JSON (jsonschema)          K with its one-sigma band, plottable
//
// The navigation position is the one to steer by (kept on GNSS while valid, dead reckoning from the
// last fix through outages), under the name map tools look for; navsat/dead_reckoning is the pure DR.
// No DDS here: views (fleet_state.hpp) in, CDR bytes out.
#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "odonav/ground/fleet_state.hpp"

namespace odonav::ground {

/// sensor_msgs/msg/NavSatFix (ROS 2), fields as in the .msg.
struct NavSatFixMsg {
  double stamp_s = 0.0;  ///< header.stamp, the source sample's stamp (s)
  std::string frame_id;
  std::int8_t status = -1;    ///< NavSatStatus.STATUS_* (-1 no fix, 0 fix, 1 SBAS, 2 GBAS)
  std::uint16_t service = 0;  ///< NavSatStatus.SERVICE_* bits (0: not known)
  double latitude_deg = 0.0, longitude_deg = 0.0, altitude_m = 0.0;
  std::array<double, 9> position_covariance_m2{};  ///< ENU, row major
  std::uint8_t position_covariance_type = 0;       ///< 0 unknown .. 3 known
};

/// diagnostic_msgs/msg/DiagnosticStatus.
struct DiagnosticStatusMsg {
  std::uint8_t level = 0;  ///< OK 0, WARN 1, ERROR 2, STALE 3
  std::string name, message, hardware_id;
  std::vector<std::pair<std::string, std::string>> values;
};

/// diagnostic_msgs/msg/DiagnosticArray.
struct DiagnosticArrayMsg {
  double stamp_s = 0.0;
  std::string frame_id;
  std::vector<DiagnosticStatusMsg> status;
};

inline constexpr const char* kNavSatFixType = "sensor_msgs/msg/NavSatFix";
inline constexpr const char* kDiagnosticArrayType = "diagnostic_msgs/msg/DiagnosticArray";

/// The derived channels of one vehicle.
enum class DerivedChannel { kNavSatNavigation, kNavSatDeadReckoning, kNavSatGnss, kDiagnostics, kScaleFactorPlot };
inline constexpr std::array<DerivedChannel, 5> kAllDerivedChannels{
    DerivedChannel::kNavSatNavigation, DerivedChannel::kNavSatDeadReckoning, DerivedChannel::kNavSatGnss,
    DerivedChannel::kDiagnostics, DerivedChannel::kScaleFactorPlot};

/// "/odonav/<vehicle>/navsat/gnss" etc. (table above).
std::string derived_topic(const std::string& vehicle_id, DerivedChannel channel);
/// The vehicle's channel of an odonav topic: "/odonav/<vehicle>/<short name>" ("/odonav/v1/gnss/fix").
std::string vehicle_topic(const std::string& vehicle_id, const std::string& topic_short_name);
/// Schema name: the ROS type ("sensor_msgs/msg/NavSatFix"), or "odonav_ground/ScaleFactorPlot".
std::string derived_schema_name(DerivedChannel channel);
/// Message encoding: "cdr", or "json" for the K plot.
std::string derived_encoding(DerivedChannel channel);
/// Schema encoding: "ros2msg", or "jsonschema" for the K plot.
std::string derived_schema_encoding(DerivedChannel channel);
/// The schema text: the complete ros2msg (with dependencies, from the embedded library) or the
/// JSON schema.
std::string derived_schema(DerivedChannel channel);

/// The pure dead-reckoning position as a NavSatFix: status FIX (a position exists; it comes from no
/// satellite, service 0), covariance unknown (DR reports an error only against GNSS), frame "wgs84".
NavSatFixMsg navsat_from_dead_reckoning(const DeadReckoningView& dr);
/// The GNSS-anchored navigation position as a NavSatFix (the "navigation" channel): status FIX while
/// anchored or bridging by dead reckoning (service 0 when bridging, GPS when anchored), NO_FIX before
/// the first fix; covariance diagonal ENU (type DIAGONAL_KNOWN) when known, else unknown.
NavSatFixMsg navsat_from_navigation(const NavigationPositionView& nav);
/// The GNSS fix as a NavSatFix: status from the fix quality (invalid: NO_FIX; single: FIX;
/// DGPS: SBAS; RTK fixed/float: GBAS; dead-reckoning fixes: NO_FIX) and `valid`; covariance
/// diagonal (position_std_m squared east, north and up, type APPROXIMATED: the receiver gives one
/// horizontal sigma) when the sigma is known, else unknown; service GPS.
NavSatFixMsg navsat_from_gnss(const GnssView& gnss);
/// One status per component of the snapshot: name "<vehicle>/<component>" (the Diagnostics panel
/// groups by it), hardware_id the vehicle id, level the Health level or STALE (3) when the
/// component is stale, message its reason (stale: "STALE: no Health for N s; last: <reason>"),
/// values: state, level, age_s, stale, last command (id, result, detail) and every counter.
/// stamp: the newest Health stamp of the vehicle (UNIX seconds, as components stamp Health).
DiagnosticArrayMsg diagnostics_from(const VehicleSnapshot& vehicle);
/// The K plot message: {"stamp_s", "vehicle_id", "k_m_per_pulse", "sigma_m_per_pulse",
/// "k_minus_sigma", "k_plus_sigma" (null when sigma is unknown), "estimator", "converged",
/// "frozen", "source"}.
nlohmann::json scale_factor_plot(const ScaleFactorView& k);

/// CDR bytes (encapsulation header included) of the messages above.
std::vector<std::uint8_t> encode_cdr(const NavSatFixMsg& m);
std::vector<std::uint8_t> encode_cdr(const DiagnosticArrayMsg& m);

}  // namespace odonav::ground
