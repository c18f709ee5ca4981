// Drives across longitude 180 and past both poles (odonav-simulator's antimeridian, polar_north and
// south_pole scenarios) through odonav-offline's chain, against the simulator's truth: every
// position written is in range, the pure DR and the GNSS-anchored navigation position are as
// accurate there as on an ordinary drive, the anchored position stays within its own stated sigma,
// the evaluation's figures are right, and a pass near a pole is warned about.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <string>

#include "odonav/simulator/simulator.hpp"
#include "odonav/offline/evaluation.hpp"
#include "odonav/checkpoint_state.hpp"
#include "odonav/dataset.hpp"
#include "odonav/frames.hpp"
#include "odonav/geodesy.hpp"
#include "odonav/offline/offline_runner.hpp"
#include "offline_test_params.hpp"
#include "odonav/offline/run_diagnosis.hpp"

using namespace odonav;
using namespace odonav::offline;
using namespace odonav::offline::test;

namespace {

struct ScenarioRun {
  simulator::SimulationConfig cfg;
  Dataset d;
  OfflineResult r;
};

ScenarioRun run(const std::string& scenario) {
  ScenarioRun x;
  x.cfg = simulator::scenario_config(scenario);
  x.cfg.seed = 1;
  x.d = simulator::simulate(x.cfg);
  x.r = run_offline(x.d, default_params(x.d));
  return x;
}

// The truth at t_s (rows in time order, asked in time order), interpolated exactly anywhere.
class TruthCursor {
 public:
  explicit TruthCursor(const Dataset& d) : tr_(d.truth) {}
  std::optional<TruthSample> at(double t_s) {
    if (tr_.empty() || t_s < tr_.front().t_s || t_s > tr_.back().t_s) return std::nullopt;
    while (i_ + 1 < tr_.size() && tr_[i_ + 1].t_s <= t_s) ++i_;
    const std::size_t j = std::min(i_ + 1, tr_.size() - 1);
    const double f = j == i_ ? 0.0 : (t_s - tr_[i_].t_s) / (tr_[j].t_s - tr_[i_].t_s);
    TruthSample s = f < 0.5 ? tr_[i_] : tr_[j];
    s.position = interpolate_geodetic(tr_[i_].position, tr_[j].position, f);
    return s;
  }

 private:
  const std::vector<TruthSample>& tr_;
  std::size_t i_ = 0;
};

struct Figures {
  double dr_max_m = 0.0, dr_final_m = 0.0, dr_distance_m = 0.0;
  double nav_max_m = 0.0, nav_rms_m = 0.0;  ///< anchored rows after the settle time
  double nav_max_over_sigma = 0.0;          ///< largest error / reported horizontal sigma there
  double gnss_rms_m = 0.0;                  ///< valid fixes against the truth antenna, same span
  double closest_pole_m = 1e30;             ///< of the truth
  std::size_t nav_rows = 0;
};

constexpr double kSettleS = 30.0;  // calibration and identification first; the DR starts at once

Figures figures(const ScenarioRun& x) {
  Figures f;
  const double t0 = x.d.truth.front().t_s;
  TruthCursor truth(x.d);
  for (const dead_reckoning::DeadReckoningOutput& o : x.r.dr_online) {
    const std::optional<TruthSample> t = truth.at(o.t_s);
    if (!t) continue;
    const double e = horizontal_distance_m(o.position, t->position);
    f.dr_max_m = std::max(f.dr_max_m, e);
    f.dr_final_m = e;
    f.dr_distance_m = o.distance_m;
    f.closest_pole_m = std::min(f.closest_pole_m, distance_to_pole_m(t->position));
  }
  TruthCursor truth2(x.d);
  double nav2 = 0.0;
  for (const dead_reckoning::AnchoredPosition& p : x.r.navigation_position) {
    const std::optional<TruthSample> t = truth2.at(p.t_s);
    if (!t || p.t_s - t0 < kSettleS || p.status != dead_reckoning::AnchorStatus::kAnchored) continue;
    const double e = horizontal_distance_m(p.position, t->position);
    f.nav_max_m = std::max(f.nav_max_m, e);
    f.nav_max_over_sigma = std::max(f.nav_max_over_sigma, e / p.horizontal_sigma_m());
    nav2 += e * e;
    ++f.nav_rows;
  }
  f.nav_rms_m = std::sqrt(nav2 / static_cast<double>(std::max<std::size_t>(1, f.nav_rows)));
  TruthCursor truth3(x.d);
  double g2 = 0.0;
  std::size_t m = 0;
  for (const GnssSample& g : x.d.gnss) {
    if (!g.valid() || g.t_s - t0 < kSettleS) continue;
    const std::optional<TruthSample> t = truth3.at(g.t_s);
    if (!t) continue;
    const Geodetic antenna = move_geodetic(t->position, body_to_enu(t->attitude) * x.cfg.lever_arm_m);
    g2 += std::pow(horizontal_distance_m(g.position, antenna), 2);
    ++m;
  }
  f.gnss_rms_m = std::sqrt(g2 / static_cast<double>(std::max<std::size_t>(1, m)));
  std::cout << x.cfg.scenario << ": DR max " << f.dr_max_m << " m, final " << f.dr_final_m << " m after "
            << f.dr_distance_m << " m; anchored max " << f.nav_max_m << " m, RMS " << f.nav_rms_m << " m, max/sigma "
            << f.nav_max_over_sigma << " over " << f.nav_rows << " rows; GNSS RMS " << f.gnss_rms_m
            << " m; truth's closest approach to a pole " << f.closest_pole_m << " m\n";
  return f;
}

// Every row of dead_reckoning.csv and navigation_position.csv, as written: lat in [-90, 90], lon in
// [-180, 180). Returns the smallest and largest longitude written (deg).
std::pair<double, double> expect_rows_in_range(const ScenarioRun& x) {
  const results::OutputRows rows = to_output_rows(x.r, "vff_lm_rls");
  double lo = 1e9, hi = -1e9;
  const auto check = [&](double lat_rad, double lon_rad, double t_s) {
    const double lat = rad_to_deg(lat_rad), lon = rad_to_deg(lon_rad);
    EXPECT_TRUE(lat >= -90.0 && lat <= 90.0) << x.cfg.scenario << " t=" << t_s << " lat " << lat;
    EXPECT_TRUE(lon >= -180.0 && lon < 180.0) << x.cfg.scenario << " t=" << t_s << " lon " << lon;
    lo = std::min(lo, lon);
    hi = std::max(hi, lon);
  };
  EXPECT_FALSE(rows.dead_reckoning.empty());
  EXPECT_EQ(rows.navigation_position.size(), rows.dead_reckoning.size());
  for (const results::DeadReckoningRow& r : rows.dead_reckoning) check(r.lat_rad, r.lon_rad, r.t_s);
  for (const results::NavigationPositionRow& r : rows.navigation_position) check(r.lat_rad, r.lon_rad, r.t_s);
  return {lo, hi};
}

bool has_warning(const ScenarioRun& x, const std::string& code) {
  const RunDiagnosis diagnosis = diagnose_run(x.d, default_params(x.d), x.r);
  return std::any_of(diagnosis.warnings.begin(), diagnosis.warnings.end(),
                     [&](const RunWarning& w) { return w.code == code; });
}

}  // namespace

