// Dead reckoner (docs/ALGORITHM.md §4) on synthetic drives with exact K and attitude.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "odonav/dead_reckoning/dead_reckoning_health.hpp"
#include "odonav/dead_reckoning/dead_reckoner.hpp"
#include "odonav/consumer_rules.hpp"
#include "odonav/dead_reckoning/drift_evaluator.hpp"
#include "odonav/dead_reckoning/scale_factor_selection.hpp"
#include "synthetic_drive.hpp"
#include "dr_health_facts.hpp"

using namespace odonav;
using namespace odonav::dead_reckoning;
using namespace odonav::synthetic;

namespace {

constexpr double kK = 0.0125;

// One lap of a circle whose circumference is exactly 25600 pulses (320 m), driven at 10 m/s with
// the odometer sampled at every 16th pulse edge (50 Hz), so the odometer itself carries no
// quantisation error and the DR must close the loop to the integration error alone.
SensorConfig lap_config() {
  SensorConfig c;
  c.duration_s = 32.0;
  c.k_m_per_pulse = kK;
  c.misalignment = Misalignment{deg_to_rad(0.8), deg_to_rad(-0.5)};
  return c;
}
Trajectory lap() { return circle(320.0 / (2.0 * kPi), 10.0, deg_to_rad(20.0)); }

std::vector<DeadReckoningOutput> run_all(const SyntheticData& d, const DeadReckonerParams& p,
                                         const std::optional<Misalignment>& mis = std::nullopt,
                                         DeadReckonerCounters* counters = nullptr) {
  DeadReckoner dr(p);
  if (mis) dr.add_misalignment(0.0, *mis);
  add_whole_drive(dr, d);
  auto out = dr.finish();
  if (counters) *counters = dr.counters();
  return out;
}

DeadReckonerParams exact_k() {
  DeadReckonerParams p;
  p.nominal_k_m_per_pulse = kK;
  return p;
}

}  // namespace

TEST(DeadReckoner, CircleWithExactKAndAttitudeClosesWithinMillimetres) {
  const SensorConfig c = lap_config();
  DeadReckonerCounters n;
  const auto out = run_all(simulate(lap(), c), exact_k(), c.misalignment, &n);
  ASSERT_EQ(out.size(), 1600u);  // every odometer sample after the start fix at t = 0
  EXPECT_EQ(n.before_start, 1u);
  const DeadReckoningOutput& end = out.back();
  EXPECT_NEAR(end.t_s, 32.0, 1e-9);
  EXPECT_NEAR(end.distance_m, 320.0, 1e-9);
  EXPECT_LT(end.enu_m.norm(), 2e-3);        // back at the start
  EXPECT_LT(end.horizontal_error_m, 2e-3);  // and on the GNSS fix there
  double max_err = 0.0;
  for (const auto& o : out) max_err = std::max(max_err, o.horizontal_error_m);
  // Between 10 Hz fixes the GNSS reference is a chord: up to 1 m^2 / (8 R) = 2.5 mm off the arc.
  EXPECT_LT(max_err, 4e-3);
  EXPECT_EQ(end.k_source, ScaleFactorSource::kNominal);
}

TEST(DeadReckoner, CounterWrapChangesNothing) {
  SensorConfig c = lap_config();
  const auto a = run_all(simulate(lap(), c), exact_k(), c.misalignment);
  c.pulse_offset = 4294967295u - 10000u;  // wraps 40 % into the lap
  const auto b = run_all(simulate(lap(), c), exact_k(), c.misalignment);
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].enu_m, b[i].enu_m) << i;
    EXPECT_EQ(a[i].distance_m, b[i].distance_m) << i;
  }
}

TEST(DeadReckoner, OnePercentKErrorGivesOnePercentOfDistanceAlongTrack) {
  SensorConfig c;
  c.duration_s = 100.0;
  c.k_m_per_pulse = kK;
  const SyntheticData d = simulate(straight(deg_to_rad(60.0), 0.0, 10.0, 0.0), c);  // 1000 m
  DeadReckonerParams p;
  p.nominal_k_m_per_pulse = 1.01 * kK;
  const auto out = run_all(d, p);
  const DeadReckoningOutput& end = out.back();
  // Along track 1 % long: 10 m over 1000 m; %D is relative to the odometer distance (1010 m).
  EXPECT_NEAR(end.horizontal_error_m, 10.0, 0.02);
  EXPECT_NEAR(end.error_percent_distance, 100.0 * 0.01 / 1.01, 0.003);
  const Eigen::Vector3d along(std::sin(deg_to_rad(60.0)), std::cos(deg_to_rad(60.0)), 0.0);
  EXPECT_NEAR(end.enu_m.dot(along), 1010.0, 0.02);

  // The identified K from t = 50 s on stops the growth: the error stays at the 5 m of the first half.
  DeadReckoner dr(p);
  dr.add_scale_factor(50.0, kK, ScaleFactorSource::kIdentified);
  add_whole_drive(dr, d);
  const auto fixed = dr.finish();
  EXPECT_NEAR(fixed.back().horizontal_error_m, 5.0, 0.02);
  EXPECT_EQ(fixed.back().k_source, ScaleFactorSource::kIdentified);
  EXPECT_EQ(fixed.back().k_m_per_pulse, kK);
  EXPECT_EQ(fixed[1000].k_source, ScaleFactorSource::kNominal);  // t = 20 s

  DriftEvaluator eval(100.0);
  for (const auto& o : out) eval.add(o.distance_m, o.horizontal_error_m);
  const DriftSummary s = eval.summary();
  EXPECT_NEAR(s.final_percent, 100.0 * 0.01 / 1.01, 0.003);
  EXPECT_NEAR(s.max_percent, 100.0 * 0.01 / 1.01, 0.01);
}

