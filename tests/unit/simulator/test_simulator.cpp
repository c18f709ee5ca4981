// The simulator's output checked against its own ground truth by independent computations:
// pulses x K against distance, GNSS velocity projected on the odometer axis against the speed
// from truth distances, noise statistics against the configured values, and the scenario figures.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <numeric>
#include <sys/wait.h>
#include <unistd.h>

#include "odonav/simulator/simulator.hpp"
#include "odonav/dataset.hpp"
#include "odonav/frames.hpp"
#include "odonav/geodesy.hpp"

using namespace odonav;
using namespace odonav::simulator;

namespace {

const Dataset& scenario(const std::string& name) {
  static std::map<std::string, Dataset> cache;
  auto it = cache.find(name);
  if (it == cache.end()) it = cache.emplace(name, simulate(scenario_config(name))).first;
  return it->second;
}

nlohmann::json simulation_meta(const Dataset& ds) { return nlohmann::json::parse(ds.meta.raw_json).at("simulation"); }

struct Stats {
  double mean = 0.0, std = 0.0;
  std::size_t n = 0;
};
Stats stats(const std::vector<double>& v) {
  Stats s;
  s.n = v.size();
  if (v.empty()) return s;
  s.mean = std::accumulate(v.begin(), v.end(), 0.0) / v.size();
  double ss = 0.0;
  for (double x : v) ss += (x - s.mean) * (x - s.mean);
  s.std = std::sqrt(ss / std::max<std::size_t>(1, v.size() - 1));
  return s;
}

// Antenna velocity due to the lever arm, d(C_b^n l)/dt, from the truth attitudes either side.
Eigen::Vector3d lever_velocity(const Dataset& ds, std::size_t k, const Eigen::Vector3d& lever) {
  const Eigen::Vector3d a = body_to_enu(ds.truth[k - 1].attitude) * lever;
  const Eigen::Vector3d b = body_to_enu(ds.truth[k + 1].attitude) * lever;
  return (b - a) / (ds.truth[k + 1].t_s - ds.truth[k - 1].t_s);
}

// Unwrapped truth heading in degrees, row by row.
std::vector<double> unwrapped_heading_deg(const Dataset& ds) {
  std::vector<double> h;
  double acc = rad_to_deg(ds.truth.front().attitude.heading_rad);
  h.push_back(acc);
  for (std::size_t i = 1; i < ds.truth.size(); ++i) {
    acc += rad_to_deg(wrap_pi(ds.truth[i].attitude.heading_rad - ds.truth[i - 1].attitude.heading_rad));
    h.push_back(acc);
  }
  return h;
}

}  // namespace

TEST(Simulator, SameSeedIsIdenticalOtherSeedChangesOnlyNoise) {
  SimulationConfig cfg = scenario_config("terrain");
  cfg.seed = 7;
  const Dataset a = simulate(cfg), b = simulate(cfg);
  cfg.seed = 8;
  const Dataset c = simulate(cfg);
  ASSERT_EQ(a.gnss.size(), b.gnss.size());
  ASSERT_EQ(a.ins.size(), b.ins.size());
  ASSERT_EQ(a.odometer.size(), b.odometer.size());
  ASSERT_EQ(a.gnss.size(), c.gnss.size());
  for (std::size_t i = 0; i < a.gnss.size(); ++i) {
    ASSERT_EQ(a.gnss[i].position.lat_rad, b.gnss[i].position.lat_rad);
    ASSERT_EQ(a.gnss[i].position.height_m, b.gnss[i].position.height_m);
    ASSERT_EQ(a.gnss[i].vel_enu_mps, b.gnss[i].vel_enu_mps);
  }
  for (std::size_t i = 0; i < a.ins.size(); ++i)
    ASSERT_EQ(a.ins[i].attitude.heading_rad, b.ins[i].attitude.heading_rad);
  for (std::size_t i = 0; i < a.odometer.size(); ++i) {
    ASSERT_EQ(a.odometer[i].pulses, b.odometer[i].pulses);
    ASSERT_EQ(a.odometer[i].pulses, c.odometer[i].pulses);  // the drive does not depend on the seed
  }
  EXPECT_EQ(a.meta.raw_json, b.meta.raw_json);
  std::size_t differing_pos = 0, differing_ins = 0;
  for (std::size_t i = 0; i < a.gnss.size(); ++i)
    differing_pos += a.gnss[i].position.lat_rad != c.gnss[i].position.lat_rad;
  for (std::size_t i = 0; i < a.ins.size(); ++i)
    differing_ins += a.ins[i].attitude.pitch_rad != c.ins[i].attitude.pitch_rad;
  // Outage rows repeat the last fix, so all but those differ.
  EXPECT_GT(differing_pos, a.gnss.size() * 8 / 10);
  EXPECT_EQ(differing_ins, a.ins.size());
  EXPECT_NE(simulation_meta(a)["gnss_velocity_outliers"], simulation_meta(c)["gnss_velocity_outliers"]);
}

