#pragma once
// odonav-gateway's middleware-free core, part 5: GNSS from gpsd (README.md, "GNSS from gpsd").
//
//   gpsd:<host>:<port>    a gpsd daemon, read through libgps (WATCH_ENABLE | WATCH_JSON);
//                         host must be a loopback address unless explicitly allowed
//
// Each gpsd TPV report becomes one GnssSample; GST reports give the accuracies of the fix with the
// same time. The conversion (gnss_sample_from) and the time gate (GnssTimeGate) are pure, so they
// are tested without a daemon; run_gpsd_input is the libgps loop.
//
// Time base: gpsd reports UTC (seconds since 1970-01-01T00:00:00Z, leap seconds ignored, as NMEA and
// POSIX do). The sample's t is that UTC minus a configured origin (--gnss-utc-origin-s, 0 by
// default: t is UTC seconds), so odometer and INS lines must be stamped on the same UTC base.
// Event time must increase: a fix whose t is not greater than the last published fix is dropped and
// counted (time_backwards when earlier, repeated when equal: gpsd may report one epoch twice).
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <mutex>
#include <optional>
#include <string>

#include "odonav/gateway/live_input.hpp"
#include "odonav/dataset.hpp"

namespace odonav::gateway {

/// What a `gpsd:` source names.
struct GpsdSourceSpec {
  std::string host = "127.0.0.1";  ///< host name or address of the daemon.
  std::uint16_t port = 2947;       ///< TCP port, 1..65535 (gpsd's default is 2947).
};

/// True for "gpsd:...".
bool is_gpsd_source(const std::string& text);

/// Parses "gpsd:<port>", "gpsd:<host>:<port>" or "gpsd:" (127.0.0.1:2947). Throws ConfigError naming
/// `flag` and the accepted forms on a bad port, and naming --allow-non-loopback when the host is not
/// "localhost", "::1" or an IPv4 address in 127.0.0.0/8 and allow_non_loopback is false.
GpsdSourceSpec parse_gpsd_source(const std::string& text, bool allow_non_loopback,
                                 const std::string& flag = "--source");

/// "gpsd:127.0.0.1:2947".
std::string to_string(const GpsdSourceSpec& spec);

/// The fields of one gpsd TPV report that the gateway uses, NaN when gpsd did not report them
/// (the libgps convention). Plain numbers so the conversion is testable without gpsd.
struct GpsdReport {
  static constexpr double kUnknown = std::numeric_limits<double>::quiet_NaN();
  double time_utc_s = kUnknown;   ///< UTC of the fix, s since 1970 (fix.time).
  int mode = 0;                   ///< 0 not seen, 1 no fix, 2 2D, 3 3D (gpsd MODE_*).
  int status = 0;                 ///< gpsd STATUS_*: 0 unknown (JSON leaves it out for a plain fix), 1 GPS,
                                  ///< 2 DGPS, 3 RTK fixed, 4 RTK float, 5 DR, 6 GNSS+DR.
  double lat_deg = kUnknown;      ///< WGS-84 latitude, deg, [-90, 90].
  double lon_deg = kUnknown;      ///< WGS-84 longitude, deg, [-180, 180].
  double alt_hae_m = kUnknown;    ///< height above the WGS-84 ellipsoid, m.
  double alt_msl_m = kUnknown;    ///< height above mean sea level, m.
  double geoid_sep_m = kUnknown;  ///< geoid separation (ellipsoid height - MSL height), m.
  double speed_mps = kUnknown;    ///< horizontal speed over ground, m/s, >= 0.
  double track_deg = kUnknown;    ///< course over ground, deg clockwise from true north, [0, 360).
  double climb_mps = kUnknown;    ///< vertical speed, m/s, up positive.
  double ecef_vx_mps = kUnknown, ecef_vy_mps = kUnknown, ecef_vz_mps = kUnknown;  ///< ECEF velocity, m/s.
  double eph_m = kUnknown;          ///< gpsd's horizontal position error estimate, m (about 95 %).
  double eps_mps = kUnknown;        ///< gpsd's speed error estimate, m/s (about 95 %).
  double gst_lat_std_m = kUnknown;  ///< GST one-sigma latitude error of the same epoch, m.
  double gst_lon_std_m = kUnknown;  ///< GST one-sigma longitude error of the same epoch, m.
};

/// Speed below which a missing course is taken as "standing": receivers stop reporting course
/// over ground at low speed (u-blox below about 0.5 m/s), m/s.
inline constexpr double kCourseMissingStandingSpeedMps = 1.0;

/// The GnssSample of a TPV report, stamped t_s = time_utc_s - utc_origin_s. Never throws.
///  - No time: std::nullopt (no stamp, nothing to publish; the caller counts it).
///  - Mode < 2 (or no latitude/longitude): fix 0 (published invalid), position and velocity NaN,
///    never zeros.
///  - Fix quality (GGA convention of docs/DATASET.md) from status: 2 DGPS, 4 RTK fixed, 5 RTK float,
///    6 dead reckoning (not a reference); unknown, GPS, GNSS+DR and others count as 1.
///  - Height: altHAE, else altMSL + geoid separation; a 2D fix (or no height) leaves it NaN, so the
///    message is published invalid (the product needs a 3D reference).
///  - Velocity ENU: the ECEF velocity rotated at the fix's position when all three are given, else
///    (speed sin track, speed cos track, climb); climb unknown -> 0 (not given by NMEA receivers).
///    Course unknown with speed below kCourseMissingStandingSpeedMps: horizontal velocity 0 with
///    vel_std_mps at least that speed; faster without course: NaN (published invalid).
///  - Accuracies: pos_std_m = hypot(GST lat, lon sigma) when given, else eph / 2 (gpsd's estimate
///    is about two sigma); vel_std_mps = eps / 2. Absent when gpsd reports none.
std::optional<GnssSample> gnss_sample_from(const GpsdReport& report, double utc_origin_s);

/// Enforces increasing event time on the GNSS stream.
class GnssTimeGate {
 public:
  enum class Verdict { kAccept, kBackwards, kRepeated };
  /// kAccept (and remembers t_s) when t_s is greater than the last accepted t; kRepeated when equal;
  /// kBackwards when smaller.
  Verdict admit(double t_s);