TEST(DeadReckoner, OneDegreeHeadingMisalignmentGives175PercentUntilApplied) {
  SensorConfig c;
  c.duration_s = 100.0;
  c.k_m_per_pulse = kK;
  c.misalignment = Misalignment{deg_to_rad(1.0), 0.0};
  const SyntheticData d = simulate(straight(deg_to_rad(200.0), 0.0, 10.0, 0.0), c);
  const auto raw = run_all(d, exact_k());
  // The DR runs 1 deg off the track: chord 2 sin(0.5 deg) = 1.745 % of the distance.
  EXPECT_NEAR(raw.back().error_percent_distance, 200.0 * std::sin(deg_to_rad(0.5)), 0.005);
  const auto fixed = run_all(d, exact_k(), c.misalignment);
  // What is left: up to one pulse of quantisation (1.25 cm) and the simulator's straight line in the
  // origin's tangent plane versus the DR's constant local bearing (meridian convergence, ~3 cm over
  // this 1 km at 52.5 deg latitude): 0.005 % of 1 km is 5 cm.
  EXPECT_LT(fixed.back().error_percent_distance, 0.005);
}

TEST(DeadReckoner, ThreeDFollowsTheSlopeTwoDLaysTheFullDistanceFlat) {
  SensorConfig c;
  c.duration_s = 50.0;
  c.k_m_per_pulse = kK;
  const double slope = deg_to_rad(5.0);
  const SyntheticData d = simulate(straight(0.0, slope, 10.0, 0.0), c);  // 500 m up a 5 deg slope
  const auto o3 = run_all(d, exact_k());
  EXPECT_NEAR(o3.back().enu_m.z(), 500.0 * std::sin(slope), 0.02);
  EXPECT_LT(o3.back().horizontal_error_m, 0.02);
  DeadReckonerParams p2 = exact_k();
  p2.mode = DeadReckoningMode::k2D;
  const auto o2 = run_all(d, p2);
  // 2-D: the height is held and the whole 500 m is laid on the horizontal, 1 / cos(5 deg) too long.
  EXPECT_NEAR(o2.back().position.height_m, c.origin.height_m, 1e-9);
  EXPECT_NEAR(o2.back().enu_m.head<2>().norm(), 500.0, 0.03);  // enu z: earth curvature only (2 cm)
  EXPECT_NEAR(o2.back().horizontal_error_m, 500.0 * (1.0 - std::cos(slope)), 0.02);
}

TEST(DeadReckoner, LeverArmMovesTheStartAndTheReferenceToTheInsPoint) {
  SensorConfig c;
  c.duration_s = 30.0;
  c.k_m_per_pulse = kK;
  c.lever_arm_body_m = Eigen::Vector3d(1.5, 0.5, 2.0);
  const SyntheticData d = simulate(circle(80.0, 8.0, 0.0), c);
  DeadReckonerParams p = exact_k();
  p.lever_arm_body_m = c.lever_arm_body_m;
  DeadReckoner dr(p);
  add_whole_drive(dr, d);
  const auto out = dr.finish();
  const LocalEnuFrame truth_frame(c.origin);
  EXPECT_LT(truth_frame.to_enu(*dr.origin()).norm(), 1e-6);  // the INS point, not the antenna
  double max_err = 0.0;
  for (const auto& o : out) max_err = std::max(max_err, o.horizontal_error_m);
  EXPECT_LT(max_err, kK + 0.005);  // one pulse of quantisation plus the GNSS chord
  // Without the lever arm the DR carries the start offset C(0) l rigidly while the antenna offset
  // turns with the vehicle: the error is the horizontal part of (C(0) - C(t)) l.
  const auto raw = run_all(d, exact_k());
  const Eigen::Vector3d drift = body_to_enu(d.ins.front().attitude) * c.lever_arm_body_m -
                                body_to_enu(d.ins.back().attitude) * c.lever_arm_body_m;
  EXPECT_GT(drift.head<2>().norm(), 2.0);
  EXPECT_NEAR(raw.back().horizontal_error_m, drift.head<2>().norm(), kK + 0.005);
}

