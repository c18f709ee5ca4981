#include "odonav/simulator/simulator.hpp"

#include <algorithm>
#include <cmath>
#include <deque>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <sstream>
#include <stdexcept>

namespace odonav::simulator {

namespace {

// One independent random stream per sensor, derived from the seed (splitmix64), so that changing
// e.g. the GNSS rate does not change the INS noise, and each stream draws in a fixed order.
std::mt19937_64 make_stream(std::uint64_t seed, std::uint64_t stream_id) {
  std::uint64_t z = seed + 0x9E3779B97F4A7C15ull * (stream_id + 1);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return std::mt19937_64(z ^ (z >> 31));
}

void require(bool ok, const std::string& field, const std::string& rule) {
  if (!ok) throw std::invalid_argument("SimulationConfig." + field + ": " + rule);
}

// Rate ratio truth/sensor, which must be a whole number so sensor epochs fall on truth rows.
int rate_ratio(double truth_rate_hz, double sensor_rate_hz, const std::string& field) {
  require(std::isfinite(sensor_rate_hz) && sensor_rate_hz > 0.0 && sensor_rate_hz <= truth_rate_hz, field,
          "must be > 0 and <= truth_rate_hz");
  const double r = truth_rate_hz / sensor_rate_hz;
  require(std::abs(r - std::round(r)) < 1e-9, field, "must divide truth_rate_hz a whole number of times");
  return static_cast<int>(std::round(r));
}

// Exact body attitude whose odometer axis points along the direction of travel (course azimuth
// heading_rad, path pitch pitch_rad) for the given body roll: C_b^n(att) * C_m^b * e1 = u.
// Starts from the small-angle answer and corrects heading and pitch by the remaining angular
// error; the map is the identity up to terms of misalignment * roll, so a few passes reach 1e-15.
Attitude body_attitude_for_motion(double heading_rad, double pitch_rad, double roll_rad, const Misalignment& mis) {
  const Eigen::Vector3d m = odometer_axis_in_body(mis);
  Attitude att{heading_rad + mis.heading_rad, pitch_rad - mis.pitch_rad, roll_rad};
  for (int pass = 0; pass < 8; ++pass) {
    const Eigen::Vector3d u = body_to_enu(att) * m;
    const double heading_now = std::atan2(u.x(), u.y());
    const double pitch_now = std::asin(std::clamp(u.z(), -1.0, 1.0));
    att.heading_rad += wrap_pi(heading_rad - heading_now);
    att.pitch_rad += pitch_rad - pitch_now;
  }
  return att;
}

bool in_outage(const std::vector<GnssOutage>& outages, double t_rel_s) {
  for (const GnssOutage& o : outages) {
    if (t_rel_s >= o.start_s && t_rel_s < o.end_s) return true;
  }
  return false;
}

// Internal per-truth-row state that the sensors are built from.
struct TruthRow {
  double t_rel_s = 0.0;
  Geodetic position;
  Attitude attitude;  // unwrapped heading
  // geodesic_course: azimuth of the carried reference direction from true north (rad, unwrapped),
  // already in attitude.heading_rad; 0 otherwise.
  double heading_offset_rad = 0.0;
  Eigen::Vector3d vel_enu_mps = Eigen::Vector3d::Zero();
  double speed_mps = 0.0;  // along the track
  double k_base_m_per_pulse = 0.0;
  double k_true_m_per_pulse = 0.0;  // base divided by (1 + slip)
  double distance_m = 0.0;
  double s_m = 0.0;  // arc length along the road (decreases while reversing)
  std::uint32_t pulses = 0;
};

}  // namespace

std::vector<std::string> scenario_names() {
  return {"straight", "ring", "terrain", "slow_robot", "polar_north", "south_pole", "antimeridian"};
}

namespace {
// The antimeridian scenario's start: the training-ground lap reaches 1214 m east of its start, so
// 600 m west of 180 at 65 N puts longitude 180 across the middle of the ring.
constexpr double kAntimeridianStartLonDeg = 180.0 - 0.0127;

// The point `distance_m` from the North (south = false) or South Pole along the meridian lon_rad.
Geodetic near_pole(bool north, double distance_m, double lon_rad, double height_m) {
  const double dlat = distance_m / wgs84_radii(0.5 * kPi).meridian_m;  // R_M at the pole, exact to 1e-6
  return Geodetic{north ? 0.5 * kPi - dlat : -0.5 * kPi + dlat, lon_rad, height_m};
}
}  // namespace

SimulationConfig scenario_config(const std::string& name) {
  SimulationConfig c;
  c.scenario = name;
  if (name == "straight") {
    c.description = "straight calibration run: about 200 s at about 10 m/s on a straight road, start and stop";
    c.course = CourseKind::kStraight;
    c.hills = {Undulation{1.5, 400.0, 0.0}};
    c.cross_slopes = {Undulation{0.5 * kDegToRad, 300.0, 0.0}};
    return c;
  }
  if (name == "ring" || name == "terrain") {
    c.course = CourseKind::kTrainingGround;
    c.laps = 2;
    c.road_grade = 0.0;
    // Pitch up to about 4-5 deg: 2*pi*A/lambda is 0.044 and 0.038 for these.
    c.hills = {Undulation{4.0, 570.0, 0.0}, Undulation{1.2, 200.0, 0.5}};
    c.cross_slopes = {Undulation{1.5 * kDegToRad, 300.0, 0.0}};
    if (name == "ring") {
      c.description = "training-ground ring: two clockwise laps, arcs 12-80 m radius, speeds 3-15 m/s";
      return c;
    }
    c.description =
        "terrain: ring course with K steps (+3 % at 250 s, -2 % at 500 s), track slip in turns, a 120 s GNSS "
        "outage and GNSS velocity outliers";
    c.k_steps = {KStep{250.0, 1.03}, KStep{500.0, 0.98}};
    // 2 % more pulses per metre at 0.45 rad/s yaw rate (a 12-15 m radius turn at 5-6 m/s).
    c.turn_slip_per_radps = 0.05;
    c.turn_slip_max = 0.03;
    c.gnss_outages = {GnssOutage{560.0, 680.0}};
    c.gnss_velocity_outliers = 6;
    return c;
  }
  if (name == "polar_north" || name == "south_pole") {
    // A straight road of 3 km passing the pole at the closest distance near its middle: it starts
    // 1500 m from the pole, aimed off the meridian by asin(closest / 1500 m), so true north (and
    // the INS heading) turns by nearly 180 deg along it although the vehicle never turns.
    const bool north = name == "polar_north";
    const double closest_m = north ? 300.0 : 50.0;
    c.course = CourseKind::kStraight;
    c.geodesic_course = true;
    c.straight_length_m = 3000.0;
    c.straight_speed_mps = 10.0;
    c.road_grade = 0.0;
    c.hills = {Undulation{1.5, 400.0, 0.0}};
    c.cross_slopes = {Undulation{0.5 * kDegToRad, 300.0, 0.0}};
    c.start = near_pole(north, 1500.0, (north ? 30.0 : -60.0) * kDegToRad, north ? 20.0 : 2800.0);
    c.straight_heading_rad = (north ? 0.0 : kPi) + std::asin(closest_m / 1500.0);
    c.description = north ? "polar_north: a straight 3 km pass 300 m from the North Pole at 10 m/s"
                          : "south_pole: a straight 3 km traverse arriving 50 m from the South Pole and leaving "
                            "along the opposite meridian, at 10 m/s";
    return c;
  }
  if (name == "antimeridian") {
    c = scenario_config("terrain");
    c.scenario = name;
    c.geodesic_course = true;
    c.start = Geodetic{65.0 * kDegToRad, kAntimeridianStartLonDeg * kDegToRad, 40.0};
    c.description =
        "antimeridian: the terrain drive (K steps, slip, outage, outliers) at 65 N on a ring that "
        "crosses longitude 180 several times";
    return c;
  }
  if (name == "slow_robot") {
    c.description =
        "slow robot: stop-and-go legs at 0.6-3 m/s with a reversing manoeuvre after every third stop, on the "
        "training-ground course; 1 Hz RTK-grade GNSS, no INS, an 800-pulse encoder on a 0.15 m wheel, true K "
        "2 % above nominal";
    c.course = CourseKind::kTrainingGround;
    c.drive = DriveKind::kStopAndGo;
    c.road_grade = 0.0;
    c.hills = {Undulation{1.0, 570.0, 0.0}, Undulation{0.3, 200.0, 0.5}};
    c.cross_slopes = {Undulation{1.0 * kDegToRad, 300.0, 0.0}};
    c.k_nominal_m_per_pulse = kPi * 0.15 / 800.0;
    c.k_true_m_per_pulse = c.k_nominal_m_per_pulse * 1.02;
    c.odometer_rate_hz = 50.0;
    c.gnss_rate_hz = 1.0;
    // RTK fixed: centimetre positions, Doppler velocity of about 2 cm/s.
    c.gnss_pos_gm_std_m = 0.01;
    c.gnss_pos_white_std_m = 0.01;
    c.gnss_vel_std_mps = 0.02;
    c.gnss_vel_up_std_mps = 0.03;
    c.lever_arm_m = Eigen::Vector3d(0.1, 0.0, 0.4);
    c.has_ins = false;
    c.roll_per_lateral_accel_rad = 0.0;
    return c;
  }
  std::string names;
  for (const std::string& n : scenario_names()) names += (names.empty() ? "" : ", ") + n;
  throw std::invalid_argument("unknown scenario '" + name + "'; known scenarios: " + names);
}

void validate(const SimulationConfig& c) {
  require(std::isfinite(c.truth_rate_hz) && c.truth_rate_hz > 0.0 && c.truth_rate_hz <= 10000.0, "truth_rate_hz",
          "must be in (0, 10000]");
  require(c.substeps >= 1 && c.substeps <= 1000, "substeps", "must be in [1, 1000]");
  rate_ratio(c.truth_rate_hz, c.odometer_rate_hz, "odometer_rate_hz");
  rate_ratio(c.truth_rate_hz, c.gnss_rate_hz, "gnss_rate_hz");
  rate_ratio(c.truth_rate_hz, c.ins_rate_hz, "ins_rate_hz");
  require(c.course == CourseKind::kStraight || c.laps >= 1, "laps", "must be >= 1");
  require(std::isfinite(c.straight_length_m) && c.straight_length_m >= 10.0, "straight_length_m", "must be >= 10 m");
  require(std::isfinite(c.straight_speed_mps) && c.straight_speed_mps > 0.0 && c.straight_speed_mps < 40.0,
          "straight_speed_mps", "must be in (0, 40) m/s");
  require(std::isfinite(c.straight_heading_rad), "straight_heading_rad", "must be finite");
  require(std::isfinite(c.duration_s) && c.duration_s >= 0.0 && c.duration_s <= 7.0 * 86400.0, "duration_s",
          "must be in [0, 604800] s (0: natural length)");
  require(std::isfinite(c.standstill_start_s) && c.standstill_start_s >= 0.0, "standstill_start_s", "must be >= 0");
  require(std::isfinite(c.standstill_end_s) && c.standstill_end_s >= 0.0, "standstill_end_s", "must be >= 0");
  require(std::isfinite(c.road_grade) && std::abs(c.road_grade) < 0.3, "road_grade", "must be in (-0.3, 0.3)");
  require(std::isfinite(c.roll_per_lateral_accel_rad), "roll_per_lateral_accel_rad", "must be finite");
  require(std::isfinite(c.roll_time_constant_s) && c.roll_time_constant_s > 0.0, "roll_time_constant_s", "must be > 0");
  // Without geodesic_course the course's headings are rhumb lines, which spiral into a pole.
  require(
      std::isfinite(c.start.lat_rad) && std::abs(c.start.lat_rad) <= (c.geodesic_course ? 0.5 * kPi : 89.0 * kDegToRad),
      "start.lat_rad", "must be within +-89 deg (+-90 deg with geodesic_course)");
  require(std::isfinite(c.start.lon_rad) && std::isfinite(c.start.height_m), "start", "lon and height must be finite");
  require(std::isfinite(c.start_time_s) && c.start_time_s >= 0.0, "start_time_s", "must be >= 0");
  require(std::isfinite(c.k_nominal_m_per_pulse) && c.k_nominal_m_per_pulse > 0.0, "k_nominal_m_per_pulse",
          "must be > 0");
  require(std::isfinite(c.k_true_m_per_pulse) && c.k_true_m_per_pulse > 0.0, "k_true_m_per_pulse", "must be > 0");
  for (std::size_t i = 0; i < c.k_steps.size(); ++i) {
    require(std::isfinite(c.k_steps[i].t_s) && c.k_steps[i].t_s >= 0.0 && std::isfinite(c.k_steps[i].factor) &&
                c.k_steps[i].factor > 0.5 && c.k_steps[i].factor < 2.0,
            "k_steps[" + std::to_string(i) + "]", "t_s must be >= 0 and factor in (0.5, 2)");
    require(i == 0 || c.k_steps[i].t_s > c.k_steps[i - 1].t_s, "k_steps[" + std::to_string(i) + "]",
            "times must increase");
  }
  require(std::isfinite(c.turn_slip_per_radps) && c.turn_slip_per_radps >= 0.0, "turn_slip_per_radps", "must be >= 0");
  require(std::isfinite(c.turn_slip_threshold_radps) && c.turn_slip_threshold_radps >= 0.0, "turn_slip_threshold_radps",
          "must be >= 0");
  require(std::isfinite(c.turn_slip_max) && c.turn_slip_max >= 0.0 && c.turn_slip_max < 0.5, "turn_slip_max",
          "must be in [0, 0.5)");
  require(std::isfinite(c.misalignment.heading_rad) && std::abs(c.misalignment.heading_rad) < 10.0 * kDegToRad &&
              std::isfinite(c.misalignment.pitch_rad) && std::abs(c.misalignment.pitch_rad) < 10.0 * kDegToRad,
          "misalignment", "angles must be within +-10 deg");
  require(c.lever_arm_m.allFinite() && c.lever_arm_m.norm() < 20.0, "lever_arm_m", "must be finite, under 20 m");
  require(std::isfinite(c.gnss_latency_s) && c.gnss_latency_s >= 0.0 && c.gnss_latency_s < 10.0, "gnss_latency_s",
          "must be in [0, 10) s");
  for (double v : {c.gnss_pos_gm_std_m, c.gnss_pos_white_std_m, c.gnss_vertical_factor, c.gnss_vel_std_mps,
                   c.gnss_vel_up_std_mps, c.ins_heading_bias_rad, c.ins_heading_noise_rad, c.ins_tilt_noise_rad}) {
    require(std::isfinite(v), "noise parameters", "gnss_* and ins_* must be finite");
  }
  require(c.gnss_pos_gm_std_m >= 0.0 && c.gnss_pos_white_std_m >= 0.0 && c.gnss_vertical_factor >= 0.0 &&
              c.gnss_vel_std_mps >= 0.0 && c.gnss_vel_up_std_mps >= 0.0,
          "gnss noise", "standard deviations must be >= 0");
  require(std::isfinite(c.gnss_pos_gm_tau_s) && c.gnss_pos_gm_tau_s > 0.0, "gnss_pos_gm_tau_s", "must be > 0");
  require(c.ins_heading_noise_rad >= 0.0 && c.ins_tilt_noise_rad >= 0.0, "ins noise", "must be >= 0");
  for (std::size_t i = 0; i < c.gnss_outages.size(); ++i) {
    require(std::isfinite(c.gnss_outages[i].start_s) && std::isfinite(c.gnss_outages[i].end_s) &&
                c.gnss_outages[i].start_s >= 0.0 && c.gnss_outages[i].end_s > c.gnss_outages[i].start_s,
            "gnss_outages[" + std::to_string(i) + "]", "needs 0 <= start_s < end_s");
  }
  require(c.gnss_velocity_outliers >= 0 && c.gnss_velocity_outliers <= 1000, "gnss_velocity_outliers",
          "must be in [0, 1000]");
  require(std::isfinite(c.gnss_outlier_min_mps) && std::isfinite(c.gnss_outlier_max_mps) &&
              c.gnss_outlier_min_mps > 0.0 && c.gnss_outlier_max_mps >= c.gnss_outlier_min_mps,
          "gnss_outlier_min_mps/max_mps", "need 0 < min <= max");
}

namespace {

// ---- the road and the drive ----

// The road, its ground and the driver's speed along it, lengthened (more laps, a longer straight)
// until the drive lasts at least cfg.duration_s when that is set; the data are cut there.
struct Drive {
  Course course;
  TerrainProfile terrain;
  int laps;
  SpeedProfile profile;
  double total_time_s;             ///< length of the simulated data, s.
  std::optional<MotionPlan> plan;  ///< DriveKind::kStopAndGo: replaces the profile.
};

double natural_duration_s(const SimulationConfig& cfg, const SpeedProfile& profile) {
  return cfg.standstill_start_s + profile.duration_s() + cfg.standstill_end_s;
}

// The slow robot's legs (speed m/s, hold s), driven in this order and repeated: after each a stop of
// 3 s, after every third a reversing manoeuvre (0.6 m/s backwards for 8 s, about 5 m, then 2 s
// standing). Accelerations of a small tracked robot: 0.5 m/s^2 up, 0.8 m/s^2 braking.
MotionPlan slow_robot_plan(double min_duration_s) {
  const std::pair<double, double> legs[] = {{1.0, 40.0}, {2.5, 60.0}, {0.8, 30.0}, {3.0, 70.0},
                                            {1.8, 50.0}, {0.6, 30.0}, {2.2, 60.0}, {1.4, 45.0}};
  MotionPlan plan;
  for (int i = 0; plan.duration_s() < min_duration_s || i < 8; ++i) {
    const auto& leg = legs[i % 8];
    plan.go(leg.first, 0.5, leg.second);
    plan.go(0.0, 0.8, 0.0);
    plan.dwell(3.0);
    if (i % 3 == 2) {
      plan.go(-0.6, 0.4, 8.0);
      plan.go(0.0, 0.4, 0.0);
      plan.dwell(2.0);
    }
  }
  return plan;
}

Drive plan_drive(const SimulationConfig& cfg) {
  Course course = cfg.course == CourseKind::kStraight
                      ? Course::straight(cfg.straight_length_m, cfg.straight_heading_rad, cfg.straight_speed_mps)
                      : Course::training_ground();
  TerrainProfile terrain(cfg.road_grade, cfg.hills, cfg.cross_slopes, course);
  int laps = cfg.laps;
  double road_length_m = course.closed() ? laps * course.lap_length_m() : cfg.straight_length_m;
  SpeedProfile profile(course, road_length_m, cfg.driver);
  if (cfg.drive == DriveKind::kStopAndGo) {
    MotionPlan plan = slow_robot_plan(cfg.duration_s - cfg.standstill_start_s - cfg.standstill_end_s);
    const double natural_s = cfg.standstill_start_s + plan.duration_s() + cfg.standstill_end_s;
    const double total_s = cfg.duration_s > 0.0 ? cfg.duration_s : natural_s;
    return Drive{std::move(course), std::move(terrain), laps, std::move(profile), total_s, std::move(plan)};
  }
  if (cfg.duration_s > 0.0) {
    while (natural_duration_s(cfg, profile) < cfg.duration_s) {
      const double factor = cfg.duration_s / natural_duration_s(cfg, profile);
      if (course.closed()) {
        laps = std::max(laps + 1, static_cast<int>(std::ceil(laps * factor * 0.98)));
        road_length_m = laps * course.lap_length_m();
      } else {
        road_length_m *= std::max(1.05, factor);
      }
      profile = SpeedProfile(course, road_length_m, cfg.driver);
    }
  }
  const double total_time_s = cfg.duration_s > 0.0 ? cfg.duration_s : natural_duration_s(cfg, profile);
  return Drive{std::move(course), std::move(terrain), laps, std::move(profile), total_time_s, std::nullopt};
}

// Horizontal arc length and (signed) speed at t_rel_s after the start of the data (standstill first),
// read forward in time (SpeedProfile::Cursor: an earlier time than the last one starts the profile
// again from the beginning, so callers ask in time order).
class DriveCursor {
 public:
  DriveCursor(const SimulationConfig& cfg, const Drive& drive) : cfg_(cfg), drive_(drive), profile_(drive.profile) {}
  SpeedProfile::State at(double t_rel_s) {
    if (drive_.plan) {
      const MotionPlan::State st = drive_.plan->at(t_rel_s - cfg_.standstill_start_s);
      SpeedProfile::State out;
      out.s_m = st.s_m;
      out.speed_mps = st.speed_mps;
      return out;
    }
    return profile_.at(t_rel_s - cfg_.standstill_start_s);
  }