TEST(Simulator, PulsesTimesKReproduceTrueDistanceWithinOnePulse) {
  for (const std::string name : {"straight", "ring", "terrain"}) {
    const Dataset& ds = scenario(name);
    ASSERT_EQ(ds.odometer.size(), ds.truth.size()) << name;
    // Spans over which k_true is constant (no K step, no slip): a prefix count of changes.
    std::vector<std::size_t> changes(ds.truth.size(), 0);
    for (std::size_t i = 1; i < ds.truth.size(); ++i) {
      changes[i] = changes[i - 1] + (ds.truth[i].k_true_m_per_pulse != ds.truth[i - 1].k_true_m_per_pulse);
    }
    std::size_t checked = 0;
    double worst_pulses = 0.0;
    for (std::size_t span : {1u, 7u, 100u, 1000u, 10000u, 50000u}) {
      for (std::size_t i = 0; i + span < ds.odometer.size(); i += 37) {
        const std::size_t j = i + span;
        if (changes[j] != changes[i]) continue;
        ASSERT_EQ(ds.odometer[i].t_s, ds.truth[i].t_s);
        const double k = ds.truth[i].k_true_m_per_pulse;
        const double n = pulse_increment(ds.odometer[i].pulses, ds.odometer[j].pulses);
        const double d = ds.truth[j].distance_m - ds.truth[i].distance_m;
        worst_pulses = std::max(worst_pulses, std::abs(n * k - d) / k);
        ++checked;
      }
    }
    EXPECT_GT(checked, 1000u) << name;
    EXPECT_LE(worst_pulses, 1.0 + 1e-6) << name;
  }
}

TEST(Simulator, CounterWrapsInEveryDefaultScenarioWithRightIncrements) {
  for (const std::string& name : scenario_names()) {
    const Dataset& ds = scenario(name);
    EXPECT_EQ(ds.odometer.front().pulses, 4294967296ull - 100000ull) << name;
    int wraps = 0;
    for (std::size_t i = 1; i < ds.odometer.size(); ++i) {
      if (ds.odometer[i].pulses >= ds.odometer[i - 1].pulses) continue;
      ++wraps;
      const uint32_t inc = pulse_increment(ds.odometer[i - 1].pulses, ds.odometer[i].pulses);
      // Truth rows at the two odometer instants (the odometer may run slower than truth).
      const auto truth_at = [&](double t) {
        return *std::lower_bound(ds.truth.begin(), ds.truth.end(), t - 1e-9,
                                 [](const TruthSample& a, double v) { return a.t_s < v; });
      };
      const TruthSample& a = truth_at(ds.odometer[i - 1].t_s);
      const TruthSample& b = truth_at(ds.odometer[i].t_s);
      const double d = b.distance_m - a.distance_m;
      const double k = b.k_true_m_per_pulse;
      // < 15 m/s * dt / K, not a 2^32 jump
      EXPECT_LT(inc, 15.0 * (ds.odometer[i].t_s - ds.odometer[i - 1].t_s) / k + 2.0) << name;
      EXPECT_LE(std::abs(inc * k - d), k + 1e-9) << name;
    }
    EXPECT_EQ(wraps, 1) << name;
  }
}

TEST(Simulator, GnssVelocityOnOdometerAxisMatchesTruthSpeed) {
  const SimulationConfig cfg = scenario_config("ring");
  const Dataset& ds = scenario("ring");
  std::vector<double> forward_err, left, up, ins_left_over_forward;
  for (std::size_t e = 1; e + 1 < ds.gnss.size(); ++e) {
    const std::size_t k = e * 10;  // 10 Hz GNSS on 100 Hz truth
    ASSERT_NEAR(ds.gnss[e].t_s, ds.truth[k].t_s, 1e-9);
    // Truth speed from truth distances (independent of the simulator's velocity).
    const double speed = (ds.truth[k + 1].distance_m - ds.truth[k - 1].distance_m) / 0.02;
    if (speed < 1.0) continue;
    const Eigen::Vector3d v = ds.gnss[e].vel_enu_mps - lever_velocity(ds, k, cfg.lever_arm_m);
    const Attitude& att = ds.truth[k].attitude;
    const Eigen::Vector3d v_odo = odometer_to_body(cfg.misalignment).transpose() * enu_to_body(att) * v;
    forward_err.push_back(forward_speed_along_odometer(v, att, cfg.misalignment) - speed);
    left.push_back(v_odo.y());
    up.push_back(v_odo.z());
    const Eigen::Vector3d v_b = enu_to_body(att) * v;
    if (speed > 5.0) ins_left_over_forward.push_back(v_b.y() / v_b.x());
  }
  ASSERT_GT(forward_err.size(), 6000u);
  const Stats f = stats(forward_err), l = stats(left), u = stats(up);
  EXPECT_LT(std::abs(f.mean), 0.005);
  EXPECT_NEAR(f.std, 0.05, 0.01);
  // No side slip: the motion is along the odometer axis.
  EXPECT_LT(std::abs(l.mean), 0.005);
  EXPECT_NEAR(l.std, 0.05, 0.01);
  EXPECT_LT(std::abs(u.mean), 0.005);
  // In the INS body the motion shows the heading misalignment (0.8 deg, to the left).
  EXPECT_NEAR(rad_to_deg(stats(ins_left_over_forward).mean), 0.8, 0.01);
}