TEST(DeadReckoner, WithoutInsUsesTheGnssCourseAndHoldsItInAnOutage) {
  SensorConfig c;
  c.duration_s = 40.0;
  c.k_m_per_pulse = kK;
  SyntheticData d = simulate(straight(deg_to_rad(45.0), 0.0, 10.0, 0.0), c);
  for (auto& g : d.gnss)
    if (g.t_s > 20.05 && g.t_s < 35.05) g.fix = 0;  // 15 s outage
  DeadReckonerParams p = exact_k();
  p.use_ins = false;
  DeadReckonerCounters n;
  const auto out = run_all(d, p, std::nullopt, &n);
  EXPECT_TRUE(out.back().degraded);
  EXPECT_NEAR(rad_to_deg(out.back().heading_rad), 45.0, 1e-9);
  EXPECT_LT(out.back().horizontal_error_m, 0.02);
  const DeadReckoningOutput& in_outage = out[1500];  // t = 30 s
  EXPECT_TRUE(in_outage.heading_held);
  EXPECT_FALSE(in_outage.gnss_reference);
  EXPECT_TRUE(std::isnan(in_outage.error_percent_distance));
  EXPECT_GT(n.heading_held, 700u);
}

namespace {
// Without INS, 1 Hz GNSS (exact positions and velocities, no accuracy fields), odometer at 50 Hz:
// 20 m forward at 2 m/s on azimuth 30 deg, a 2 s stop, then 5 m in reverse at 0.5 m/s (below the
// course's 1 m/s minimum speed: the course is held across the change of direction).
SyntheticData reversing_crawl() {
  const double az = deg_to_rad(30.0);
  const Eigen::Vector3d u(std::sin(az), std::cos(az), 0.0);
  auto along_m = [](double t) {
    return t <= 10.0 ? 2.0 * t : t <= 12.0 ? 20.0 : 20.0 - 0.5 * (std::min(t, 22.0) - 12.0);
  };
  auto speed_mps = [](double t) { return t < 10.0 ? 2.0 : t < 12.0 ? 0.0 : t < 22.0 ? -0.5 : 0.0; };
  auto path_m = [&](double t) { return t <= 12.0 ? along_m(t) : 20.0 + (20.0 - along_m(t)); };
  SyntheticData d;
  const LocalEnuFrame frame(Geodetic{deg_to_rad(52.5), deg_to_rad(13.4), 50.0});
  for (int i = 0; i <= 1200; ++i) {
    const double t = 0.02 * i;
    const auto pulses = static_cast<uint32_t>(std::floor(path_m(t) / kK + 1e-7));
    d.odometer.push_back({t, 1000u + pulses, t > 12.0 && t <= 22.0 ? -1 : 1});
  }
  for (int i = 0; i <= 24; ++i) {
    const double t = i;
    GnssSample g;
    g.t_s = t;
    g.position = frame.to_geodetic(along_m(t) * u);
    g.vel_enu_mps = speed_mps(t) * u;
    d.gnss.push_back(g);
  }
  return d;
}
}  // namespace

TEST(DeadReckoner, WithoutInsAReversingCrawlAtOneHertzIsDeadReckonedExactly) {
  DeadReckonerParams p = exact_k();
  p.use_ins = false;
  DeadReckonerCounters n;
  const auto out = run_all(reversing_crawl(), p, std::nullopt, &n);
  ASSERT_FALSE(out.empty());
  const DeadReckoningOutput& end = out.back();
  // 20 m out, 5 m back: 15 m from the start along 30 deg (pulse quantisation: under 2 pulses).
  const double az = deg_to_rad(30.0);
  EXPECT_NEAR(end.enu_m.x(), 15.0 * std::sin(az), 0.03);
  EXPECT_NEAR(end.enu_m.y(), 15.0 * std::cos(az), 0.03);
  EXPECT_NEAR(end.distance_m, 25.0, 0.03);
  EXPECT_LT(end.horizontal_error_m, 0.03);
  EXPECT_GT(n.reversing, 490u);
  EXPECT_GT(n.heading_held, 490u);  // the reverse leg is below the course's minimum speed
  EXPECT_EQ(n.distance_lost, 0u);
  // The 1 s GNSS interval is bridged (the gap follows the observed period): a reference at 5.5 s.
  const auto mid = std::find_if(out.begin(), out.end(), [](const auto& o) { return std::abs(o.t_s - 5.5) < 1e-9; });
  ASSERT_NE(mid, out.end());
  EXPECT_TRUE(mid->gnss_reference);
  EXPECT_LT(mid->horizontal_error_m, 0.03);
}