 private:
  const SimulationConfig& cfg_;
  const Drive& drive_;
  SpeedProfile::Cursor profile_;
};

// K before slip at t_rel_s, m/pulse: the initial true K times every K step reached.
double k_base_at(const SimulationConfig& cfg, double t_rel_s) {
  double k = cfg.k_true_m_per_pulse;
  for (const KStep& st : cfg.k_steps) {
    if (t_rel_s >= st.t_s) k *= st.factor;
  }
  return k;
}

// Track slip (extra pulses per metre, dimensionless) at a yaw rate, rad/s.
double slip_at(const SimulationConfig& cfg, double yaw_rate_radps) {
  return std::min(cfg.turn_slip_max,
                  cfg.turn_slip_per_radps * std::max(0.0, std::abs(yaw_rate_radps) - cfg.turn_slip_threshold_radps));
}

// Body roll the vehicle settles to at s_m, rad: outward in turns (right turn: left side down =
// negative roll) plus the ground's cross slope.
double roll_target_rad(const SimulationConfig& cfg, const Drive& drive, double s_m, double speed_mps) {
  return drive.terrain.cross_slope_rad(s_m) -
         cfg.roll_per_lateral_accel_rad * speed_mps * speed_mps * drive.course.at(s_m).curvature_per_m;
}

// ---- truth, integrated on the ellipsoid ----

// Time of truth row k after the start, s. A division, so that row 4134 is at 413.4, not
// 413.40000000000003; every use of a row's time goes through here.
double row_time_rel_s(const SimulationConfig& cfg, std::size_t k) { return static_cast<double>(k) / cfg.truth_rate_hz; }

// The vehicle's velocity, ENU m/s, moving at speed_mps along the road (azimuth heading_rad, slope
// dh/ds): the truth rows and the choice of GNSS outlier epochs (which looks at the speed before the
// truth is integrated) both use this one expression, so they agree to the bit.
Eigen::Vector3d velocity_enu_mps(double speed_mps, double heading_rad, double slope) {
  return speed_mps * Eigen::Vector3d(std::sin(heading_rad), std::cos(heading_rad), slope);
}

// The vehicle's state between truth rows, advanced in cfg.substeps steps per row.
class TruthIntegrator {
 public:
  TruthIntegrator(const SimulationConfig& cfg, const Drive& drive)
      : cfg_(cfg),
        drive_(drive),
        sub_dt_s_(1.0 / cfg.truth_rate_hz / cfg.substeps),
        roll_blend_(1.0 - std::exp(-sub_dt_s_ / cfg.roll_time_constant_s)),
        drive_at_(cfg, drive),
        pos_(cfg.start),
        roll_rad_(roll_target_rad(cfg, drive, 0.0, 0.0)) {
    if (cfg.geodesic_course) reference_north_ecef_ = enu_from_ecef(pos_).row(1).transpose();
  }