TEST(Simulator, GnssPositionNoiseMatchesConfiguredStatistics) {
  SimulationConfig cfg = scenario_config("ring");
  cfg.duration_s = 3600.0;
  cfg.seed = 11;
  const Dataset ds = simulate(cfg);
  EXPECT_NEAR(ds.truth.back().t_s, 3600.0, 1e-9);
  EXPECT_GE(simulation_meta(ds)["laps_completed"].get<int>(), 8);
  std::vector<double> east, north, up, d_east;
  Eigen::Vector3d prev_err(0, 0, 0);
  for (std::size_t e = 0; e < ds.gnss.size(); ++e) {
    const TruthSample& t = ds.truth[e * 10];
    const Geodetic antenna = move_geodetic(t.position, body_to_enu(t.attitude) * cfg.lever_arm_m);
    const Eigen::Vector3d err = LocalEnuFrame(antenna).to_enu(ds.gnss[e].position);
    east.push_back(err.x());
    north.push_back(err.y());
    up.push_back(err.z());
    if (e > 0) d_east.push_back(err.x() - prev_err.x());
    prev_err = err;
  }
  const double sigma = std::hypot(cfg.gnss_pos_gm_std_m, cfg.gnss_pos_white_std_m);  // 1.5 m per axis
  EXPECT_NEAR(stats(east).std, sigma, 0.2 * sigma);
  EXPECT_NEAR(stats(north).std, sigma, 0.2 * sigma);
  EXPECT_NEAR(stats(up).std, cfg.gnss_vertical_factor * sigma, 0.2 * cfg.gnss_vertical_factor * sigma);
  EXPECT_LT(std::abs(stats(east).mean), 1.0);
  EXPECT_LT(std::abs(stats(north).mean), 1.0);
  // Epoch-to-epoch differences: white part twice plus the Gauss-Markov step (many samples: 10 %).
  const double phi = std::exp(-0.1 / cfg.gnss_pos_gm_tau_s);
  const double d_sigma = std::sqrt(2.0 * cfg.gnss_pos_white_std_m * cfg.gnss_pos_white_std_m +
                                   2.0 * (1.0 - phi) * cfg.gnss_pos_gm_std_m * cfg.gnss_pos_gm_std_m);
  EXPECT_NEAR(stats(d_east).std, d_sigma, 0.1 * d_sigma);
  for (const GnssSample& g : ds.gnss) {
    ASSERT_EQ(g.fix, 1);
    ASSERT_NEAR(*g.pos_std_m, sigma, 1e-12);
    ASSERT_NEAR(*g.vel_std_mps, 0.05, 1e-12);
  }
}

TEST(Simulator, TerrainOutageRowsHaveFixZero) {
  const Dataset& ds = scenario("terrain");
  const nlohmann::json sim = simulation_meta(ds);
  ASSERT_EQ(sim["gnss_outages"].size(), 1u);
  const double t0 = sim["gnss_outages"][0][0], t1 = sim["gnss_outages"][0][1];
  EXPECT_DOUBLE_EQ(t1 - t0, 120.0);
  std::size_t outage_rows = 0;
  for (const GnssSample& g : ds.gnss) {
    const bool inside = g.t_s >= t0 - 1e-9 && g.t_s < t1 - 1e-9;
    EXPECT_EQ(g.fix, inside ? 0 : 1) << "t=" << g.t_s;
    EXPECT_EQ(g.valid(), !inside);
    outage_rows += inside;
  }
  EXPECT_EQ(outage_rows, 1200u);  // 120 s at 10 Hz, rows present and explicit
}