TEST(DeadReckoner, GnssGapFollowsTheObservedPeriod) {
  DeadReckonerParams p;
  EXPECT_DOUBLE_EQ(dead_reckoning_gnss_max_gap_s(p, std::nan("")), 0.5);  // nothing observed yet
  EXPECT_DOUBLE_EQ(dead_reckoning_gnss_max_gap_s(p, 0.1), 0.5);           // 10 Hz: the floor
  EXPECT_DOUBLE_EQ(dead_reckoning_gnss_max_gap_s(p, 1.0), 2.5);           // 1 Hz: 2.5 periods
  p.gnss_max_gap_s = 0.7;                                                 // fixed by the user
  EXPECT_DOUBLE_EQ(dead_reckoning_gnss_max_gap_s(p, 1.0), 0.7);
  // At 10 Hz a 1 s hole in the fixes is not bridged: the error of the epoch 5.0 s (evaluated at
  // 5.2 s, after the hold-off) is carried for the 0.5 s gap, not to 5.8 s.
  SensorConfig c;
  c.duration_s = 10.0;
  SyntheticData d = simulate(straight(0.0, 0.0, 5.0, 0.0), c);
  d.gnss.erase(
      std::remove_if(d.gnss.begin(), d.gnss.end(), [](const GnssSample& g) { return g.t_s > 5.05 && g.t_s < 5.95; }),
      d.gnss.end());
  const auto out = run_all(d, exact_k());
  const auto hole = std::find_if(out.begin(), out.end(), [](const auto& o) { return std::abs(o.t_s - 5.8) < 1e-9; });
  ASSERT_NE(hole, out.end());
  EXPECT_FALSE(hole->gnss_reference);
  const auto carried = std::find_if(out.begin(), out.end(), [](const auto& o) { return std::abs(o.t_s - 5.6) < 1e-9; });
  ASSERT_NE(carried, out.end());
  EXPECT_NEAR(carried->error_t_s, 5.0, 1e-9);
}

TEST(DeadReckoner, PercentIsUndefinedBelowOneMetre) {
  SensorConfig c;
  c.duration_s = 2.0;
  const auto out = run_all(simulate(straight(0.0, 0.0, 5.0, 0.0), c), exact_k());
  EXPECT_TRUE(std::isnan(out[3].error_percent_distance));  // 0.08 s, 0.4 m
  // 0.62 s: the error of the epoch 0.4 s (2 m driven), evaluated after its 0.2 s hold-off.
  EXPECT_FALSE(std::isnan(out[30].error_percent_distance));
  EXPECT_NEAR(out[30].error_t_s, 0.4, 1e-9);
}

// The hold-off rule: an output at t needs GNSS (and K, misalignment) of the epochs <= t - hold-off
// only. With the GNSS up to 4.8 s, every output up to 5 s leaves, equal to the run with all data,
// and the error it carries refers to an epoch at least the hold-off before it.
TEST(DeadReckoner, AnOutputWaitsForNoGnssLaterThanItsTimeMinusTheHoldOff) {
  SensorConfig c;
  c.duration_s = 10.0;
  const SyntheticData d = simulate(straight(0.0, 0.0, 5.0, 0.0), c);
  DeadReckonerParams p = exact_k();
  ASSERT_DOUBLE_EQ(p.estimate_hold_off_s, 0.2);
  const auto all = run_all(d, p);
  DeadReckoner dr(p);
  for (const auto& s : d.odometer) dr.add_odometer(s);
  for (const auto& s : d.ins) dr.add_ins(s);
  for (const auto& s : d.gnss)
    if (s.t_s <= 4.8 + 1e-9) dr.add_gnss(s);
  const auto out = dr.process_until(5.0);
  ASSERT_FALSE(out.empty());
  EXPECT_NEAR(out.back().t_s, 5.0, 1e-9);
  ASSERT_LE(out.size(), all.size());
  for (std::size_t i = 0; i < out.size(); ++i) {
    EXPECT_EQ(out[i].t_s, all[i].t_s);
    EXPECT_EQ(out[i].enu_m, all[i].enu_m) << i;
    EXPECT_TRUE(out[i].horizontal_error_m == all[i].horizontal_error_m ||
                (std::isnan(out[i].horizontal_error_m) && std::isnan(all[i].horizontal_error_m)))
        << i;
    if (std::isfinite(out[i].error_t_s)) {
      EXPECT_LE(out[i].error_t_s, out[i].t_s - 0.2 + 1e-6) << i;
    }
  }
  EXPECT_NEAR(out.back().error_t_s, 4.8, 1e-9);
  EXPECT_LT(out.back().horizontal_error_m, 0.01);  // exact K, straight line
}