  // Truth row k (at k / truth_rate_hz), after integrating from row k - 1.
  TruthRow row(std::size_t k) {
    const double t_rel = row_time_rel_s(cfg_, k);
    if (k == 0) return row_at(t_rel, drive_at_.at(t_rel));
    for (int j = 1; j <= cfg_.substeps; ++j) {
      const double t_sub = j == cfg_.substeps ? t_rel : row_time_rel_s(cfg_, k - 1) + j * sub_dt_s_;
      substep(t_sub);
    }
    // The last substep ended at t_rel: its state is the drive's state at the row.
    return row_at(t_rel, SpeedProfile::State{s_prev_, v_prev_});
  }

 private:
  // Moves along the road from the last substep to t_sub: position, distance, pulses, roll.
  void substep(double t_sub) {
    const double t_mid = t_sub - 0.5 * sub_dt_s_;
    const SpeedProfile::State now = drive_at_.at(t_sub);
    const double ds_h = now.s_m - s_prev_;
    const CoursePoint mid = drive_.course.at(0.5 * (s_prev_ + now.s_m));
    const double dh = drive_.terrain.height_m(now.s_m) - drive_.terrain.height_m(s_prev_);
    if (cfg_.geodesic_course) {
      geodesic_step(mid.heading_rad, ds_h);
    } else {
      pos_ =
          move_geodetic(pos_, Eigen::Vector3d(ds_h * std::sin(mid.heading_rad), ds_h * std::cos(mid.heading_rad), dh));
    }
    pos_.height_m = cfg_.start.height_m + drive_.terrain.height_m(now.s_m);  // exact, no accumulation
    const double dd = std::hypot(ds_h, dh);
    distance_m_ += dd;
    const double yaw_rate_mid = 0.5 * (v_prev_ + now.speed_mps) * mid.curvature_per_m;
    pulse_phase_ += dd * (1.0 + slip_at(cfg_, yaw_rate_mid)) / k_base_at(cfg_, t_mid);
    roll_rad_ += (roll_target_rad(cfg_, drive_, now.s_m, now.speed_mps) - roll_rad_) * roll_blend_;
    s_prev_ = now.s_m;
    v_prev_ = now.speed_mps;
  }