TEST(Simulator, TerrainVelocityOutliersAreWhereMetaSays) {
  const SimulationConfig cfg = scenario_config("terrain");
  const Dataset& ds = scenario("terrain");
  const nlohmann::json list = simulation_meta(ds)["gnss_velocity_outliers"];
  ASSERT_EQ(list.size(), 6u);
  std::map<long, Eigen::Vector2d> expected;
  for (const auto& o : list) {
    expected[std::lround(o["t_s"].get<double>() * 10.0)] = {o["error_ve_mps"].get<double>(),
                                                            o["error_vn_mps"].get<double>()};
  }
  std::size_t found = 0;
  double worst_normal = 0.0;
  for (std::size_t e = 1; e + 1 < ds.gnss.size(); ++e) {
    if (!ds.gnss[e].valid()) continue;
    const std::size_t k = e * 10;
    const Eigen::Vector3d truth =
        (body_to_enu(ds.truth[k].attitude) * odometer_to_body(cfg.misalignment) * Eigen::Vector3d::UnitX()) *
            ((ds.truth[k + 1].distance_m - ds.truth[k - 1].distance_m) / 0.02) +
        lever_velocity(ds, k, cfg.lever_arm_m);
    const Eigen::Vector3d err = ds.gnss[e].vel_enu_mps - truth;
    auto it = expected.find(std::lround(ds.gnss[e].t_s * 10.0));
    if (it != expected.end()) {
      ++found;
      EXPECT_GE(it->second.norm(), 3.0);
      EXPECT_LE(it->second.norm(), 10.0);
      EXPECT_NEAR(err.x(), it->second.x(), 0.25);
      EXPECT_NEAR(err.y(), it->second.y(), 0.25);
    } else {
      worst_normal = std::max(worst_normal, err.head<2>().norm());
    }
  }
  EXPECT_EQ(found, 6u);
  EXPECT_LT(worst_normal, 0.35);  // 0.05 m/s noise: far below the 3 m/s outliers
}

TEST(Simulator, TerrainKStepsInMetaMatchTruthAndSlipOnlyInTurns) {
  const SimulationConfig cfg = scenario_config("terrain");
  const Dataset& ds = scenario("terrain");
  const nlohmann::json steps = simulation_meta(ds)["k_steps"];
  ASSERT_EQ(steps.size(), 2u);
  EXPECT_DOUBLE_EQ(steps[0]["k_before"].get<double>(), cfg.k_true_m_per_pulse);
  EXPECT_NEAR(steps[0]["k_after"].get<double>() / steps[0]["k_before"].get<double>(), 1.03, 1e-12);
  EXPECT_NEAR(steps[1]["k_after"].get<double>() / steps[1]["k_before"].get<double>(), 0.98, 1e-12);
  EXPECT_DOUBLE_EQ(steps[1]["k_before"].get<double>(), steps[0]["k_after"].get<double>());
  EXPECT_DOUBLE_EQ(steps[0]["t_s"].get<double>(), 250.0);
  EXPECT_DOUBLE_EQ(steps[1]["t_s"].get<double>(), 500.0);
  // Without slip (low yaw rate) k_true is the base value: the nearest such rows either side of a
  // step show k_before and k_after.
  const std::vector<double> heading = unwrapped_heading_deg(ds);
  auto yaw_rate_at = [&](std::size_t i) {
    // One-sided rates: a central difference cancels where the S-bend turns from left to right.
    return deg_to_rad(std::max(std::abs(heading[i + 1] - heading[i]), std::abs(heading[i] - heading[i - 1]))) / 0.01;
  };
  for (const auto& st : steps) {
    const std::size_t step_row = static_cast<std::size_t>(std::lround(st["t_s"].get<double>() * 100.0));
    ASSERT_DOUBLE_EQ(ds.truth[step_row].t_s, st["t_s"].get<double>());
    std::size_t before = step_row - 1, after = step_row;
    while (yaw_rate_at(before) > 0.5 * cfg.turn_slip_threshold_radps) --before;
    while (yaw_rate_at(after) > 0.5 * cfg.turn_slip_threshold_radps) ++after;
    EXPECT_GT(ds.truth[before].t_s, ds.truth[step_row].t_s - 30.0);
    EXPECT_LT(ds.truth[after].t_s, ds.truth[step_row].t_s + 30.0);
    EXPECT_DOUBLE_EQ(ds.truth[before].k_true_m_per_pulse, st["k_before"].get<double>());
    EXPECT_DOUBLE_EQ(ds.truth[after].k_true_m_per_pulse, st["k_after"].get<double>());
  }
  // Slip: k_true below the base only where the yaw rate is high, and up to a few percent.
  std::size_t slipping = 0;
  double max_slip = 0.0;
  for (std::size_t i = 1; i + 1 < ds.truth.size(); ++i) {
    double base = cfg.k_true_m_per_pulse;
    for (const auto& st : steps) {
      if (ds.truth[i].t_s >= st["t_s"].get<double>()) base = st["k_after"];
    }
    const double slip = base / ds.truth[i].k_true_m_per_pulse - 1.0;
    const double yaw_rate = yaw_rate_at(i);
    if (slip > 1e-12) {
      ++slipping;
      EXPECT_GT(std::abs(yaw_rate), cfg.turn_slip_threshold_radps * 0.9) << "t=" << ds.truth[i].t_s;
    }
    max_slip = std::max(max_slip, slip);
  }
  EXPECT_GT(slipping, 1000u);
  EXPECT_GT(max_slip, 0.015);
  EXPECT_LE(max_slip, cfg.turn_slip_max + 1e-12);
}