TEST(AnywhereOnEarth, AntimeridianTerrainDrive) {
  const ScenarioRun x = run("antimeridian");
  const auto [lo, hi] = expect_rows_in_range(x);
  EXPECT_LT(lo, -179.99);  // the ring really lies on both sides of 180
  EXPECT_GT(hi, 179.99);
  const Figures f = figures(x);
  // As on the terrain drive at 52.5 N (same course, K steps, slip and outage): the DR within a few
  // metres over 8 km (a longitude wrapped the wrong way would be kilometres), the anchored position
  // better than the fixes it follows and within 4 of its own sigmas on every row.
  EXPECT_LT(f.dr_max_m, 6.0);
  EXPECT_LT(f.nav_rms_m, f.gnss_rms_m);
  EXPECT_LT(f.nav_max_over_sigma, 4.0);
  // The evaluation (summary.json's figures) across 180: the same maximum as measured here.
  std::vector<TimedPosition> dr, truth;
  std::vector<double> distance;
  for (const dead_reckoning::DeadReckoningOutput& o : x.r.dr_online) {
    dr.push_back({o.t_s, o.position});
    distance.push_back(o.distance_m);
  }
  for (const TruthSample& t : x.d.truth) truth.push_back({t.t_s, t.position});
  const DrEvaluation e = evaluate_dead_reckoning(dr, distance, truth, {});
  EXPECT_NEAR(e.max_error_m, f.dr_max_m, 0.01);
  EXPECT_FALSE(has_warning(x, "near_pole"));
}

TEST(AnywhereOnEarth, StraightPass300mFromTheNorthPole) {
  const ScenarioRun x = run("polar_north");
  const auto [lo, hi] = expect_rows_in_range(x);
  EXPECT_LT(hi - lo, 360.0);
  EXPECT_GT(hi - lo, 150.0);  // the track swings round the pole
  const Figures f = figures(x);
  EXPECT_NEAR(f.closest_pole_m, 300.0, 1.0);
  // 300 m from the pole a metre across the meridian is 3 mrad of north: the DR (north taken where
  // GNSS puts it) stays within a few metres over the 3 km, as on a straight road anywhere; the
  // anchored position better than the fixes and within 4 of its sigmas.
  EXPECT_LT(f.dr_max_m, 6.0);
  EXPECT_LT(f.nav_rms_m, f.gnss_rms_m);
  EXPECT_LT(f.nav_max_over_sigma, 4.0);
  EXPECT_TRUE(has_warning(x, "near_pole"));
}