  // geodesic_course: moves ds_h metres along the tangent plane in the direction course_heading_rad
  // from the carried reference direction (ECEF), then carries that direction into the new tangent
  // plane (parallel transport: no turn about the vertical) and measures its azimuth from true north.
  void geodesic_step(double course_heading_rad, double ds_h) {
    const Eigen::Vector3d up = enu_from_ecef(pos_).row(2).transpose();
    const Eigen::Vector3d reference_east = reference_north_ecef_.cross(up);
    const Eigen::Vector3d along =
        std::cos(course_heading_rad) * reference_north_ecef_ + std::sin(course_heading_rad) * reference_east;
    pos_ = from_ecef_m(to_ecef_m(pos_) + ds_h * along, pos_.lon_rad);
    const Eigen::Matrix3d enu = enu_from_ecef(pos_);
    const Eigen::Vector3d up_new = enu.row(2).transpose();
    reference_north_ecef_ = (reference_north_ecef_ - reference_north_ecef_.dot(up_new) * up_new).normalized();
    const double azimuth = std::atan2(reference_north_ecef_.dot(enu.row(0)), reference_north_ecef_.dot(enu.row(1)));
    heading_offset_rad_ += wrap_pi(azimuth - heading_offset_rad_);
  }

  TruthRow row_at(double t_rel, const SpeedProfile::State& st) const {
    CoursePoint cp = drive_.course.at(st.s_m);
    if (cfg_.geodesic_course) cp.heading_rad += heading_offset_rad_;
    const double slope = drive_.terrain.slope(st.s_m);
    TruthRow r;
    r.t_rel_s = t_rel;
    r.position = pos_;
    r.attitude = body_attitude_for_motion(cp.heading_rad, std::atan(slope), roll_rad_, cfg_.misalignment);
    r.vel_enu_mps = velocity_enu_mps(st.speed_mps, cp.heading_rad, slope);
    r.speed_mps = r.vel_enu_mps.norm();
    r.heading_offset_rad = heading_offset_rad_;
    r.k_base_m_per_pulse = k_base_at(cfg_, t_rel);
    r.k_true_m_per_pulse = r.k_base_m_per_pulse / (1.0 + slip_at(cfg_, st.speed_mps * cp.curvature_per_m));
    r.distance_m = distance_m_;
    r.s_m = st.s_m;
    // The counter shows whole pulses, modulo 2^32.
    r.pulses = static_cast<std::uint32_t>(
        (static_cast<std::uint64_t>(cfg_.counter_start) + static_cast<std::uint64_t>(std::floor(pulse_phase_))) &
        0xFFFFFFFFull);
    return r;
  }