TEST(Simulator, RingIsTwoClockwiseLapsOfAbout800Seconds) {
  const Dataset& ds = scenario("ring");
  const nlohmann::json sim = simulation_meta(ds);
  const double duration = ds.truth.back().t_s - ds.truth.front().t_s;
  EXPECT_GT(duration, 700.0);
  EXPECT_LT(duration, 900.0);
  EXPECT_EQ(sim["laps_completed"].get<int>(), 2);
  EXPECT_TRUE(sim["clockwise"].get<bool>());
  const std::vector<double> heading = unwrapped_heading_deg(ds);
  EXPECT_NEAR(heading.back() - heading.front(), 720.0, 0.5);
  // Back at the start, standing still.
  EXPECT_LT(horizontal_distance_m(ds.truth.front().position, ds.truth.back().position), 0.5);
  EXPECT_EQ(ds.odometer.back().pulses, ds.odometer[ds.odometer.size() - 300].pulses);
  // Distance is two laps (3-D, a little longer than the horizontal lap).
  const double lap = sim["lap_length_m"];
  EXPECT_GT(ds.truth.back().distance_m, 2.0 * lap);
  EXPECT_LT(ds.truth.back().distance_m, 2.0 * lap * 1.003);
  // Sample counts: 100 Hz odometer/INS/truth, 10 Hz GNSS.
  EXPECT_EQ(ds.odometer.size(), ds.ins.size());
  EXPECT_EQ(ds.gnss.size(), (ds.truth.size() - 1) / 10 + 1);
  // Pitch varies a few degrees, roll a few degrees from terrain and turns.
  double max_pitch = 0.0, max_roll = 0.0;
  for (const TruthSample& r : ds.truth) {
    max_pitch = std::max(max_pitch, std::abs(rad_to_deg(r.attitude.pitch_rad)));
    max_roll = std::max(max_roll, std::abs(rad_to_deg(r.attitude.roll_rad)));
  }
  EXPECT_GT(max_pitch, 2.0);
  EXPECT_LT(max_pitch, 8.0);
  EXPECT_GT(max_roll, 1.0);
  EXPECT_LT(max_roll, 6.0);
}

TEST(Simulator, StraightIsAbout200SecondsAtAbout10MetresPerSecond) {
  const Dataset& ds = scenario("straight");
  const double duration = ds.truth.back().t_s - ds.truth.front().t_s;
  EXPECT_GT(duration, 190.0);
  EXPECT_LT(duration, 210.0);
  std::vector<double> cruise;
  for (std::size_t i = 1; i + 1 < ds.truth.size(); ++i) {
    if (ds.truth[i].t_s > 30.0 && ds.truth[i].t_s < duration - 30.0) {
      cruise.push_back((ds.truth[i + 1].distance_m - ds.truth[i - 1].distance_m) / 0.02);
    }
  }
  const Stats s = stats(cruise);
  EXPECT_NEAR(s.mean, 10.0, 0.3);
  EXPECT_GT(s.std, 0.1);  // small variations, not constant
  EXPECT_LT(s.std, 0.6);
  EXPECT_EQ(ds.truth.front().distance_m, 0.0);
  EXPECT_GT(ds.truth.back().distance_m, 1800.0);
  const std::vector<double> heading = unwrapped_heading_deg(ds);
  EXPECT_LT(std::abs(heading.back() - heading.front()), 0.1);
}

TEST(Simulator, OdometerAxisPointsAlongTheTruthMotion) {
  const SimulationConfig cfg = scenario_config("ring");
  const Dataset& ds = scenario("ring");
  // The central chord is the tangent for constant curvature; where an arc meets a straight it is
  // off by up to curvature * step / 4 (0.06 deg in the 12 m turn), so judge the bulk by a percentile.
  std::vector<double> err_deg;
  for (std::size_t k = 1; k + 1 < ds.truth.size(); k += 3) {
    const Eigen::Vector3d chord = LocalEnuFrame(ds.truth[k].position).to_enu(ds.truth[k + 1].position) -
                                  LocalEnuFrame(ds.truth[k].position).to_enu(ds.truth[k - 1].position);
    if (chord.norm() < 0.04) continue;  // below 2 m/s
    const Eigen::Vector3d axis = body_to_enu(ds.truth[k].attitude) * odometer_axis_in_body(cfg.misalignment);
    err_deg.push_back(rad_to_deg(std::acos(std::min(1.0, axis.dot(chord.normalized())))));
  }
  ASSERT_GT(err_deg.size(), 5000u);
  std::sort(err_deg.begin(), err_deg.end());
  EXPECT_LT(err_deg[err_deg.size() * 995 / 1000], 0.002);
  EXPECT_LT(err_deg.back(), 0.1);  // a misalignment sign error would show 0.8 deg everywhere
}

