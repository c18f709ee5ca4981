// Sigma coverage (coverage.hpp): the arithmetic on synthetic errors with exact expected fractions,
// and which reference each published quantity is compared with.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "odonav/simulator/simulator.hpp"
#include "odonav/offline/coverage.hpp"
#include "odonav/offline/offline_runner.hpp"
#include "offline_test_params.hpp"
#include "odonav/frames.hpp"
#include "odonav/geodesy.hpp"

namespace odonav::offline {
namespace {

const QuantityCoverage& find(const std::vector<QuantityCoverage>& all, const std::string& quantity) {
  for (const QuantityCoverage& q : all)
    if (q.quantity == quantity) return q;
  ADD_FAILURE() << "no quantity " << quantity;
  static const QuantityCoverage none;
  return none;
}

/// n, then the counts within 1, 2 and 3 sigma.
std::array<std::size_t, 4> counts(const Coverage& c) {
  return {c.n, c.within_1_sigma, c.within_2_sigma, c.within_3_sigma};
}
using Counts = std::array<std::size_t, 4>;

TEST(Coverage, CountsWithinOneTwoThreeSigmaAndTheMeanNees) {
  Coverage c;
  // |z| = 0.5, 1 (on the bound: within), 1.5, 2.5, 3, 4: sigmas of 2 m, errors of either sign.
  for (const double error_m : {1.0, -2.0, 3.0, -5.0, 6.0, 8.0}) c.add(error_m, 2.0);
  EXPECT_EQ(counts(c), (Counts{6, 2, 3, 5}));
  EXPECT_DOUBLE_EQ(c.fraction_within(1), 2.0 / 6.0);
  EXPECT_DOUBLE_EQ(c.fraction_within(2), 3.0 / 6.0);
  EXPECT_DOUBLE_EQ(c.fraction_within(3), 5.0 / 6.0);
  EXPECT_DOUBLE_EQ(c.mean_nees(), (0.25 + 1.0 + 2.25 + 6.25 + 9.0 + 16.0) / 6.0);
  EXPECT_DOUBLE_EQ(c.max_abs_z, 4.0);
}

TEST(Coverage, AZeroSigmaClaimsAnExactValueAndNoSigmaIsNoClaim) {
  Coverage c;
  c.add(0.0, 0.0);                                       // exact and right: z = 0
  c.add(1e-9, 0.0);                                      // exact and wrong: outside every bound
  c.add(1.0, std::numeric_limits<double>::quiet_NaN());  // no sigma: not counted
  c.add(1.0, -1.0);
  c.add(std::numeric_limits<double>::infinity(), 1.0);
  EXPECT_EQ(counts(c), (Counts{2, 1, 1, 1}));
  EXPECT_TRUE(std::isinf(c.mean_nees()));
  EXPECT_TRUE(std::isnan(Coverage{}.fraction_within(2)));
  EXPECT_TRUE(std::isnan(Coverage{}.mean_nees()));
}

TEST(Coverage, MergeAddsTheCounts) {
  Coverage a, b;
  a.add(0.5, 1.0);
  b.add(2.5, 1.0);
  b.add(-3.5, 1.0);
  a.merge(b);
  EXPECT_EQ(counts(a), (Counts{3, 1, 1, 2}));
  EXPECT_DOUBLE_EQ(a.mean_nees(), (0.25 + 6.25 + 12.25) / 3.0);
  EXPECT_DOUBLE_EQ(a.max_abs_z, 3.5);
}

// A simulated dataset in miniature: truth with a K step at 5 s, the true misalignment, a simulated
// INS heading bias and GNSS latency; and outputs whose errors are known multiples of their sigmas.
TEST(Coverage, EachQuantityAgainstItsReference) {
  Dataset d;
  const Geodetic origin{deg_to_rad(52.5), deg_to_rad(13.4), 80.0};
  const LocalEnuFrame frame(origin);
  for (int i = 0; i <= 100; ++i) {
    TruthSample t;
    t.t_s = 0.1 * i;
    t.position = frame.to_geodetic(Eigen::Vector3d(2.0 * t.t_s, 0.0, 0.0));
    t.k_true_m_per_pulse = t.t_s < 5.0 ? 0.0125 : 0.0125 * 1.03;
    d.truth.push_back(t);
  }
  d.meta.truth_misalignment_heading_deg = 0.8;
  d.meta.truth_misalignment_pitch_deg = -0.5;
  d.meta.raw_json = nlohmann::json{{"simulation", {{"ins_heading_bias_deg", 0.2}, {"gnss_latency_s", 0.1}}}}.dump();

  results::OutputRows rows;
  // K: no sigma yet (not counted), then |z| 0.5 (converged), 2.5 against the K before the step,
  // 1.5 against the K after it (converged).
  const auto k_row = [&](double t_s, double k, std::optional<double> sigma, bool converged, double latency_s,
                         std::optional<double> latency_sigma_s) {
    results::ScaleFactorRow r;
    r.t_s = t_s;
    r.k_m_per_pulse = k;
    r.sigma_m_per_pulse = sigma;
    r.converged = converged;
    r.gnss_latency_s = latency_s;
    r.gnss_latency_sigma_s = latency_sigma_s;
    rows.scale_factor.push_back(r);
  };
  k_row(1.0, 0.02, std::nullopt, false, 0.0, std::nullopt);
  k_row(2.0, 0.0125 + 0.5e-5, 1e-5, true, 0.0, 0.01);                 // latency |z| 10, K converged
  k_row(3.0, 0.0125 - 2.5e-5, 1e-5, false, 0.1 + 0.005, 0.01);        // latency |z| 0.5
  k_row(6.0, 0.0125 * 1.03 + 1.5e-5, 1e-5, true, 0.1 - 0.025, 0.01);  // latency |z| 2.5, K converged
  // Misalignment: heading against 0.8 + 0.2 deg, pitch against -0.5 deg.
  const auto m_row = [&](double t_s, double heading_deg, double pitch_deg, double std_deg, bool converged) {
    results::MisalignmentRow r;
    r.t_s = t_s;
    r.heading_rad = deg_to_rad(heading_deg);
    r.pitch_rad = deg_to_rad(pitch_deg);
    r.heading_std_rad = r.pitch_std_rad = deg_to_rad(std_deg);
    r.converged = converged;
    rows.misalignment.push_back(r);
  };
  m_row(1.0, 0.0, 0.0, std::numeric_limits<double>::quiet_NaN(), false);  // no sigma yet
  m_row(2.0, 1.0 + 0.35, -0.5 - 0.05, 0.1, false);                        // |z| 3.5 and 0.5
  m_row(3.0, 1.0 - 0.15, -0.5 + 0.25, 0.1, true);                         // |z| 1.5 and 2.5
  // Position: not started (no variance), then anchored rows off the truth by 0.5 / -1.5 / 2.5
  // sigmas (east / north / up; sigma 2 m), one bridging row at |z| 0.5 on every axis.
  const auto nav_row = [&](double t_s, const Eigen::Vector3d& error_m, double var_m2, const char* status) {
    results::NavigationPositionRow r;
    r.t_s = t_s;
    const Geodetic p = frame.to_geodetic(Eigen::Vector3d(2.0 * t_s, 0.0, 0.0) + error_m);
    r.lat_rad = p.lat_rad;
    r.lon_rad = p.lon_rad;
    r.height_m = p.height_m;
    r.var_east_m2 = r.var_north_m2 = r.var_up_m2 = var_m2;
    r.status = status;
    rows.navigation_position.push_back(r);
  };
  nav_row(0.5, Eigen::Vector3d(9.0, 9.0, 9.0), std::numeric_limits<double>::quiet_NaN(), "not_started");
  nav_row(1.0, Eigen::Vector3d(1.0, -3.0, 5.0), 4.0, "anchored");
  nav_row(1.05, Eigen::Vector3d(1.0, -3.0, 5.0), 4.0, "anchored");  // between two truth rows
  nav_row(2.0, Eigen::Vector3d(-1.0, 1.0, -1.0), 4.0, "dead_reckoning");

  const std::vector<QuantityCoverage> all = evaluate_coverage(d, rows);
  ASSERT_EQ(all.size(), 7u);

  const QuantityCoverage& k = find(all, "K");
  EXPECT_EQ(counts(k.all), (Counts{3, 1, 2, 3}));
  EXPECT_EQ(counts(k.converged), (Counts{2, 1, 2, 2}));

  const QuantityCoverage& heading = find(all, "misalignment heading");
  EXPECT_EQ(counts(heading.all), (Counts{2, 0, 1, 1}));
  EXPECT_EQ(counts(heading.converged), (Counts{1, 0, 1, 1}));
  const QuantityCoverage& pitch = find(all, "misalignment pitch");
  EXPECT_EQ(counts(pitch.all), (Counts{2, 1, 1, 2}));
  EXPECT_EQ(counts(pitch.converged), (Counts{1, 0, 0, 1}));
  EXPECT_NEAR(pitch.all.mean_nees(), (0.25 + 6.25) / 2.0, 1e-9);

  const QuantityCoverage& latency = find(all, "GNSS latency");
  EXPECT_EQ(counts(latency.all), (Counts{3, 1, 1, 2}));
  EXPECT_EQ(counts(latency.converged), (Counts{2, 0, 0, 1}));  // the rows whose K is converged

  const QuantityCoverage& east = find(all, "position east");
  const QuantityCoverage& north = find(all, "position north");
  const QuantityCoverage& up = find(all, "position up");
  // converged: the anchored rows.
  EXPECT_EQ(counts(east.all), (Counts{3, 3, 3, 3}));
  EXPECT_EQ(counts(east.converged), (Counts{2, 2, 2, 2}));
  EXPECT_EQ(counts(north.all), (Counts{3, 1, 3, 3}));
  EXPECT_EQ(counts(north.converged), (Counts{2, 0, 2, 2}));
  EXPECT_EQ(counts(up.all), (Counts{3, 1, 1, 3}));
  EXPECT_EQ(counts(up.converged), (Counts{2, 0, 0, 2}));
  EXPECT_NEAR(up.converged.mean_nees(), 6.25, 1e-6);
}

// A simulation's K timeline comes before truth.csv's k_true, which also holds the turn slip (fewer
// metres per pulse in every turn): the published K is the straight-line K.
TEST(Coverage, KAgainstTheSimulatedTimelineNotTheTurnSlip) {
  Dataset d;
  for (int i = 0; i <= 100; ++i) {
    TruthSample t;
    t.t_s = 0.1 * i;
    const double k_m_per_pulse = t.t_s < 5.0 ? 0.0125 : 0.0125 * 1.03;
    t.k_true_m_per_pulse = t.t_s >= 2.0 && t.t_s < 3.0 ? 0.99 * k_m_per_pulse : k_m_per_pulse;  // a turn
    d.truth.push_back(t);
  }
  d.meta.raw_json = nlohmann::json{{"simulation",
                                    {{"k_true_initial_m_per_pulse", 0.0125},
                                     {"k_steps", {{{"t_s", 5.0}, {"k_before", 0.0125}, {"k_after", 0.0125 * 1.03}}}}}}}
                        .dump();
  results::OutputRows rows;
  for (const auto& [t_s, k] : {std::pair{2.5, 0.0125 + 0.5e-5}, std::pair{6.0, 0.0125 * 1.03 - 0.5e-5}}) {
    results::ScaleFactorRow r;
    r.t_s = t_s;
    r.k_m_per_pulse = k;
    r.sigma_m_per_pulse = 1e-5;
    rows.scale_factor.push_back(r);
  }
  const QuantityCoverage& k = find(evaluate_coverage(d, rows), "K");
  EXPECT_EQ(counts(k.all), (Counts{2, 2, 2, 2}));  // against k_true in the turn, the first would be 13 sigmas off
}

// Without truth.csv, K against the given reference and the position against each fix from the rows
// the fix has not acted on (stamped before its epoch + hold-off), the fix's variance added.
TEST(Coverage, ARecordingWithoutTruthUsesTheKReferenceAndTheFixesNotYetApplied) {
  Dataset d;
  const Geodetic origin{deg_to_rad(52.5), deg_to_rad(13.4), 80.0};
  const LocalEnuFrame frame(origin);
  const auto fix = [&](double t_s, double east_m) {
    GnssSample g;
    g.t_s = t_s;
    g.position = frame.to_geodetic(Eigen::Vector3d(east_m, 0.0, 0.0));
    g.pos_std_m = 1.0;
    g.fix = 1;
    d.gnss.push_back(g);
  };
  fix(0.0, 0.0);
  fix(1.0, 10.0);
  fix(2.0, 20.0);
  results::OutputRows rows;
  const auto nav_row = [&](double t_s, double east_m) {
    results::NavigationPositionRow r;
    r.t_s = t_s;
    const Geodetic p = frame.to_geodetic(Eigen::Vector3d(east_m, 0.0, 0.0));
    r.lat_rad = p.lat_rad;
    r.lon_rad = p.lon_rad;
    r.height_m = p.height_m;
    r.var_east_m2 = r.var_north_m2 = 3.0;  // + the fix's 1 m^2: sigma 2 m
    r.var_up_m2 = 4.0 - 2.25;              // + (1.5 x 1 m)^2
    r.status = "anchored";
    rows.navigation_position.push_back(r);
  };
  nav_row(0.0, 1.0);   // at the first fix: |z| east 0.5
  nav_row(0.9, 12.0);  // with the row at 1.1 brackets the fix at 1.0: east 13 against 10, |z| 1.5
  nav_row(1.1, 14.0);
  nav_row(2.3, 29.0);  // the fix at 2.0 already applies at 2.2: not compared
  results::ScaleFactorRow k;
  k.t_s = 1.0;
  k.k_m_per_pulse = 0.0201;
  k.sigma_m_per_pulse = 0.0002;
  rows.scale_factor.push_back(k);

  CoverageOptions options;
  options.k_reference_m_per_pulse = 0.02;
  const std::vector<QuantityCoverage> all = evaluate_coverage(d, rows, options);
  ASSERT_EQ(all.size(), 4u);  // K and the position; no misalignment or latency reference
  EXPECT_EQ(counts(find(all, "K").all), (Counts{1, 1, 1, 1}));
  const QuantityCoverage& east = find(all, "position east");
  EXPECT_EQ(counts(east.all), (Counts{2, 1, 2, 2}));
  EXPECT_NEAR(east.all.mean_nees(), (0.25 + 2.25) / 2.0, 1e-6);
  EXPECT_EQ(counts(find(all, "position up").all), (Counts{2, 2, 2, 2}));
  EXPECT_NEAR(find(all, "position up").all.max_abs_z, 0.0, 1e-6);
}

// The published sigmas on the simulator, seeds 1-3, run as a user runs odonav-offline: only the
// quantities whose sigmas meet a bound with a clear margin today (odonav-bench-coverage, BENCHMARKS.md
// §11, has every quantity; the misalignment, whose error is one value per drive, needs hundreds of
// drives, and the slow robot's height does not meet one yet).
std::map<std::string, QuantityCoverage> pooled_over_seeds(simulator::SimulationConfig cfg, const std::string& label,
                                                          uint64_t first_seed = 1, uint64_t seeds = 3) {
  std::map<std::string, QuantityCoverage> pooled;
  for (uint64_t seed = first_seed; seed < first_seed + seeds; ++seed) {
    cfg.seed = seed;
    const Dataset d = simulator::simulate(cfg);
    const OfflineParams p = test::user_params(d);
    const OfflineResult r = run_offline(d, p);
    for (const QuantityCoverage& q : evaluate_coverage(d, to_output_rows(r, p.identification.estimator_name))) {
      QuantityCoverage& sum = pooled[q.quantity];
      sum.quantity = q.quantity;
      sum.all.merge(q.all);
      sum.converged.merge(q.converged);
    }
  }
  for (const auto& [name, q] : pooled)
    std::printf("%s %s: n %zu, within 2 / 3 sigma %.1f / %.1f %%, mean NEES %.2f\n", label.c_str(), name.c_str(),
                q.all.n, 100.0 * q.all.fraction_within(2), 100.0 * q.all.fraction_within(3), q.all.mean_nees());
  return pooled;
}
std::map<std::string, QuantityCoverage> pooled_over_seeds(const std::string& scenario_name) {
  return pooled_over_seeds(simulator::scenario_config(scenario_name), scenario_name);
}

TEST(Coverage, PublishedSigmasOnTerrainSeedsOneToThree) {
  const std::map<std::string, QuantityCoverage> c = pooled_over_seeds("terrain");
  // Measured: K 98.0 / 99.4 % within 2 / 3 sigma (96.3 / 97.9 % before K's sigma counted the lag
  // after a change and the latency not yet known; most of the rest are the rows of a K step before
  // its first samples), misalignment heading 98 %, position 96-100 % and 100 % within 3.
  for (const char* name : {"K", "misalignment heading", "position east", "position north", "position up"}) {
    ASSERT_TRUE(c.count(name)) << name;
    const Coverage& q = c.at(name).all;
    EXPECT_GT(q.n, 20000u) << name;
    EXPECT_GE(q.fraction_within(2), 0.90) << name;
  }
  EXPECT_GE(c.at("K").all.fraction_within(2), 0.95);
  EXPECT_GE(c.at("K").all.fraction_within(3), 0.985);
  for (const char* name : {"position east", "position north", "position up"}) {
    EXPECT_GE(c.at(name).all.fraction_within(3), 0.99) << name;
    EXPECT_LT(c.at(name).all.mean_nees(), 1.5) << name;
  }
}

// A receiver 100 ms late: until the latency is decided every accelerating sample reads K low by the
// latency times its speed change, all alike, so the residuals' scatter cannot show it (the first
// estimates were 5-11 % low with a sigma of 0.5 %). K's sigma counts the latency not yet known.
TEST(Coverage, PublishedKSigmaHonestBeforeTheLatencyIsKnown) {
  simulator::SimulationConfig cfg = simulator::scenario_config("terrain");
  cfg.gnss_latency_s = 0.1;
  const std::map<std::string, QuantityCoverage> pooled = pooled_over_seeds(cfg, "terrain, 100 ms");
  const Coverage& k = pooled.at("K").all;
  std::printf("terrain, 100 ms: K n %zu, within 2 / 3 sigma %.1f / %.1f %%\n", k.n, 100.0 * k.fraction_within(2),
              100.0 * k.fraction_within(3));
  // Measured: 97.5 / 99.3 % (93.9 / 96.1 % with the scatter's sigma).
  EXPECT_GT(k.n, 20000u);
  EXPECT_GE(k.fraction_within(2), 0.95);
  EXPECT_GE(k.fraction_within(3), 0.985);
}

TEST(Coverage, PublishedKSigmaOnStraightSeedsOneToThree) {
  const std::map<std::string, QuantityCoverage> c = pooled_over_seeds("straight");
  // Measured: 99 % within 2 sigma, 99.9 % within 3, mean NEES 0.65.
  ASSERT_TRUE(c.count("K"));
  const Coverage& k = c.at("K").all;
  EXPECT_GT(k.n, 5000u);
  EXPECT_GE(k.fraction_within(2), 0.95);
  EXPECT_GE(k.fraction_within(3), 0.99);
  EXPECT_LT(k.mean_nees(), 1.5);
}

// The slow robot (no INS, 2 cm fixes, reversing manoeuvres): the lever arm of each fix is turned by
// the held course, which points backwards while reversing. Taken as the body heading, it put the
// anchored position 2 x 0.1 m off along the track (11 sigmas) for every reversing stretch.
TEST(Coverage, SlowRobotPositionHonestWhileReversing) {
  const std::map<std::string, QuantityCoverage> c = pooled_over_seeds("slow_robot");
  // Measured: east 99.8 / 100 %, north 98.6 / 98.9 % (93 / 94 % before the reversed course was turned).
  for (const char* name : {"position east", "position north"}) {
    ASSERT_TRUE(c.count(name)) << name;
    const Coverage& q = c.at(name).all;
    EXPECT_GT(q.n, 50000u) << name;
    EXPECT_GE(q.fraction_within(2), 0.95) << name;
    EXPECT_GE(q.fraction_within(3), 0.97) << name;
  }
  // K at 1 Hz and 0.3 m/s: neighbouring samples share a GNSS speed, so the residuals move together
  // and the window's scatter alone was optimistic (96.6 % within 2 sigma, mean NEES 1.23); the
  // published sigma counts their correlation (measured 99.9 %, 0.82).
  const Coverage& k = c.at("K").all;
  EXPECT_GT(k.n, 1000u);
  EXPECT_GE(k.fraction_within(2), 0.98);
  EXPECT_LT(k.mean_nees(), 1.1);
}

// The published GNSS latency is the one in force; its sigma is the one it was applied with. The
// online estimate's sigma, published before, described another value: until the first application
// 0 was in force with a sigma of a few ms against a true 100 ms (up to 8 sigmas at 1 Hz).
TEST(Coverage, PublishedGnssLatencySigmaIsTheOneOfTheValueInForce) {
  simulator::SimulationConfig cfg = simulator::scenario_config("terrain");
  cfg.gnss_latency_s = 0.1;
  const std::map<std::string, QuantityCoverage> pooled = pooled_over_seeds(cfg, "terrain, 100 ms");
  const Coverage& latency = pooled.at("GNSS latency").all;
  // Measured: every row within 3 sigmas (largest 2.3); K with it 97.7 % within 2 sigma.
  EXPECT_GT(latency.n, 20000u);
  EXPECT_GE(latency.fraction_within(3), 0.99);
  EXPECT_GE(pooled.at("K").all.fraction_within(2), 0.975);
}

// At 1 Hz the latency's samples are K's, and neighbours share the GNSS speed of their common epoch:
// the latency's least-squares sigma, which takes them as independent, is widened by K's residual
// correlation factor. Twenty drives: one drive's latency error is one slowly varying value, so
// three say little about a sigma.
TEST(Coverage, PublishedGnssLatencySigmaCountsTheResidualsCorrelationAtOneHertz) {
  simulator::SimulationConfig cfg = simulator::scenario_config("terrain");
  cfg.gnss_rate_hz = 1.0;
  cfg.gnss_latency_s = 0.1;
  const std::map<std::string, QuantityCoverage> pooled = pooled_over_seeds(cfg, "terrain, 1 Hz, 100 ms", 101, 20);
  const Coverage& latency = pooled.at("GNSS latency").all;
  // Measured: 94.1 / 100 % within 2 / 3 sigma, mean NEES 1.00 (90.6 / 92.7 %, 1.90 with the plain
  // least-squares sigma); K 96.6 % within 2 sigma.
  EXPECT_GT(latency.n, 10000u);
  EXPECT_GE(latency.fraction_within(2), 0.92);
  EXPECT_GE(latency.fraction_within(3), 0.99);
  EXPECT_LT(latency.mean_nees(), 1.3);
  EXPECT_GE(pooled.at("K").all.fraction_within(2), 0.95);
}

// After an application restarts the latency sums, the first new block is judged against the value
// just applied. Taken on its own, a block that one K cannot describe became the reference, and later,
// correct blocks were left out as inconsistent with it: the online estimate stayed off for minutes,
// and on seed 1072 a wrong 0.186 s was applied at 549 s and kept to the end.
TEST(Coverage, OnlineGnssLatencyIsNotLockedOntoOneBadBlockAfterARestart) {
  simulator::SimulationConfig cfg = simulator::scenario_config("terrain");
  cfg.gnss_rate_hz = 1.0;
  cfg.gnss_latency_s = 0.1;
  for (const uint64_t seed : {1072u, 1170u, 1200u}) {
    cfg.seed = seed;
    const Dataset d = simulator::simulate(cfg);
    const OfflineParams p = test::user_params(d);
    const OfflineResult r = run_offline(d, p);
    Coverage online;
    for (const identification::IdentificationOutput& o : r.identification)
      if (o.latency.sigma_s >= 0.0) online.add(o.latency.estimate_s - cfg.gnss_latency_s, o.latency.sigma_s);
    // The value in force at the drive's end.
    const results::ScaleFactorRow last = to_output_rows(r, p.identification.estimator_name).scale_factor.back();
    ASSERT_TRUE(last.gnss_latency_sigma_s) << seed;
    const double z_end = (last.gnss_latency_s - cfg.gnss_latency_s) / *last.gnss_latency_sigma_s;
    std::printf(
        "seed %llu: online estimate within 3 sigma %.1f %% of %zu; in force at the end %.4f s, %.1f sigma off\n",
        static_cast<unsigned long long>(seed), 100.0 * online.fraction_within(3), online.n, last.gnss_latency_s, z_end);
    // Measured: online 100 / 98.1 / 96.9 % within 3 sigma, in force at the end 0.8 / 0.1 / 1.0 sigma
    // off (45.6 / 82.2 / 83.5 % and 4.6 / 0.1 / 1.0 before).
    EXPECT_GT(online.n, 500u) << seed;
    EXPECT_GE(online.fraction_within(3), 0.95) << seed;
    EXPECT_LT(std::abs(z_end), 3.0) << seed;
  }
}
}  // namespace
}  // namespace odonav::offline
