#pragma once
// Synthetic sensor data from an exactly known trajectory, for the tests of the sample builder, the
// misalignment calibrator and the dead reckoner (shared by tests/unit/{samples,calibration,dead_reckoning}).
//
// The trajectory is the INS reference point's path in a local ENU frame; the odometer axis points
// along the motion; the INS body is turned from it by the installation misalignment, exactly.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <random>
#include <vector>

#include "odonav/dataset.hpp"
#include "odonav/frames.hpp"
#include "odonav/geodesy.hpp"

namespace odonav::synthetic {

struct Trajectory {
  std::function<Eigen::Vector3d(double)> enu_m;      ///< reference point position (m) at t (s).
  std::function<Eigen::Vector3d(double)> direction;  ///< unit motion direction (ENU) at t.
  std::function<double(double)> speed_mps;           ///< speed along the track at t (>= 0).
  std::function<double(double)> distance_m;          ///< path length since t = 0.
};

/// Straight line at azimuth heading_rad (clockwise from north), climbing at slope_rad, speed v0 + a t.
inline Trajectory straight(double heading_rad, double slope_rad, double v0_mps, double accel_mps2) {
  const Eigen::Vector3d u(std::sin(heading_rad) * std::cos(slope_rad), std::cos(heading_rad) * std::cos(slope_rad),
                          std::sin(slope_rad));
  Trajectory tr;
  tr.distance_m = [=](double t) { return v0_mps * t + 0.5 * accel_mps2 * t * t; };
  tr.speed_mps = [=](double t) { return v0_mps + accel_mps2 * t; };
  tr.direction = [=](double) { return u; };
  tr.enu_m = [=](double t) { return Eigen::Vector3d((v0_mps * t + 0.5 * accel_mps2 * t * t) * u); };
  return tr;
}

/// Level circle driven clockwise (seen from above) at constant speed, starting at the origin with
/// azimuth heading0_rad.
inline Trajectory circle(double radius_m, double speed_mps, double heading0_rad) {
  const double w = speed_mps / radius_m;
  Trajectory tr;
  tr.distance_m = [=](double t) { return speed_mps * t; };
  tr.speed_mps = [=](double) { return speed_mps; };
  tr.direction = [=](double t) {
    const double psi = heading0_rad + w * t;
    return Eigen::Vector3d(std::sin(psi), std::cos(psi), 0.0);
  };
  // d/dt position = v (sin psi, cos psi): integrate exactly.
  tr.enu_m = [=](double t) {
    const double psi = heading0_rad + w * t;
    return Eigen::Vector3d(radius_m * (std::cos(heading0_rad) - std::cos(psi)),
                           radius_m * (std::sin(psi) - std::sin(heading0_rad)), 0.0);
  };
  return tr;
}

/// The body attitude (roll 0) whose odometer axis, turned by `mis`, points along the unit ENU vector u:
/// body_to_enu(att) * odometer_axis_in_body(mis) == u exactly (solved in closed form).
/// Speed 8 + 2 sin(2 pi t / 12) m/s on a straight line: accelerations of up to 1 m/s^2 that change
/// all the time, the signal a GNSS latency is read from.
inline Trajectory wavy_drive() {
  Trajectory tr = straight(deg_to_rad(30.0), 0.0, 8.0, 0.0);
  const double w = 2.0 * kPi / 12.0;
  const Eigen::Vector3d u = tr.direction(0.0);
  tr.speed_mps = [=](double t) { return 8.0 + 2.0 * std::sin(w * t); };
  tr.distance_m = [=](double t) { return 8.0 * t + 2.0 / w * (1.0 - std::cos(w * t)); };
  tr.enu_m = [=](double t) { return Eigen::Vector3d((8.0 * t + 2.0 / w * (1.0 - std::cos(w * t))) * u); };
  return tr;
}

inline Attitude body_attitude_for_motion(const Eigen::Vector3d& u, const Misalignment& mis) {
  const Eigen::Vector3d m = odometer_axis_in_body(mis);
  // Up component with roll 0: m_x sin p + m_z cos p = r sin(p + phi) = u_z.
  const double r = std::hypot(m.x(), m.z());
  const double phi = std::atan2(m.z(), m.x());
  const double p = std::asin(u.z() / r) - phi;
  // The levelled (forward, left) components of m are rotated by the heading onto u's azimuth.
  const double fwd = m.x() * std::cos(p) - m.z() * std::sin(p);
  const double h = std::atan2(u.x(), u.y()) + std::atan2(m.y(), fwd);
  return Attitude{wrap_two_pi(h), p, 0.0};
}

struct SensorConfig {
  double duration_s = 60.0;
  double k_m_per_pulse = 0.0125;
  double odometer_period_s = 0.02;
  double gnss_period_s = 0.1;
  double ins_period_s = 0.01;
  uint32_t pulse_offset = 1000;
  double velocity_noise_mps = 0.0;  ///< white noise on each ENU velocity component.
  uint32_t seed = 1;
  Misalignment misalignment;
  Geodetic origin{deg_to_rad(52.5), deg_to_rad(13.4), 50.0};
  Eigen::Vector3d lever_arm_body_m = Eigen::Vector3d::Zero();  ///< antenna in body FLU.
  double gnss_latency_s = 0.0;                                 ///< GNSS stamp = measurement time + this (s).
};

struct SyntheticData {
  std::vector<OdometerSample> odometer;
  std::vector<GnssSample> gnss;
  std::vector<InsSample> ins;
};

inline SyntheticData simulate(const Trajectory& tr, const SensorConfig& c) {
  SyntheticData d;
  const LocalEnuFrame frame(c.origin);
  auto attitude = [&](double t) { return body_attitude_for_motion(tr.direction(t), c.misalignment); };
  auto antenna_enu = [&](double t) -> Eigen::Vector3d {
    return tr.enu_m(t) + body_to_enu(attitude(t)) * c.lever_arm_body_m;
  };
  const long n_odo = std::lround(c.duration_s / c.odometer_period_s);
  for (long i = 0; i <= n_odo; ++i) {
    const double t = static_cast<double>(i) * c.odometer_period_s;
    // The tiny bias makes a sample taken exactly at a pulse edge count that pulse despite rounding.
    const double pulses = std::floor(tr.distance_m(t) / c.k_m_per_pulse + 1e-7);
    d.odometer.push_back({t, static_cast<uint32_t>(c.pulse_offset + static_cast<uint64_t>(pulses)), 1});
  }
  std::mt19937 rng(c.seed);
  std::normal_distribution<double> noise(0.0, c.velocity_noise_mps);
  const long n_gnss = std::lround(c.duration_s / c.gnss_period_s);
  for (long i = 0; i <= n_gnss; ++i) {
    const double t = static_cast<double>(i) * c.gnss_period_s;
    GnssSample g;
    g.t_s = t + c.gnss_latency_s;
    g.position = frame.to_geodetic(antenna_enu(t));
    Eigen::Vector3d v = tr.speed_mps(t) * tr.direction(t);
    if (c.lever_arm_body_m.squaredNorm() > 0.0) {
      const double h = 1e-4;  // the lever-arm term omega x l, by a central difference of the antenna path
      v = (antenna_enu(t + h) - antenna_enu(t - h)) / (2.0 * h);
    }
    if (c.velocity_noise_mps > 0.0) v += Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    g.vel_enu_mps = v;
    g.fix = 1;
    d.gnss.push_back(g);
  }
  const long n_ins = std::lround(c.duration_s / c.ins_period_s);
  for (long i = 0; i <= n_ins; ++i) {
    const double t = static_cast<double>(i) * c.ins_period_s;
    d.ins.push_back({t, attitude(t), std::nullopt});
  }
  return d;
}

/// The circle of the checkpoint tests (calibration, dead reckoning): 250 m at 10 m/s (2.3 deg/s)
/// from azimuth 30 deg, the INS turned by the installation misalignment checkpoint_misalignment(),
/// the GNSS antenna at checkpoint_lever_arm_body_m() (1.4 m from the INS).
inline Misalignment checkpoint_misalignment() { return Misalignment{deg_to_rad(0.8), deg_to_rad(-0.5)}; }
inline Eigen::Vector3d checkpoint_lever_arm_body_m() { return Eigen::Vector3d(0.8, -0.3, 1.1); }
inline Trajectory checkpoint_circle() { return circle(250.0, 10.0, deg_to_rad(30.0)); }

/// The sensors on checkpoint_circle(): `duration_s` of data, 0.05 m/s velocity noise drawn with `seed`.
inline SensorConfig checkpoint_sensors(double duration_s, uint32_t seed) {
  SensorConfig c;
  c.duration_s = duration_s;
  c.velocity_noise_mps = 0.05;
  c.seed = seed;
  c.misalignment = checkpoint_misalignment();
  c.lever_arm_body_m = checkpoint_lever_arm_body_m();
  return c;
}

/// Adds every sample of `d` to `core` (add_odometer, add_ins, add_gnss): the whole odometer, then the
/// INS, then the GNSS, for the tests that hand a core a drive at once.
template <class Core>
void add_whole_drive(Core& core, const SyntheticData& d) {
  for (const auto& s : d.odometer) core.add_odometer(s);
  for (const auto& s : d.ins) core.add_ins(s);
  for (const auto& s : d.gnss) core.add_gnss(s);
}

/// Feeds `d` to `core` (add_odometer, add_gnss, add_ins) as three streams with different lags: in
/// random bursts (seeded by `seed`) of 1 to max_burst samples of one stream at a time; after each
/// burst, process_until(w) with w the minimum over the streams not yet exhausted of the stamp of
/// their last sample fed (infinite once all are). The caller finishes the core.
template <class Core, class ProcessUntil>
void feed_in_random_bursts(const SyntheticData& d, Core& core, uint32_t seed, int max_burst,
                           ProcessUntil process_until) {
  std::mt19937 rng(seed);
  std::size_t io = 0, ig = 0, ii = 0;
  double wo = -1, wg = -1, wi = -1;
  while (io < d.odometer.size() || ig < d.gnss.size() || ii < d.ins.size()) {
    const int which = std::uniform_int_distribution<int>(0, 2)(rng);
    const int burst = std::uniform_int_distribution<int>(1, max_burst)(rng);
    for (int k = 0; k < burst; ++k) {
      if (which == 0 && io < d.odometer.size()) {
        core.add_odometer(d.odometer[io]);
        wo = d.odometer[io++].t_s;
      }
      if (which == 1 && ig < d.gnss.size()) {
        core.add_gnss(d.gnss[ig]);
        wg = d.gnss[ig++].t_s;
      }
      if (which == 2 && ii < d.ins.size()) {
        core.add_ins(d.ins[ii]);
        wi = d.ins[ii++].t_s;
      }
    }
    const double inf = std::numeric_limits<double>::infinity();
    process_until(
        std::min({io < d.odometer.size() ? wo : inf, ig < d.gnss.size() ? wg : inf, ii < d.ins.size() ? wi : inf}));
  }
}

}  // namespace odonav::synthetic