  const SimulationConfig& cfg_;
  const Drive& drive_;
  const double sub_dt_s_;
  const double roll_blend_;
  DriveCursor drive_at_;
  Geodetic pos_;
  Eigen::Vector3d reference_north_ecef_ = Eigen::Vector3d::Zero();  // geodesic_course: unit, tangent
  double heading_offset_rad_ = 0.0;  // geodesic_course: its azimuth from true north, unwrapped
  double distance_m_ = 0.0, pulse_phase_ = 0.0;
  double s_prev_ = 0.0, v_prev_ = 0.0;
  double roll_rad_;
};

// ---- INS: true attitude + heading bias + white noise (random stream 2) ----

class InsModel {
 public:
  explicit InsModel(const SimulationConfig& cfg) : cfg_(cfg), rng_(make_stream(cfg.seed, 2)) {}
  InsSample sample(const TruthRow& r) {
    const double nh = normal_(rng_), np = normal_(rng_), nr = normal_(rng_);  // fixed draw order
    InsSample s;
    s.t_s = cfg_.start_time_s + r.t_rel_s;
    s.attitude.heading_rad =
        wrap_two_pi(r.attitude.heading_rad + cfg_.ins_heading_bias_rad + cfg_.ins_heading_noise_rad * nh);
    s.attitude.pitch_rad = r.attitude.pitch_rad + cfg_.ins_tilt_noise_rad * np;
    s.attitude.roll_rad = r.attitude.roll_rad + cfg_.ins_tilt_noise_rad * nr;
    return s;
  }

 private:
  const SimulationConfig& cfg_;
  std::mt19937_64 rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
};

// ---- GNSS at the antenna ----

struct Outlier {
  std::size_t epoch;
  Eigen::Vector2d error_en_mps;
  double t_s;  ///< the stamp of its GNSS row (meta.json lists it).
};

// The GNSS epochs: every `every`-th truth row from row 0, `count` of them.
struct GnssEpochs {
  std::size_t every;
  std::size_t count;
  std::size_t row(std::size_t epoch) const { return epoch * every; }
};

// A set of epoch numbers added in increasing order, held as runs of consecutive epochs (the
// candidates for a velocity outlier are long runs broken only by slow driving and outages), indexed
// as the sorted list they stand for.
class EpochRuns {
 public:
  void add(std::size_t epoch) {
    if (!runs_.empty() && runs_.back().first + runs_.back().count == epoch) {
      ++runs_.back().count;
    } else {
      runs_.push_back(Run{epoch, 1, size_});
    }
    ++size_;
  }
  std::size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  /// The i-th epoch of the sorted list (i < size()).
  std::size_t operator[](std::size_t i) const {
    const auto it = std::upper_bound(runs_.begin(), runs_.end(), i,
                                     [](std::size_t index, const Run& r) { return index < r.index; });
    const Run& r = *(it - 1);
    return r.first + (i - r.index);
  }