TEST(DeadReckoner, DifferentInterleavingsGiveBitIdenticalOutputs) {
  SensorConfig c = lap_config();
  c.velocity_noise_mps = 0.05;
  const SyntheticData d = simulate(lap(), c);
  auto feed_controls = [&](DeadReckoner& dr) {
    dr.add_misalignment(0.0, Misalignment{});
    dr.add_misalignment(10.0, c.misalignment);
    dr.add_scale_factor(5.0, 1.002 * kK, ScaleFactorSource::kIdentified);
    dr.add_scale_factor(20.0, kK, ScaleFactorSource::kCommanded);
  };
  DeadReckonerParams p;
  p.lever_arm_body_m = Eigen::Vector3d(0.3, 0.0, 1.0);
  DeadReckoner a(p);
  feed_controls(a);
  for (const auto& s : d.gnss) a.add_gnss(s);
  for (const auto& s : d.odometer) a.add_odometer(s);
  for (const auto& s : d.ins) a.add_ins(s);
  const auto oa = a.finish();

  DeadReckoner b(p);
  feed_controls(b);
  std::vector<DeadReckoningOutput> ob;
  feed_in_random_bursts(d, b, 21, 50, [&](double w) {
    for (const auto& o : b.process_until(w)) ob.push_back(o);
  });
  for (const auto& o : b.finish()) ob.push_back(o);
  ASSERT_EQ(oa.size(), ob.size());
  ASSERT_EQ(oa.size(), 1600u);
  for (std::size_t i = 0; i < oa.size(); ++i) {
    EXPECT_EQ(oa[i].t_s, ob[i].t_s);
    EXPECT_EQ(oa[i].enu_m, ob[i].enu_m) << i;
    EXPECT_EQ(oa[i].position.lat_rad, ob[i].position.lat_rad) << i;
    EXPECT_EQ(oa[i].k_source, ob[i].k_source) << i;
    EXPECT_TRUE(oa[i].horizontal_error_m == ob[i].horizontal_error_m ||
                (std::isnan(oa[i].horizontal_error_m) && std::isnan(ob[i].horizontal_error_m)))
        << i;
  }
  EXPECT_EQ(oa[100].k_source, ScaleFactorSource::kNominal);     // 2 s
  EXPECT_EQ(oa[500].k_source, ScaleFactorSource::kIdentified);  // 10 s
  EXPECT_EQ(oa.back().k_source, ScaleFactorSource::kCommanded);
}

TEST(DriftEvaluator, FinalAndMaximumPercentAboveTheMinimumDistance) {
  DriftEvaluator e(100.0);
  e.add(50.0, 5.0);                                        // below 100 m: ignored
  e.add(200.0, 2.0);                                       // 1 %
  e.add(300.0, std::numeric_limits<double>::quiet_NaN());  // no reference
  e.add(400.0, 2.0);                                       // 0.5 %
  const DriftSummary s = e.summary();
  EXPECT_EQ(s.points, 2u);
  EXPECT_DOUBLE_EQ(s.final_percent, 0.5);
  EXPECT_DOUBLE_EQ(s.max_percent, 1.0);
  EXPECT_DOUBLE_EQ(s.max_percent_distance_m, 200.0);
}

TEST(DriftEvaluator, AgainstATruthTrack) {
  SensorConfig c;
  c.duration_s = 60.0;
  c.k_m_per_pulse = kK;
  const Trajectory tr = straight(deg_to_rad(10.0), 0.0, 10.0, 0.0);
  const SyntheticData d = simulate(tr, c);
  const LocalEnuFrame frame(c.origin);
  std::vector<TruthSample> truth;
  for (int i = 0; i <= 600; ++i) {
    TruthSample t;
    t.t_s = 0.1 * i;
    t.position = frame.to_geodetic(tr.enu_m(t.t_s));
    truth.push_back(t);
  }
  const TruthTrack track(truth);
  DeadReckonerParams p;
  p.nominal_k_m_per_pulse = 0.995 * kK;
  DriftEvaluator eval;
  for (const auto& o : run_all(d, p)) {
    const auto ref = track.position_at(o.t_s);
    ASSERT_TRUE(ref.has_value());
    eval.add(o.distance_m, horizontal_distance_m(o.position, *ref));
  }
  EXPECT_NEAR(eval.summary().final_percent, 100.0 * 0.005 / 0.995, 0.003);
  EXPECT_FALSE(track.position_at(61.0).has_value());
}

TEST(DeadReckoner, BadInputIsRejectedWithClearErrors) {
  DeadReckonerParams bad;
  bad.nominal_k_m_per_pulse = 0.0;
  EXPECT_THROW(DeadReckoner{bad}, std::invalid_argument);
  DeadReckoner dr;
  EXPECT_THROW(dr.add_scale_factor(1.0, std::numeric_limits<double>::infinity(), ScaleFactorSource::kCommanded),
               StreamInputError);
  dr.add_odometer({1.0, 5u, 1});
  try {
    dr.add_odometer({0.5, 6u, 1});
    FAIL();
  } catch (const StreamInputError& e) {
    EXPECT_NE(std::string(e.what()).find("odometer"), std::string::npos);
  }
}

// --- pulse jumps: a counter glitch must not move the dead reckoning by kilometres ---