TEST(Simulator, InsAttitudeHasConfiguredBiasAndNoise) {
  const Dataset& ds = scenario("ring");
  ASSERT_EQ(ds.ins.size(), ds.truth.size());
  std::vector<double> dh, dp, dr;
  for (std::size_t i = 0; i < ds.ins.size(); ++i) {
    dh.push_back(rad_to_deg(wrap_pi(ds.ins[i].attitude.heading_rad - ds.truth[i].attitude.heading_rad)));
    dp.push_back(rad_to_deg(ds.ins[i].attitude.pitch_rad - ds.truth[i].attitude.pitch_rad));
    dr.push_back(rad_to_deg(ds.ins[i].attitude.roll_rad - ds.truth[i].attitude.roll_rad));
    ASSERT_GE(ds.ins[i].attitude.heading_rad, 0.0);
    ASSERT_LT(ds.ins[i].attitude.heading_rad, 2.0 * kPi);
  }
  EXPECT_NEAR(stats(dh).mean, 0.02, 0.001);
  EXPECT_NEAR(stats(dh).std, 0.01, 0.002);
  EXPECT_NEAR(stats(dp).std, 0.005, 0.001);
  EXPECT_NEAR(stats(dr).std, 0.005, 0.001);
  EXPECT_LT(std::abs(stats(dp).mean), 0.0005);
}

TEST(Simulator, OneHertzGnssWithLatencyIsStampedLate) {
  SimulationConfig cfg = scenario_config("straight");
  cfg.gnss_rate_hz = 1.0;
  cfg.gnss_latency_s = 0.2;
  cfg.gnss_vel_std_mps = 0.0;
  cfg.gnss_vel_up_std_mps = 0.0;
  cfg.lever_arm_m.setZero();
  const Dataset ds = simulate(cfg);
  ASSERT_EQ(ds.gnss.size(), static_cast<std::size_t>(std::floor(ds.truth.back().t_s)) + 1);
  for (std::size_t e = 1; e + 1 < ds.gnss.size(); ++e) {
    EXPECT_NEAR(ds.gnss[e].t_s, e + 0.2, 1e-9);
    // Noise-free velocity equals the truth speed at the MEASUREMENT time, 0.2 s before the stamp
    // (0.2 s later the speed differs by up to 0.2 m/s; the central difference is within a*dt/4).
    const std::size_t k = e * 100;
    const double speed = (ds.truth[k + 1].distance_m - ds.truth[k - 1].distance_m) / 0.02;
    EXPECT_NEAR(ds.gnss[e].vel_enu_mps.norm(), speed, 3e-3) << "t=" << ds.gnss[e].t_s;
  }
  EXPECT_EQ(simulation_meta(ds)["gnss_latency_s"].get<double>(), 0.2);
}

TEST(Simulator, BadConfigAndUnknownScenarioNameTheProblem) {
  try {
    scenario_config("moon");
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("moon"), std::string::npos);
    for (const std::string& n : scenario_names()) EXPECT_NE(msg.find(n), std::string::npos) << msg;
  }
  SimulationConfig cfg = scenario_config("straight");
  cfg.gnss_rate_hz = 3.0;  // does not divide 100 Hz
  try {
    simulate(cfg);
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("gnss_rate_hz"), std::string::npos) << e.what();
  }
  cfg = scenario_config("straight");
  cfg.k_true_m_per_pulse = std::nan("");
  EXPECT_THROW(simulate(cfg), std::invalid_argument);
  cfg = scenario_config("terrain");
  cfg.gnss_outages = {GnssOutage{100.0, 50.0}};
  EXPECT_THROW(simulate(cfg), std::invalid_argument);
}