 private:
  struct Run {
    std::size_t first, count, index;  // first epoch, length, position of `first` in the list
  };
  std::vector<Run> runs_;
  std::size_t size_ = 0;
};

// Velocity outlier epochs, from their own random stream (3), drawn before the GNSS noise:
// moving (> 2 m/s), GNSS valid, at least 5 s apart; sorted by epoch. The speed at an epoch comes
// from the drive plan directly (what TruthIntegrator::row reports, without integrating the truth),
// so the outliers are known before the first sample is produced.
std::vector<Outlier> pick_velocity_outliers(const SimulationConfig& cfg, const Drive& drive, const GnssEpochs& epochs) {
  std::vector<Outlier> outliers;
  if (cfg.gnss_velocity_outliers <= 0) return outliers;
  std::mt19937_64 rng = make_stream(cfg.seed, 3);
  EpochRuns candidates;
  DriveCursor drive_at(cfg, drive);
  for (std::size_t e = 1; e + 1 < epochs.count; ++e) {
    const double t_rel = row_time_rel_s(cfg, epochs.row(e));
    const SpeedProfile::State st = drive_at.at(t_rel);
    const double speed_mps =
        velocity_enu_mps(st.speed_mps, drive.course.at(st.s_m).heading_rad, drive.terrain.slope(st.s_m)).norm();
    if (speed_mps > 2.0 && !in_outage(cfg.gnss_outages, t_rel)) candidates.add(e);
  }
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const double min_gap = 5.0 * cfg.gnss_rate_hz;
  for (int tries = 0;
       tries < 1000 && !candidates.empty() && outliers.size() < static_cast<std::size_t>(cfg.gnss_velocity_outliers);
       ++tries) {
    const std::size_t pick =
        std::min(candidates.size() - 1, static_cast<std::size_t>(unit(rng) * static_cast<double>(candidates.size())));
    const double magnitude =
        cfg.gnss_outlier_min_mps + (cfg.gnss_outlier_max_mps - cfg.gnss_outlier_min_mps) * unit(rng);
    const double angle = 2.0 * kPi * unit(rng);
    const std::size_t e = candidates[pick];
    const bool too_close = std::any_of(outliers.begin(), outliers.end(), [&](const Outlier& o) {
      return std::abs(static_cast<double>(o.epoch) - static_cast<double>(e)) < min_gap;
    });
    if (!too_close) {
      const double t_s = cfg.start_time_s + row_time_rel_s(cfg, epochs.row(e)) + cfg.gnss_latency_s;
      outliers.push_back(Outlier{e, magnitude * Eigen::Vector2d(std::sin(angle), std::cos(angle)), t_s});
    }
  }
  std::sort(outliers.begin(), outliers.end(), [](const Outlier& a, const Outlier& b) { return a.epoch < b.epoch; });
  return outliers;
}

// The receiver's errors, from random stream 1: a first-order Gauss-Markov position error (ENU, m)
// plus white position and velocity noise. Draw order per epoch: Gauss-Markov (not at the first
// epoch, whose value is the stationary draw made at construction), white, velocity.
class GnssErrorModel {
 public:
  explicit GnssErrorModel(const SimulationConfig& cfg)
      : rng_(make_stream(cfg.seed, 1)),
        phi_(std::exp(-(1.0 / cfg.gnss_rate_hz) / cfg.gnss_pos_gm_tau_s)),
        drive_(std::sqrt(1.0 - phi_ * phi_)),
        gm_std_(cfg.gnss_pos_gm_std_m, cfg.gnss_pos_gm_std_m, cfg.gnss_pos_gm_std_m * cfg.gnss_vertical_factor),
        white_std_(cfg.gnss_pos_white_std_m, cfg.gnss_pos_white_std_m,
                   cfg.gnss_pos_white_std_m * cfg.gnss_vertical_factor),
        vel_std_(cfg.gnss_vel_std_mps, cfg.gnss_vel_std_mps, cfg.gnss_vel_up_std_mps) {
    // The correlated error starts in its stationary distribution (a receiver that has been on).
    for (int a = 0; a < 3; ++a) gm_[a] = gm_std_[a] * normal_(rng_);
  }
  // Draws the errors of the next epoch (first = the first epoch).
  void next_epoch(bool first) {
    if (!first) {
      for (int a = 0; a < 3; ++a) gm_[a] = phi_ * gm_[a] + drive_ * gm_std_[a] * normal_(rng_);
    }
    for (int a = 0; a < 3; ++a) white_[a] = white_std_[a] * normal_(rng_);
    for (int a = 0; a < 3; ++a) vel_noise_[a] = vel_std_[a] * normal_(rng_);
  }
  Eigen::Vector3d position_error_enu_m() const { return gm_ + white_; }
  const Eigen::Vector3d& velocity_error_enu_mps() const { return vel_noise_; }

 private:
  std::mt19937_64 rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
  const double phi_, drive_;
  const Eigen::Vector3d gm_std_, white_std_, vel_std_;
  Eigen::Vector3d gm_, white_, vel_noise_;
};

// The GNSS rows, epoch after epoch: the truth at the antenna plus the receiver's errors, the
// outliers, and the outages (last position repeated, fix 0).
class GnssModel {
 public:
  GnssModel(const SimulationConfig& cfg, std::vector<Outlier> outliers)
      : cfg_(cfg),
        errors_(cfg),
        pos_std_m_(std::hypot(cfg.gnss_pos_gm_std_m, cfg.gnss_pos_white_std_m)),
        outliers_(std::move(outliers)) {}

