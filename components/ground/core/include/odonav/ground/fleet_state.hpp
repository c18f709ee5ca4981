#pragma once
// What the ground station knows about its fleet, without DDS: the latest message of every topic per
// vehicle (and per component for Health), arrival rates, and which producers went silent.
// odonav-ground's DDS node converts each received message into the plain views below and feeds them
// here from the listener threads; the monitor takes snapshots (thread-safe) to print them.
//
// Time: `now_s` everywhere is the ground station's steady clock in seconds (any origin), used for
// ages, rates and staleness only. Message stamps are kept as sent (dataset time base, seconds).
// Units and frames are those of the topics (idl/README.md): SI, radians, ENU.
#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "odonav/gap_detector.hpp"
#include "odonav/results/output_files.hpp"

namespace odonav::ground {

/// The vehicle topics the monitor follows, in the order of idl/README.md.
enum class Stream { kOdometer, kInsAttitude, kGnssFix, kMisalignment, kScaleFactor, kDeadReckoning, kHealth };
inline constexpr int kStreamCount = 7;
/// Short name of a stream ("odometer", "ins", "gnss", "misalignment", "scale_factor", "dead_reckoning", "health").
const char* stream_name(Stream s);

struct HealthView {
  std::string vehicle_id, component;
  double stamp_s = 0.0;
  std::uint32_t state = 0;  ///< Health.STATE_* (0 starting .. 4 stopping)
  std::uint32_t level = 0;  ///< Health.LEVEL_* (0 OK, 1 WARN, 2 ERROR, 3 STALE)
  std::string reason;
  std::vector<std::pair<std::string, double>> counters;
  std::uint32_t last_command_id = 0;
  std::uint32_t last_command_result = 0;  ///< 0 none, 1 accepted, 2 rejected
  std::string last_command_detail;
};

// The estimate views hold the estimate as the row its output file has (odonav/results/
// output_files.hpp: radians, SI, unknown = NaN or nullopt), made from the message by the one field
// table of odonav/dds/output_messages.hpp, plus what only the topic carries. So a field added to a
// topic and its table reaches the ground's JSON and page without a line here.

struct ScaleFactorView {
  std::string vehicle_id;
  results::ScaleFactorRow row;  ///< t_s the message stamp (NaN when a peer's stamp is invalid)
  bool frozen = false;
  std::string source;  ///< the publishing identification instance ("identification", "identification/standby")
};

struct MisalignmentView {
  std::string vehicle_id;
  results::MisalignmentRow row;  ///< state "waiting" | "calibrating" | "converged" | "frozen"
};

struct DeadReckoningView {
  std::string vehicle_id;
  results::DeadReckoningRow row;  ///< east/north/up_m in the local ENU of the DR origin; lon in [-pi, pi)
  double origin_latitude_deg = 0.0, origin_longitude_deg = 0.0, origin_height_m = 0.0;  ///< WGS-84
  bool gnss_valid = false;
};

/// The GNSS-anchored navigation position (NavigationPosition).
struct NavigationPositionView {
  std::string vehicle_id;
  results::NavigationPositionRow row;  ///< status "not_started" | "anchored" | "dead_reckoning"
};

struct GnssView {
  std::string vehicle_id;
  double stamp_s = 0.0;
  bool valid = false;
  std::uint8_t fix_quality = 0;                                    ///< NMEA GGA quality
  double speed_mps = 0.0;                                          ///< horizontal speed from the ENU velocity
  double latitude_deg = 0.0, longitude_deg = 0.0, height_m = 0.0;  ///< WGS-84, ellipsoidal [m]
  double position_std_m = -1.0;                                    ///< one-sigma horizontal [m]; -1: unknown
};

/// Names for the numeric enumerations of the topics.
std::string health_state_name(std::uint32_t state);     ///< "STARTING" .. "STOPPING", else "STATE<n>"
std::string health_level_name(std::uint32_t level);     ///< "OK", "WARN", "ERROR", "STALE", else "LEVEL<n>"
std::string command_result_name(std::uint32_t result);  ///< "none", "accepted", "rejected"
std::string fix_quality_name(std::uint8_t quality);     ///< "invalid", "single", "dgps", "rtk-fixed", ...

/// When an item counts as STALE: silent by the reader's deadline (edge reported through
/// on_silence), or not heard of for longer than stale_after_s of its stream. The defaults are 1.5
/// deadline periods for the topics with a deadline (health 3 s, estimates 1 s), so STALE shows
/// within 2 periods even if a deadline event were missed, and 1 s for the 10-100 Hz streams the
/// ground reads best effort without a deadline.
struct FleetStateConfig {
  double rate_window_s = 2.0;  ///< arrival rates are counted over this sliding window (s, > 0)
  double stale_after_s[kStreamCount] = {1.0, 1.0, 1.0, 1.5, 1.5, 1.0, 4.5};
};

/// One component of a vehicle in a snapshot.
struct ComponentSnapshot {
  HealthView health;
  double age_s = 0.0;  ///< since its last Health arrived
  bool stale = false;
};

template <class View>
struct ItemSnapshot {
  View view;
  double age_s = 0.0;
  bool stale = false;
};

struct VehicleSnapshot {
  std::string vehicle_id;
  std::vector<ComponentSnapshot> components;  ///< sorted by component name
  std::optional<ItemSnapshot<ScaleFactorView>> scale_factor;
  std::optional<ItemSnapshot<MisalignmentView>> misalignment;
  std::optional<ItemSnapshot<DeadReckoningView>> dead_reckoning;
  std::optional<ItemSnapshot<NavigationPositionView>> navigation;  ///< stale as dead_reckoning
  std::optional<ItemSnapshot<GnssView>> gnss;
  double rate_hz[kStreamCount] = {0, 0, 0, 0, 0, 0, 0};  ///< arrivals per second over the rate window
  bool stale = false;                                    ///< some producer of this vehicle is stale
  /// Holes in the dead-reckoning outputs this ground station received, from their stamps (event
  /// time; odonav/gap_detector.hpp, period learned, 100 Hz): outputs missed in all gaps, the number
  /// of gaps, and the last one. They are what did not reach the ground: a fault on the vehicle
  /// (stalled or restarted dead reckoning) or losses on the best-effort link. The K stream is not
  /// checked: in a GNSS outage it repeats its last stamp and then resumes, with no outputs missing.
  std::uint64_t dead_reckoning_missed = 0;
  std::uint64_t dead_reckoning_gaps = 0;
  std::optional<OutputGap> dead_reckoning_last_gap;
};

struct FleetSnapshot {
  double now_s = 0.0;
  std::vector<VehicleSnapshot> vehicles;  ///< sorted by vehicle id
};

/// The fleet, fed from any thread (one internal mutex).
class FleetState {
 public:
  explicit FleetState(FleetStateConfig config = FleetStateConfig());