TEST(DeadReckoner, MillionfoldPulseStepIsRejectedCountedAndTheLapStillCloses) {
  const SensorConfig c = lap_config();
  SyntheticData d = simulate(lap(), c);
  // 16 pulses per 50 Hz sample; from sample 800 (half a lap) the counter reads 16 million too high
  // (200 km at K): the gate is 100 m/s / K * 20 ms + 2 = 162 pulses.
  for (std::size_t i = 800; i < d.odometer.size(); ++i) d.odometer[i].pulses += 16000000u;
  DeadReckonerCounters n;
  const auto out = run_all(d, exact_k(), c.misalignment, &n);
  EXPECT_EQ(n.pulse_jumps_rejected, 1u);
  EXPECT_EQ(n.pulse_rebases, 1u);
  ASSERT_EQ(out.size(), 1599u);  // the rejected sample has no output
  // The interval holding the jump is estimated at the last rate (exact at this constant speed).
  EXPECT_NEAR(out.back().distance_m, 320.0, 1e-9);
  EXPECT_LT(out.back().enu_m.norm(), 2e-3);
  double max_err = 0.0, max_from_start = 0.0;
  for (const auto& o : out) {
    max_err = std::max(max_err, o.horizontal_error_m);
    max_from_start = std::max(max_from_start, o.enu_m.norm());
  }
  EXPECT_LT(max_err, 4e-3);
  EXPECT_LT(max_from_start, 320.0 / kPi + 1e-3);  // never beyond the lap's diameter
}

TEST(DeadReckoner, MillionfoldPulseSpikeIsRejectedAndNoDistanceIsLost) {
  const SensorConfig c = lap_config();
  SyntheticData d = simulate(lap(), c);
  d.odometer[800].pulses += 16000000u;  // one bad value
  DeadReckonerCounters n;
  const auto out = run_all(d, exact_k(), c.misalignment, &n);
  EXPECT_EQ(n.pulse_jumps_rejected, 1u);
  EXPECT_EQ(n.pulse_rebases, 0u);
  ASSERT_EQ(out.size(), 1599u);
  EXPECT_NEAR(out.back().distance_m, 320.0, 1e-9);
  double max_err = 0.0;
  for (const auto& o : out) max_err = std::max(max_err, o.horizontal_error_m);
  // The interval around the dropped sample is 40 ms long: its chord is still within millimetres.
  EXPECT_LT(max_err, 4e-3);
}

TEST(DeadReckoner, JumpGateFollowsTheNominalKAndTheMaximumSpeed) {
  const SensorConfig c = lap_config();
  const SyntheticData d = simulate(lap(), c);  // 10 m/s = 800 pulses/s
  DeadReckonerParams p = exact_k();
  p.max_speed_mps = 8.0;  // 640 pulses/s: 12.8 + 2 < 16 per sample, every increment is "too fast"
  DeadReckonerCounters n;
  run_all(d, p, c.misalignment, &n);
  EXPECT_EQ(n.pulse_jumps_rejected, 1600u);
  p.max_speed_mps = 11.0;  // 880 pulses/s: 17.6 + 2 >= 16
  run_all(d, p, c.misalignment, &n);
  EXPECT_EQ(n.pulse_jumps_rejected, 0u);
  p.max_speed_mps = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(DeadReckoner{p}, std::invalid_argument);
}

TEST(DeadReckoner, ErrorAgainstGnssComparesEachFixWithTheDrAtItsStampMinusTheLatency) {
  // From rest at 0.5 m/s^2 (20 m/s after 40 s), exact K: the DR is the truth. The receiver stamps
  // every fix 0.2 s late, so fix g shows the truth at g - 0.2: 0.2 v behind the DR at g (4 m at the
  // end). With the latency in force from 10 s on, the fixes from then on are compared with the DR
  // at g - 0.2, and the error is the DR's own (pulse quantisation, millimetres).
  SensorConfig c;
  c.duration_s = 40.0;
  c.k_m_per_pulse = kK;
  SyntheticData d = simulate(straight(deg_to_rad(60.0), 0.0, 0.0, 0.5), c);
  for (auto& g : d.gnss) g.t_s += 0.2;
  const auto run = [&](bool compensate, DeadReckonerCounters* n) {
    DeadReckoner dr(exact_k());
    if (compensate) {
      dr.add_gnss_latency(10.0, 0.2);
      dr.add_gnss_latency(10.0, 0.3);  // not later than the previous one: ignored, counted
      dr.add_gnss_latency(11.0, 0.2);  // unchanged: nothing new
    }
    add_whole_drive(dr, d);
    auto out = dr.finish();
    if (n) *n = dr.counters();
    return out;
  };
  const auto raw = run(false, nullptr);
  DeadReckonerCounters n;
  const auto compensated = run(true, &n);
  ASSERT_EQ(raw.size(), compensated.size());
  EXPECT_EQ(n.gnss_latency_stale, 1u);
  double worst_raw_after_10 = 0.0, worst_after_10 = 0.0;
  for (std::size_t i = 0; i < raw.size(); ++i) {
    // The positions are the same: the latency only moves the reference.
    EXPECT_EQ(raw[i].enu_m, compensated[i].enu_m) << i;
    if (!(compensated[i].error_t_s >= 10.5)) continue;  // epochs evaluated with the latency in force
    worst_raw_after_10 = std::max(worst_raw_after_10, raw[i].horizontal_error_m);
    worst_after_10 = std::max(worst_after_10, compensated[i].horizontal_error_m);
  }
  EXPECT_NEAR(raw.back().horizontal_error_m, 0.2 * 20.0, 0.05);  // 0.2 s x 20 m/s
  EXPECT_GT(worst_raw_after_10, 3.9);
  EXPECT_LT(worst_after_10, 0.02);
  EXPECT_LT(compensated.back().horizontal_error_m, 0.02);
  // A latency beyond +-10 s is not one.
  DeadReckoner dr(exact_k());
  EXPECT_THROW(dr.add_gnss_latency(1.0, 12.0), StreamInputError);
}