  // The row of epoch `epoch` at truth row `r`; `before` and `after` are the truth rows either side
  // (or `r` itself at the ends), for the lever-arm velocity.
  GnssSample sample(std::size_t epoch, const TruthRow& before, const TruthRow& r, const TruthRow& after) {
    errors_.next_epoch(epoch == 0);
    const Eigen::Vector3d lever_enu = body_to_enu(r.attitude) * cfg_.lever_arm_m;
    const Eigen::Vector3d lever_vel = lever_arm_velocity_enu_mps(before, r, after);
    GnssSample g;
    g.t_s = cfg_.start_time_s + r.t_rel_s + cfg_.gnss_latency_s;
    if (in_outage(cfg_.gnss_outages, r.t_rel_s)) {
      // No solution: the receiver repeats its last position, reports no velocity, fix 0.
      g.position = last_valid_ ? *last_valid_ : move_geodetic(r.position, lever_enu);
      g.vel_enu_mps.setZero();
      g.fix = 0;
      g.pos_std_m = 999.0;
      g.vel_std_mps = 999.0;
    } else {
      g.position = move_geodetic(move_geodetic(r.position, lever_enu), errors_.position_error_enu_m());
      g.vel_enu_mps = r.vel_enu_mps + lever_vel + errors_.velocity_error_enu_mps();
      if (next_outlier_ < outliers_.size() && outliers_[next_outlier_].epoch == epoch) {
        g.vel_enu_mps.head<2>() += outliers_[next_outlier_].error_en_mps;
        ++next_outlier_;
      }
      g.fix = 1;
      g.pos_std_m = pos_std_m_;
      g.vel_std_mps = cfg_.gnss_vel_std_mps;
      last_valid_ = g.position;
    }
    return g;
  }

  const std::vector<Outlier>& outliers() const { return outliers_; }

 private:
  // Lever-arm velocity d(C_b^n l)/dt, ENU m/s, by central difference over the neighbouring truth
  // rows (10 ms): the truncation error is ~ (omega dt)^2 / 6 relative, far below the noise. With
  // geodesic_course only the body's own turning counts: the neighbours' headings are taken against
  // the reference direction of row r, since the turn of true north between the rows (the meridian
  // convergence, fast near a pole) moves no antenna.
  Eigen::Vector3d lever_arm_velocity_enu_mps(const TruthRow& before, const TruthRow& r, const TruthRow& after) const {
    Eigen::Vector3d lever_vel = Eigen::Vector3d::Zero();
    if (after.t_rel_s > before.t_rel_s) {
      Attitude a = after.attitude, b = before.attitude;
      if (cfg_.geodesic_course) {
        a.heading_rad -= after.heading_offset_rad - r.heading_offset_rad;
        b.heading_rad -= before.heading_offset_rad - r.heading_offset_rad;
      }
      lever_vel =
          (body_to_enu(a) * cfg_.lever_arm_m - body_to_enu(b) * cfg_.lever_arm_m) / ((after.t_rel_s - before.t_rel_s));
    }
    return lever_vel;
  }