  void on_health(const HealthView& h, double now_s);
  void on_scale_factor(const ScaleFactorView& v, double now_s);
  void on_misalignment(const MisalignmentView& v, double now_s);
  void on_dead_reckoning(const DeadReckoningView& v, double now_s);
  void on_gnss(const GnssView& v, double now_s);
  /// The GNSS-anchored position (same producer and rate as dead reckoning: no rate of its own).
  void on_navigation(const NavigationPositionView& v, double now_s);
  /// An arrival of a stream that keeps no content here (odometer, INS): counted for its rate.
  void on_arrival(const std::string& vehicle_id, Stream stream, double now_s);
  /// The reader's deadline edge: `silent` true when the instance (vehicle, and component for
  /// Health; empty otherwise) went silent, false when its data returned.
  void on_silence(const std::string& vehicle_id, Stream stream, const std::string& component, bool silent);

  /// Everything known now; `vehicles` restricts it to those ids when not empty.
  FleetSnapshot snapshot(double now_s, const std::vector<std::string>& vehicles = {}) const;

 private:
  struct Timed {
    double last_arrival_s = 0.0;
    bool silent = false;
  };
  struct Vehicle {
    std::map<std::string, std::pair<HealthView, Timed>> components;
    std::optional<std::pair<ScaleFactorView, Timed>> scale_factor;
    std::optional<std::pair<MisalignmentView, Timed>> misalignment;
    std::optional<std::pair<DeadReckoningView, Timed>> dead_reckoning;
    std::optional<std::pair<NavigationPositionView, Timed>> navigation;
    std::optional<std::pair<GnssView, Timed>> gnss;
    std::deque<double> arrivals[kStreamCount];
    GapDetector dead_reckoning_gaps;  ///< period learned from the stamps
  };
  Vehicle& vehicle(const std::string& id);
  void count(Vehicle& v, Stream s, double now_s);
  /// Keeps view as the latest of its stream (the member slot of its vehicle), arrived at now_s (s,
  /// steady clock); returns the vehicle. The caller holds mutex_.
  template <class View>
  Vehicle& keep_latest(std::optional<std::pair<View, Timed>> Vehicle::*slot, const View& view, double now_s);
  bool is_stale(const Timed& t, Stream s, double now_s) const;

  FleetStateConfig config_;
  mutable std::mutex mutex_;
  std::map<std::string, Vehicle> vehicles_;
};

/// The snapshot as JSON (for --once --json): {"vehicles": [{"vehicle_id", "stale", "components":
/// [{"component", "state", "level", "reason", "stale", "age_s", "stamp_s", "last_command": {...},
/// "counters": {...}}], "scale_factor", "misalignment", "dead_reckoning", "navigation": each the row
/// of its output file with the file's column names and units (results::row_json: "t", degrees,
/// unknown = null) plus "age_s", "stale" and what only the topic carries ("frozen", "source";
/// "origin_lat_deg", "origin_lon_deg", "origin_height_m", "gnss_valid"; navigation adds
/// "horizontal_sigma_m"), "gnss": {"valid", "fix_quality", "fix", "speed_mps", "stamp_s", "age_s",
/// "stale"}; each null while not heard, "rates_hz": {stream: Hz}}]}. "gaps": {"dead_reckoning":
/// {"missed", "gaps", "last": "missed 522 dead-reckoning outputs t=40.010-45.220 s" or null,
/// "last_first_missing_t_s", "last_last_missing_t_s" (null without a gap)}}.
nlohmann::json snapshot_json(const FleetSnapshot& snapshot);

/// The dashboard text: at most `height` lines of at most `width` characters (>= 40 x 8), one block
/// per vehicle while they fit, then a line counting the vehicles left out. With `ansi`, STALE
/// marks and warnings are shown in reverse video / colour (SGR codes, which take no columns).
std::string render_dashboard(const FleetSnapshot& snapshot, int width, int height, bool ansi, const std::string& title);

}  // namespace odonav::ground