TEST(DeadReckoner, AStampThatLeadsItsMeasurementIsComparedWhenTheDrReachesIt) {
  // The same drive, the receiver stamping every fix `lead` s EARLY (a negative latency): fix g shows
  // the truth at g + lead. Within the hold-off (0.05 s) and beyond it (0.5 s: the DR must wait for
  // the instant the fix describes), every fix after the start is compared with the DR there and
  // anchors once: the run neither stops on a repeated fix time nor drops the fixes.
  for (const double lead : {0.05, 0.5}) {
    SensorConfig c;
    c.duration_s = 40.0;
    c.k_m_per_pulse = kK;
    SyntheticData d = simulate(straight(deg_to_rad(60.0), 0.0, 0.0, 0.5), c);
    for (auto& g : d.gnss) g.t_s -= lead;
    DeadReckoner dr(exact_k());
    dr.add_gnss_latency(0.0, -lead);
    add_whole_drive(dr, d);
    std::vector<DeadReckoningOutput> out;
    ASSERT_NO_THROW(out = dr.finish()) << lead;
    std::size_t fixes = 0, with_error = 0;
    double worst = 0.0, last_fix_t = -1e9;
    for (const auto& o : out) {
      for (const auto& f : o.gnss_fixes) {
        EXPECT_GT(f.t_s, last_fix_t) << lead;  // each fix once, in order
        last_fix_t = f.t_s;
        ++fixes;
      }
      if (std::isfinite(o.horizontal_error_m)) {
        ++with_error;
        worst = std::max(worst, o.horizontal_error_m);
      }
    }
    // 10 Hz over 40 s: the fixes from the start on, but the last ones (their instant after the end).
    EXPECT_GE(fixes, 390u - static_cast<std::size_t>(10 * lead) - 2) << lead;
    EXPECT_GT(with_error, out.size() * 9 / 10) << lead;
    // The lead is compensated: what remains is the start, taken at the first fix's stamp (no
    // latency is applied to the start) while the fix shows the vehicle lead s later, 0.5 a lead^2
    // further from rest, plus the DR's own error (below 0.02 m, as with a late stamp above).
    EXPECT_LT(worst, 0.5 * 0.5 * lead * lead + 0.02) << lead;
  }
}