  const SimulationConfig& cfg_;
  GnssErrorModel errors_;
  const double pos_std_m_;
  const std::vector<Outlier> outliers_;
  std::size_t next_outlier_ = 0;
  std::optional<Geodetic> last_valid_;
};

TruthSample truth_sample(const SimulationConfig& cfg, const TruthRow& r) {
  TruthSample ts;
  ts.t_s = cfg.start_time_s + r.t_rel_s;
  ts.position = r.position;
  ts.attitude = r.attitude;
  ts.attitude.heading_rad = wrap_two_pi(r.attitude.heading_rad);
  ts.k_true_m_per_pulse = r.k_true_m_per_pulse;
  ts.distance_m = r.distance_m;
  return ts;
}

// ---- meta ----

// meta.json's "simulation" object: what was simulated, for the evaluation and for people.
nlohmann::json simulation_meta(const SimulationConfig& cfg, const Drive& drive, const TruthRow& last,
                               const std::vector<Outlier>& outliers) {
  const Course& course = drive.course;
  const double s_end = last.s_m;  // the drive's arc length at the last row
  nlohmann::json sim;
  sim["scenario"] = cfg.scenario;
  sim["seed"] = cfg.seed;
  sim["course"] = course.closed() ? "training_ground" : "straight";
  sim["lap_length_m"] = course.lap_length_m();
  sim["laps_planned"] = course.closed() ? drive.laps : 1;
  sim["laps_completed"] = course.closed() ? static_cast<int>(std::floor(s_end / course.lap_length_m() + 1e-9)) : 0;
  sim["clockwise"] = course.closed() && course.lap_turning_rad() > 0.0;
  sim["duration_s"] = last.t_rel_s;
  sim["distance_m"] = last.distance_m;
  sim["start_time_s"] = cfg.start_time_s;
  sim["k_true_initial_m_per_pulse"] = cfg.k_true_m_per_pulse;
  nlohmann::json steps = nlohmann::json::array();
  double k = cfg.k_true_m_per_pulse;
  for (const KStep& st : cfg.k_steps) {
    steps.push_back({{"t_s", cfg.start_time_s + st.t_s}, {"k_before", k}, {"k_after", k * st.factor}});
    k *= st.factor;
  }
  sim["k_steps"] = steps;
  sim["turn_slip"] = {{"per_radps", cfg.turn_slip_per_radps},
                      {"threshold_radps", cfg.turn_slip_threshold_radps},
                      {"max", cfg.turn_slip_max}};
  nlohmann::json outages = nlohmann::json::array();
  for (const GnssOutage& o : cfg.gnss_outages) {
    outages.push_back({cfg.start_time_s + o.start_s, cfg.start_time_s + o.end_s});
  }
  sim["gnss_outages"] = outages;
  nlohmann::json outlier_list = nlohmann::json::array();
  for (const Outlier& o : outliers) {
    outlier_list.push_back(
        {{"t_s", o.t_s}, {"error_ve_mps", o.error_en_mps.x()}, {"error_vn_mps", o.error_en_mps.y()}});
  }
  sim["gnss_velocity_outliers"] = outlier_list;
  sim["lever_arm_m"] = {cfg.lever_arm_m.x(), cfg.lever_arm_m.y(), cfg.lever_arm_m.z()};
  sim["gnss_latency_s"] = cfg.gnss_latency_s;
  sim["gnss_rate_hz"] = cfg.gnss_rate_hz;
  sim["gnss_pos_gm_std_m"] = cfg.gnss_pos_gm_std_m;
  sim["gnss_pos_gm_tau_s"] = cfg.gnss_pos_gm_tau_s;
  sim["gnss_pos_white_std_m"] = cfg.gnss_pos_white_std_m;
  sim["gnss_vel_std_mps"] = cfg.gnss_vel_std_mps;
  sim["ins_heading_bias_deg"] = rad_to_deg(cfg.ins_heading_bias_rad);
  sim["ins_heading_noise_deg"] = rad_to_deg(cfg.ins_heading_noise_rad);
  sim["ins_tilt_noise_deg"] = rad_to_deg(cfg.ins_tilt_noise_rad);
  sim["counter_start"] = cfg.counter_start;
  if (cfg.geodesic_course) sim["geodesic_course"] = true;  // absent: headings from local north
  return sim;
}

// The dataset's meta (DATASET.md, meta.json) with `sim` as its "simulation" object.
DatasetMeta dataset_meta(const SimulationConfig& cfg, const nlohmann::json& sim) {
  DatasetMeta m;
  m.format = "odonav-dataset/1";
  m.vehicle_id = cfg.vehicle_id;
  m.description = cfg.description;
  m.k_nominal_m_per_pulse = cfg.k_nominal_m_per_pulse;
  m.truth_misalignment_heading_deg = rad_to_deg(cfg.misalignment.heading_rad);
  m.truth_misalignment_pitch_deg = rad_to_deg(cfg.misalignment.pitch_rad);
  nlohmann::json meta;
  meta["format"] = m.format;
  meta["vehicle_id"] = m.vehicle_id;
  meta["description"] = m.description;
  meta["odometer"] = {{"k_nominal_m_per_pulse", cfg.k_nominal_m_per_pulse}};
  meta["truth"] = {{"misalignment_heading_deg", *m.truth_misalignment_heading_deg},
                   {"misalignment_pitch_deg", *m.truth_misalignment_pitch_deg}};
  meta["simulation"] = sim;
  m.raw_json = meta.dump(2);
  m.gnss_lever_arm_m = cfg.lever_arm_m;
  return m;
}

}  // namespace

DatasetWriterOptions dataset_writer_options(const SimulationConfig& cfg) {
  DatasetWriterOptions o;
  o.gnss_pos_std_m = true;  // every GNSS row has both (999 in an outage)
  o.gnss_vel_std_mps = true;
  o.ins = cfg.has_ins;
  o.ins_velocity = false;  // the simulated INS reports attitude only
  o.truth = true;
  o.truth_columns = TruthColumns{};  // every column, every row
  return o;
}

DatasetMeta simulate(const SimulationConfig& cfg, SampleSink& sink) {
  validate(cfg);
  const Drive drive = plan_drive(cfg);
  const std::size_t n_rows = static_cast<std::size_t>(std::floor(drive.total_time_s * cfg.truth_rate_hz + 1e-9)) + 1;
  const std::size_t odometer_every = rate_ratio(cfg.truth_rate_hz, cfg.odometer_rate_hz, "odometer_rate_hz");
  const std::size_t ins_every = rate_ratio(cfg.truth_rate_hz, cfg.ins_rate_hz, "ins_rate_hz");
  const std::size_t gnss_every = rate_ratio(cfg.truth_rate_hz, cfg.gnss_rate_hz, "gnss_rate_hz");
  const GnssEpochs epochs{gnss_every, (n_rows - 1) / gnss_every + 1};
  // Each sensor draws from its own random stream (make_stream), so the order in which the sensors
  // are sampled does not change any number; within a stream the draw order is fixed.
  GnssModel gnss(cfg, pick_velocity_outliers(cfg, drive, epochs));
  InsModel ins(cfg);
  TruthIntegrator integrator(cfg, drive);

  // Three truth rows are held: the one being sampled and its neighbours (the GNSS lever-arm
  // velocity is a central difference). A GNSS row's stamp is its measurement time plus the
  // latency, so it waits in `stamped` until the truth reaches its stamp: at most latency * rate rows.
  TruthRow before, row = integrator.row(0), after;
  std::deque<GnssSample> stamped;
  double last_odometer_s_m = 0.0;
  for (std::size_t k = 0; k < n_rows; ++k) {
    if (k + 1 < n_rows) after = integrator.row(k + 1);
    const TruthRow& next = k + 1 < n_rows ? after : row;
    const TruthRow& previous = k > 0 ? before : row;
    const double t_s = cfg.start_time_s + row.t_rel_s;
    sink.add(truth_sample(cfg, row));
    if (k % odometer_every == 0) {
      // The counter counts up in both directions; the direction flag says which way the interval
      // ending here was driven (a quadrature encoder's direction bit).
      const int direction = k >= odometer_every && row.s_m < last_odometer_s_m ? -1 : 1;
      sink.add(OdometerSample{t_s, row.pulses, direction});
      last_odometer_s_m = row.s_m;
    }
    if (cfg.has_ins && k % ins_every == 0) sink.add(ins.sample(row));
    if (k % gnss_every == 0) stamped.push_back(gnss.sample(k / gnss_every, previous, row, next));
    while (!stamped.empty() && stamped.front().t_s <= t_s) {
      sink.add(stamped.front());
      stamped.pop_front();
    }
    if (k + 1 < n_rows) {
      before = std::move(row);
      row = std::move(after);
    }
  }
  for (; !stamped.empty(); stamped.pop_front()) sink.add(stamped.front());
  return dataset_meta(cfg, simulation_meta(cfg, drive, row, gnss.outliers()));
}

Dataset simulate(const SimulationConfig& cfg) {
  // Collects what the streaming simulation produces.
  struct Collector : SampleSink {
    Dataset ds;
    void add(const TruthSample& s) override { ds.truth.push_back(s); }
    void add(const OdometerSample& s) override { ds.odometer.push_back(s); }
    void add(const InsSample& s) override { ds.ins.push_back(s); }
    void add(const GnssSample& s) override { ds.gnss.push_back(s); }
  } collector;
  collector.ds.meta = simulate(cfg, static_cast<SampleSink&>(collector));
  return std::move(collector.ds);
}

}  // namespace odonav::simulator