TEST(AnywhereOnEarth, TraverseArriving50mFromTheSouthPole) {
  const ScenarioRun x = run("south_pole");
  expect_rows_in_range(x);
  const Figures f = figures(x);
  EXPECT_NEAR(f.closest_pole_m, 50.0, 1.0);
  // 50 m from the pole the GNSS error that places north (2 m: 2.3 deg there) turns the DR's steps
  // while it sweeps round the pole, a few metres in all; a DR taking north at its own position
  // turned its error into an angle about the pole and left 100 m off. The anchored position
  // follows the fixes as closely as they are (not better: the DR increments near the pole carry
  // that angle) and within 4 of its sigmas.
  EXPECT_LT(f.dr_max_m, 10.0);
  EXPECT_LT(f.nav_rms_m, 1.2 * f.gnss_rms_m);
  EXPECT_LT(f.nav_max_over_sigma, 4.0);
  EXPECT_TRUE(has_warning(x, "near_pole"));
}

TEST(AnywhereOnEarth, ADriveStartingOnTheNorthPoleItself) {
  // The start fix and the first seconds on latitude 90 exactly (any longitude describes the
  // point): every output finite and in range, and the DR and anchored errors those of a start
  // where north is undefined for the first metres (docs/ALGORITHM.md §4c).
  ScenarioRun x;
  x.cfg = simulator::scenario_config("polar_north");
  x.cfg.seed = 1;
  x.cfg.start = Geodetic{0.5 * kPi, deg_to_rad(30.0), 20.0};
  x.cfg.straight_length_m = 1000.0;
  x.d = simulator::simulate(x.cfg);
  x.r = run_offline(x.d, default_params(x.d));
  expect_rows_in_range(x);
  const Figures f = figures(x);
  EXPECT_LT(f.closest_pole_m, 1e-6);
  // North is taken where GNSS puts the vehicle, 2 m off: over the first metres that is any
  // direction, and the error it leaves grows only with the logarithm of the distance from the
  // pole (2 m x ln(1000 m / 1 m) = 14 m at most), not with the distance.
  EXPECT_LT(f.dr_max_m, 15.0);
  // The anchored position carries the DR's wrong first metres in its increments, and says so in
  // its sigma.
  EXPECT_LT(f.nav_max_over_sigma, 4.0);
  EXPECT_TRUE(has_warning(x, "near_pole"));
}

TEST(AnywhereOnEarth, ADeadReckonerRestoredInThePolarCapContinuesBitForBit) {
  // The north offset of the polar cap (the DR's error at the latest GNSS epoch) is part of the
  // checkpoint: a dead reckoner restored 20 s after passing 50 m from the South Pole continues
  // with exactly the positions of the one that ran on.
  simulator::SimulationConfig cfg = simulator::scenario_config("south_pole");
  const Dataset d = simulator::simulate(cfg);
  dead_reckoning::DeadReckonerParams p;
  p.nominal_k_m_per_pulse = d.meta.k_nominal_m_per_pulse.value_or(0.0125);
  p.lever_arm_body_m = d.meta.gnss_lever_arm_m;
  const double t_save = d.truth.front().t_s + 170.0;
  const auto add_inputs = [&](dead_reckoning::DeadReckoner& dr, bool before_save) {
    const auto wanted = [&](double t_s) { return (t_s <= t_save) == before_save; };
    for (const OdometerSample& s : d.odometer)
      if (wanted(s.t_s)) dr.add_odometer(s);
    for (const InsSample& s : d.ins)
      if (wanted(s.t_s)) dr.add_ins(s);
    for (const GnssSample& s : d.gnss)
      if (wanted(s.t_s)) dr.add_gnss(s);
  };
  dead_reckoning::DeadReckoner ran_on(p);
  add_inputs(ran_on, true);
  ran_on.process_until(t_save);
  const StateJson state = ran_on.save_state();
  EXPECT_EQ(state.at("heading_position_offset_enu_m").size(), 3u);
  dead_reckoning::DeadReckoner restored(p);
  restored.restore_state(state);
  add_inputs(ran_on, false);
  add_inputs(restored, false);
  const std::vector<dead_reckoning::DeadReckoningOutput> a = ran_on.finish(), b = restored.finish();
  ASSERT_EQ(a.size(), b.size());
  ASSERT_GT(a.size(), 10000u);
  for (std::size_t i = 0; i < a.size(); ++i) {
    ASSERT_EQ(a[i].position.lat_rad, b[i].position.lat_rad) << a[i].t_s;
    ASSERT_EQ(a[i].position.lon_rad, b[i].position.lon_rad) << a[i].t_s;
  }
}