TEST(Simulator, WrittenDatasetReadsBackUnderFailPolicy) {
  const Dataset& ds = scenario("terrain");
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("odonav-simulator-test-" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  write_dataset(dir.string(), ds);
  DatasetReadReport report;
  const Dataset back = read_dataset(dir.string(), BadRowPolicy::kFail, &report);
  EXPECT_EQ(report.total_bad(), 0u);
  ASSERT_EQ(back.odometer.size(), ds.odometer.size());
  ASSERT_EQ(back.gnss.size(), ds.gnss.size());
  ASSERT_EQ(back.ins.size(), ds.ins.size());
  ASSERT_EQ(back.truth.size(), ds.truth.size());
  for (std::size_t i = 0; i < ds.odometer.size(); i += 97) EXPECT_EQ(back.odometer[i].pulses, ds.odometer[i].pulses);
  for (std::size_t i = 0; i < ds.gnss.size(); i += 31) {
    EXPECT_NEAR(back.gnss[i].position.lat_rad, ds.gnss[i].position.lat_rad, 1e-12);
    EXPECT_EQ(back.gnss[i].fix, ds.gnss[i].fix);
  }
  EXPECT_NEAR(back.truth.back().k_true_m_per_pulse, ds.truth.back().k_true_m_per_pulse, 1e-12);
  ASSERT_TRUE(back.meta.k_nominal_m_per_pulse.has_value());
  EXPECT_DOUBLE_EQ(*back.meta.k_nominal_m_per_pulse, 0.0125);
  EXPECT_DOUBLE_EQ(*back.meta.truth_misalignment_heading_deg, 0.8);
  EXPECT_EQ(simulation_meta(back)["k_steps"], simulation_meta(ds)["k_steps"]);
  std::filesystem::remove_all(dir);
}

TEST(Simulator, ExecutableWritesReadableDatasetAndRejectsBadArguments) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("odonav-simulator-exe-" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  const std::string exe = ODONAV_SIM_EXECUTABLE;
  const std::string cmd = exe + " straight --out " + dir.string() + " --seed 3 --gnss-rate 1 > /dev/null 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  const Dataset back = read_dataset(dir.string(), BadRowPolicy::kFail);
  const nlohmann::json sim = simulation_meta(back);
  EXPECT_EQ(sim["seed"].get<int>(), 3);
  EXPECT_EQ(sim["scenario"].get<std::string>(), "straight");
  EXPECT_EQ(back.gnss.size(), static_cast<std::size_t>(std::floor(back.truth.back().t_s)) + 1);  // 1 Hz
  EXPECT_TRUE(std::filesystem::exists(dir / "truth.csv"));
  EXPECT_TRUE(std::filesystem::exists(dir / "meta.json"));
  std::filesystem::remove_all(dir);
  // Bad arguments: exit code 2, nothing written.
  for (const std::string& args :
       std::vector<std::string>{"moon --out " + dir.string(), "ring", "ring --out " + dir.string() + " --seed x",
                                "ring --out " + dir.string() + " --gnss-rate 3"}) {
    const int rc = std::system((exe + " " + args + " > /dev/null 2>&1").c_str());
    EXPECT_TRUE(WIFEXITED(rc) && WEXITSTATUS(rc) == 2) << args;
  }
  EXPECT_FALSE(std::filesystem::exists(dir));
}

TEST(Simulator, SlowRobotStopsReversesAndHasNoIns) {
  const SimulationConfig cfg = scenario_config("slow_robot");
  const Dataset& ds = scenario("slow_robot");
  EXPECT_FALSE(ds.has_ins());
  EXPECT_NEAR(cfg.k_nominal_m_per_pulse, kPi * 0.15 / 800.0, 1e-15);
  EXPECT_NEAR(cfg.k_true_m_per_pulse / cfg.k_nominal_m_per_pulse, 1.02, 1e-12);
  // 1 Hz GNSS, 50 Hz odometer.
  ASSERT_GT(ds.gnss.size(), 400u);
  EXPECT_NEAR(ds.gnss[1].t_s - ds.gnss[0].t_s, 1.0, 1e-9);
  EXPECT_NEAR(ds.odometer[1].t_s - ds.odometer[0].t_s, 0.02, 1e-9);
  // Speeds up to 3 m/s, stops, and reversing: odometer direction -1 exactly while the truth
  // distance grows but the GNSS velocity points backwards along the heading of the road.
  double max_speed = 0.0;
  std::size_t reversing = 0, stopped = 0;
  for (const GnssSample& g : ds.gnss) max_speed = std::max(max_speed, g.vel_enu_mps.head<2>().norm());
  for (const OdometerSample& o : ds.odometer) reversing += o.direction < 0 ? 1 : 0;
  for (std::size_t i = 1; i < ds.odometer.size(); ++i) stopped += ds.odometer[i].pulses == ds.odometer[i - 1].pulses;
  EXPECT_LT(max_speed, 3.2);
  EXPECT_GT(max_speed, 2.8);
  EXPECT_GT(reversing, 1000u);  // two manoeuvres of about 9.5 s at 50 Hz
  EXPECT_GT(stopped, 1000u);
  // While reversing the pulses still count up, and the distance they make is the path driven.
  const double k = cfg.k_true_m_per_pulse;
  for (std::size_t i = 1; i < ds.odometer.size(); ++i) {
    if (ds.odometer[i].direction > 0) continue;
    const uint32_t inc = pulse_increment(ds.odometer[i - 1].pulses, ds.odometer[i].pulses);
    EXPECT_LE(inc * k, 0.6 * 0.02 + k + 1e-9);
  }
}

TEST(Simulator, MotionPlanGoesForwardBackwardAndStops) {
  MotionPlan plan;
  plan.go(2.0, 0.5, 10.0);  // 4 s to 2 m/s (4 m), 10 s at 2 m/s (20 m)
  plan.go(0.0, 1.0, 0.0);   // 2 s braking (2 m)
  plan.dwell(3.0);
  plan.go(-1.0, 0.5, 4.0);  // 2 s to -1 m/s (-1 m), 4 s (-4 m)
  plan.go(0.0, 0.5, 0.0);   // 2 s (-1 m)
  EXPECT_NEAR(plan.duration_s(), 4 + 10 + 2 + 3 + 2 + 4 + 2, 1e-12);
  EXPECT_NEAR(plan.at(4.0).s_m, 4.0, 1e-12);
  EXPECT_NEAR(plan.at(14.0).s_m, 24.0, 1e-12);
  EXPECT_NEAR(plan.at(17.0).s_m, 26.0, 1e-12);
  EXPECT_EQ(plan.at(17.0).speed_mps, 0.0);
  EXPECT_NEAR(plan.at(24.0).speed_mps, -1.0, 1e-12);
  EXPECT_NEAR(plan.at(plan.duration_s()).s_m, 20.0, 1e-12);
  EXPECT_NEAR(plan.max_s_m(), 26.0, 1e-12);
  EXPECT_THROW(plan.go(1.0, 0.0, 1.0), std::invalid_argument);
}

TEST(Simulator, PolarScenariosDriveAStraightRoadPastThePole) {
  // geodesic_course: the straight road is a geodesic, so its ends are the road's length apart and
  // it passes the pole at the distance it was aimed at, while the INS heading (true azimuth) turns
  // by nearly 180 deg. The GNSS velocity carries no lever-arm velocity from that turn of north
  // (near the pole north turns at v / 50 m = 0.2 rad/s, 0.12 m/s on this lever arm, always on the
  // same side of the body): its mean error in the body's axes is the receiver's noise alone.
  for (const auto& [name, closest_m] : {std::pair<std::string, double>{"polar_north", 300.0}, {"south_pole", 50.0}}) {
    const SimulationConfig cfg = scenario_config(name);
    const Dataset& ds = scenario(name);
    double nearest_m = 1e30;
    for (const TruthSample& t : ds.truth) {
      nearest_m = std::min(nearest_m, distance_to_pole_m(t.position));
      ASSERT_TRUE(t.position.lon_rad >= -kPi && t.position.lon_rad < kPi) << name << " t=" << t.t_s;
    }
    EXPECT_NEAR(nearest_m, closest_m, 0.5) << name;
    // Plane geometry round the pole (the start 1500 m out on the ellipsoid): the road runs at the
    // start height h, so its length L = 3000 m is L R / (R + h) on the ellipsoid (R the radius of
    // curvature at the pole), its end lies hypot(that - sqrt(1500^2 - d^2), d) from the pole, and
    // north turns by 180 deg less the two angles asin(d / distance) at the ends.
    const double start_m = 1500.0, r_m = wgs84_radii(0.5 * kPi).meridian_m;
    const double length_m = cfg.straight_length_m * r_m / (r_m + cfg.start.height_m);
    const double end_m = std::hypot(length_m - std::sqrt(start_m * start_m - closest_m * closest_m), closest_m);
    EXPECT_NEAR(horizontal_distance_m(ds.truth.front().position, ds.truth.back().position), length_m, 0.05) << name;
    EXPECT_NEAR(distance_to_pole_m(ds.truth.back().position), end_m, 0.5) << name;
    const double turn_deg =
        rad_to_deg(wrap_pi(ds.truth.back().attitude.heading_rad - ds.truth.front().attitude.heading_rad));
    EXPECT_NEAR(std::abs(turn_deg),
                180.0 - rad_to_deg(std::asin(closest_m / start_m)) - rad_to_deg(std::asin(closest_m / end_m)), 0.1)
        << name;
    double forward = 0.0, left = 0.0;
    std::size_t n = 0;
    for (std::size_t e = 0; e < ds.gnss.size(); ++e) {
      const std::size_t k = e * 10;  // 10 Hz GNSS on 100 Hz truth
      if (k == 0 || k + 1 >= ds.truth.size() || !ds.gnss[e].valid()) continue;
      if (distance_to_pole_m(ds.truth[k].position) > 2.0 * closest_m) continue;
      const LocalEnuFrame frame(ds.truth[k].position);
      const Eigen::Vector3d truth_v =
          (frame.to_enu(ds.truth[k + 1].position) - frame.to_enu(ds.truth[k - 1].position)) /
          (ds.truth[k + 1].t_s - ds.truth[k - 1].t_s);
      const Eigen::Vector3d err = ds.gnss[e].vel_enu_mps - truth_v;
      const double psi = ds.truth[k].attitude.heading_rad;
      forward += err.x() * std::sin(psi) + err.y() * std::cos(psi);
      left += -err.x() * std::cos(psi) + err.y() * std::sin(psi);
      ++n;
    }
    ASSERT_GT(n, 100u) << name;
    // 0.05 m/s per axis over at least 100 epochs: 0.005 m/s of noise in each mean.
    EXPECT_LT(std::hypot(forward, left) / static_cast<double>(n), 0.02) << name;
  }
}