// Held estimates. A 30 s straight drive with GNSS at 10 Hz and the odometer at 50 Hz; the
// identification publishes K from epoch 2.0 s on (K = kK (1 + 1e-4 i) at epoch i x 0.1 s) but its
// epochs 10.1-15.0 s never arrive (killed, restarted), and the calibration's epochs 20.1-22.0 s
// never arrive. With the hold-off 0.2 s the estimate of epoch g applies from g + 0.2 - 1 us, so
// the outputs t = 10.30-15.28 s (250 at 50 Hz) ran on the K of epoch 10.0 s and t = 20.30-22.28 s
// (100) on the misalignment of epoch 20.0 s; the outputs before 2.2 s (no K received yet: nominal)
// are not held. The report changes no number: the same run without it is bit-identical.
TEST(DeadReckoner, OutputsOnAnEstimateHeldThroughAnEstimatorSilenceAreCountedAsOneSpan) {
  SensorConfig c;
  c.duration_s = 30.0;
  c.k_m_per_pulse = kK;
  c.misalignment = Misalignment{deg_to_rad(0.8), deg_to_rad(-0.5)};
  const SyntheticData d = simulate(straight(deg_to_rad(30.0), 0.0, 8.0, 0.0), c);
  const auto k_lost = [](long i) { return i >= 101 && i <= 150; };
  const auto mis_lost = [](long i) { return i >= 201 && i <= 220; };
  const double hold_off_s = exact_k().estimate_hold_off_s;
  const auto run = [&](bool report, DeadReckoner& dr) {
    std::vector<DeadReckoningOutput> out;
    std::size_t io = 0, ii = 0, ig = 0;
    // As the node: inputs arrive in event time, processed every 0.1 s.
    for (long w = 1; w <= 301; ++w) {
      const double w_s = 0.1 * static_cast<double>(w);
      for (; io < d.odometer.size() && d.odometer[io].t_s <= w_s; ++io) dr.add_odometer(d.odometer[io]);
      for (; ii < d.ins.size() && d.ins[ii].t_s <= w_s; ++ii) dr.add_ins(d.ins[ii]);
      for (; ig < d.gnss.size() && d.gnss[ig].t_s <= w_s; ++ig) {
        const double g = d.gnss[ig].t_s;
        const long i = std::lround(g / 0.1);
        dr.add_gnss(d.gnss[ig]);
        if (i >= 20 && !k_lost(i)) {
          dr.add_scale_factor(estimate_applies_from_s(g, hold_off_s), kK * (1.0 + 1e-4 * static_cast<double>(i)),
                              ScaleFactorSource::kIdentified);
          if (report) dr.add_estimate_received(HeldEstimate::kScaleFactor, g);
        }
        if (!mis_lost(i)) {
          dr.add_misalignment(estimate_applies_from_s(g, hold_off_s), c.misalignment);
          if (report) dr.add_estimate_received(HeldEstimate::kMisalignment, g);
        }
      }
      for (const auto& o : dr.process_until(w_s)) out.push_back(o);
    }
    for (const auto& o : dr.finish()) out.push_back(o);
    return out;
  };
  DeadReckoner dr(exact_k());
  const auto out = run(true, dr);
  DeadReckoner silent(exact_k());
  const auto plain = run(false, silent);
  ASSERT_EQ(out.size(), plain.size());
  ASSERT_EQ(out.size(), 1500u);
  std::vector<double> k_held_t, mis_held_t;
  for (std::size_t i = 0; i < out.size(); ++i) {
    EXPECT_EQ(out[i].enu_m, plain[i].enu_m) << i;
    EXPECT_EQ(out[i].k_m_per_pulse, plain[i].k_m_per_pulse) << i;
    EXPECT_FALSE(plain[i].k_held || plain[i].misalignment_held) << i;  // no estimate reported: nothing held
    if (out[i].k_held) k_held_t.push_back(out[i].t_s);
    if (out[i].misalignment_held) mis_held_t.push_back(out[i].t_s);
    // A held K is the one of epoch 10.0 s (the last received before the silence).
    if (out[i].k_held) {
      EXPECT_DOUBLE_EQ(out[i].k_m_per_pulse, kK * (1.0 + 1e-4 * 100.0)) << out[i].t_s;
    }
  }
  ASSERT_EQ(k_held_t.size(), 250u);
  EXPECT_NEAR(k_held_t.front(), 10.30, 1e-9);
  EXPECT_NEAR(k_held_t.back(), 15.28, 1e-9);
  ASSERT_EQ(mis_held_t.size(), 100u);
  EXPECT_NEAR(mis_held_t.front(), 20.30, 1e-9);
  EXPECT_NEAR(mis_held_t.back(), 22.28, 1e-9);
  EXPECT_EQ(dr.counters().outputs_on_held_k, 250u);
  EXPECT_EQ(dr.counters().outputs_on_held_misalignment, 100u);
  EXPECT_EQ(silent.counters().outputs_on_held_k, 0u);

  const auto k_span = dr.last_held_span(HeldEstimate::kScaleFactor);
  ASSERT_TRUE(k_span.has_value());
  EXPECT_FALSE(k_span->open);
  EXPECT_EQ(k_span->outputs, 250u);
  EXPECT_NEAR(k_span->first_t_s, 10.30, 1e-9);
  EXPECT_NEAR(k_span->last_t_s, 15.28, 1e-9);
  EXPECT_NEAR(k_span->estimate_epoch_s, 10.0, 1e-9);
  EXPECT_EQ(held_span_text(HeldEstimate::kScaleFactor, *k_span),
            "outputs t=10.3-15.3 s used the K of t=10.0 s held: identification silent");
  const auto mis_span = dr.last_held_span(HeldEstimate::kMisalignment);
  ASSERT_TRUE(mis_span.has_value());
  EXPECT_EQ(held_span_text(HeldEstimate::kMisalignment, *mis_span),
            "outputs t=20.3-22.3 s used the misalignment of t=20.0 s held: calibration silent");

  // Health: WARN with the span while it goes on and for the notice duration after the last held
  // output (wall clock), then no more.
  DeadReckoningHealthFacts f = odonav::test::running_dr_facts(1, 1);
  f.held_k_span = k_span;
  f.held_k_changed_at_s = 100.0;
  f.now_s = 100.0 + kDeadReckoningNoticeDuration_s - 1.0;
  ComponentHealth h = dead_reckoning_health(f);
  EXPECT_EQ(h.level, ComponentHealth::Level::kWarn);
  EXPECT_EQ(h.reason, "outputs t=10.3-15.3 s used the K of t=10.0 s held: identification silent");
  f.now_s = 100.0 + kDeadReckoningNoticeDuration_s + 1.0;
  h = dead_reckoning_health(f);
  EXPECT_EQ(h.level, ComponentHealth::Level::kOk);
  EXPECT_EQ(h.reason, "");
  HeldSpan open = *k_span;
  open.open = true;
  f.held_k_span = open;
  h = dead_reckoning_health(f);  // an open span is told whatever the time
  EXPECT_EQ(h.reason, "outputs since t=10.3 s use the K of t=10.0 s held: identification silent");
}