 private:
  std::optional<double> last_t_s_;
};

/// Counters of the gpsd source (health).
struct GpsdCounters {
  std::uint64_t reports = 0;              ///< TPV reports read.
  std::uint64_t no_time = 0;              ///< TPV without a time (dropped).
  std::uint64_t time_backwards = 0;       ///< TPV earlier than the last published fix (dropped).
  std::uint64_t repeated = 0;             ///< TPV at the time of the last published fix (dropped).
  std::uint64_t no_fix = 0;               ///< published with fix 0 (mode < 2 or status 0).
  std::uint64_t connection_failures = 0;  ///< failed connects and lost connections.
  bool connected = false;
  std::string last_failure;  ///< "gpsd:127.0.0.1:2947: ..." of the last failure, empty if none.
};

/// Back-off before reconnecting after the n-th consecutive failure (n >= 1): 1, 2, 4, 8, 16, 30, 30... s.
double gpsd_reconnect_backoff_s(int consecutive_failures);

/// Reads gpsd until stop() is true: connects (gps_open, gps_stream WATCH_ENABLE|WATCH_JSON), turns
/// every TPV into a sample (gnss_sample_from, then the time gate) and hands it to `publish_gnss`.
/// A failed connect or a lost connection is counted (counters.last_failure says why, WARN in the
/// log) and retried after gpsd_reconnect_backoff_s. periodic() is called at least every 100 ms.
/// `counters` is only touched with `counters_mutex` held (the health publisher may run on another
/// thread); publish_gnss and periodic are called without it.
void run_gpsd_input(const GpsdSourceSpec& spec, double utc_origin_s,
                    const std::function<void(const GnssSample&)>& publish_gnss, const std::function<bool()>& stop,
                    const std::function<void()>& periodic, GpsdCounters& counters, std::mutex& counters_mutex);

}  // namespace odonav::gateway
