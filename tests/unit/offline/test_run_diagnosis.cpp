// "Never a silent zero": runs whose main result is missing or degenerate are named with the gate,
// the threshold and the observed value (simulated drives with known causes).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <string>

#include "odonav/simulator/simulator.hpp"
#include "odonav/offline/offline_runner.hpp"
#include "odonav/offline/run_diagnosis.hpp"
#include "odonav/offline/evaluation.hpp"
#include "odonav/offline/summary.hpp"

using namespace odonav;
using namespace odonav::offline;

namespace {

/// The simulator's scenario `name` with this seed and length.
simulator::SimulationConfig scenario(const std::string& name, std::uint64_t seed, double duration_s) {
  simulator::SimulationConfig cfg = simulator::scenario_config(name);
  cfg.seed = seed;
  cfg.duration_s = duration_s;
  return cfg;
}

simulator::SimulationConfig straight(double duration_s = 120.0) { return scenario("straight", 5, duration_s); }

OfflineParams params_for(const Dataset& d) {
  OfflineParams p;
  p.dead_reckoning.nominal_k_m_per_pulse = d.meta.k_nominal_m_per_pulse.value_or(0.0125);
  return p;
}

/// The diagnosis of an offline run of d with params_for(d).
RunDiagnosis diagnosed(const Dataset& d) {
  const OfflineParams p = params_for(d);
  return diagnose_run(d, p, run_offline(d, p));
}

const RunWarning* find(const RunDiagnosis& r, const std::string& code) {
  for (const RunWarning& w : r.warnings)
    if (w.code == code) return &w;
  return nullptr;
}

}  // namespace

TEST(RunDiagnosis, ACleanDriveHasNoWarning) {
  const Dataset d = simulator::simulate(straight());
  const RunDiagnosis r = diagnosed(d);
  EXPECT_TRUE(r.usable);
  for (const RunWarning& w : r.warnings) ADD_FAILURE() << w.code << ": " << w.message;
}

TEST(RunDiagnosis, OneHertzGnssWithTheTenHertzGapGateNamesTheGateThePeriodAndTheFlag) {
  simulator::SimulationConfig cfg = straight();
  cfg.gnss_rate_hz = 1.0;
  const Dataset d = simulator::simulate(cfg);
  OfflineParams p = params_for(d);
  p.identification.builder.max_interval_s = 0.5;  // the 10 Hz setting, given explicitly
  const OfflineResult result = run_offline(d, p);
  const RunDiagnosis r = diagnose_run(d, p, result);
  EXPECT_FALSE(r.usable);
  const RunWarning* w = find(r, "no_k");
  ASSERT_NE(w, nullptr);
  EXPECT_NE(w->message.find("as gaps > 0.5 s (--max-interval-s); the GNSS period is 1 s"), std::string::npos)
      << w->message;
  EXPECT_NE(w->message.find("0 of " + std::to_string(result.builder_counters.epochs)), std::string::npos) << w->message;
}

TEST(RunDiagnosis, AWrongNominalKThatTruncatesTheDeadReckoningIsNamed) {
  const Dataset d = simulator::simulate(straight());
  OfflineParams p = params_for(d);
  p.dead_reckoning.nominal_k_m_per_pulse = 1.0;  // 80x the encoder's: every real increment is a "jump"
  const OfflineResult result = run_offline(d, p);
  const RunDiagnosis r = diagnose_run(d, p, result);
  const RunWarning* w = find(r, "dead_reckoning_truncated");
  if (result.dr_online.empty()) {
    ASSERT_NE(find(r, "no_dead_reckoning"), nullptr);
  } else {
    ASSERT_NE(w, nullptr) << "DR ends at " << result.dr_online.back().t_s;
    EXPECT_NE(w->message.find("pulse-jump gate"), std::string::npos) << w->message;
    EXPECT_NE(w->message.find("--nominal-k"), std::string::npos) << w->message;
  }
}

TEST(RunDiagnosis, NoTimeOverlapIsNamedWithBothSpans) {
  Dataset d = simulator::simulate(straight(60.0));
  for (GnssSample& g : d.gnss) g.t_s += 1e6;  // GNSS in another time base
  const RunDiagnosis r = diagnosed(d);
  EXPECT_FALSE(r.usable);
  const RunWarning* w = find(r, "no_time_overlap");
  ASSERT_NE(w, nullptr);
  EXPECT_NE(w->message.find("do not overlap"), std::string::npos) << w->message;
  EXPECT_NE(w->message.find("1000000"), std::string::npos) << w->message;
}

TEST(RunDiagnosis, NegatedGnssVelocityIsNamed) {
  Dataset d = simulator::simulate(straight(60.0));
  for (GnssSample& g : d.gnss) g.vel_enu_mps = -g.vel_enu_mps;
  const RunDiagnosis r = diagnosed(d);
  EXPECT_FALSE(r.usable);
  const RunWarning* w = find(r, "no_k");
  ASSERT_NE(w, nullptr);
  EXPECT_NE(w->message.find("negative forward speed"), std::string::npos) << w->message;
  const RunWarning* m = find(r, "no_misalignment");
  ASSERT_NE(m, nullptr);
  EXPECT_NE(m->message.find("reversing"), std::string::npos) << m->message;
}

TEST(RunDiagnosis, AKFarFromTheNominalIsCalledImplausible) {
  const Dataset d = simulator::simulate(straight());
  OfflineParams p = params_for(d);
  p.dead_reckoning.nominal_k_m_per_pulse = 0.0125 / 3.6;               // the encoder is said to be 3.6x finer
  p.identification.builder.odometer_jump_gate.k_m_per_pulse = 0.0125;  // gate kept at the real encoder
  p.dead_reckoning.max_speed_mps = 1000.0;
  const RunDiagnosis r = diagnose_run(d, p, run_offline(d, p));
  const RunWarning* w = find(r, "implausible_k");
  ASSERT_NE(w, nullptr);
  EXPECT_NE(w->message.find("x the nominal K"), std::string::npos) << w->message;
}

TEST(RunDiagnosis, MedianPeriodIgnoresOutagesAndJitter) {
  EXPECT_NEAR(median_period_s({0.0, 1.0, 2.0, 3.01, 4.0, 100.0, 101.0}), 1.0, 0.02);
  EXPECT_TRUE(std::isnan(median_period_s({5.0})));
}

// The consistency monitor on the terrain course (turns, a K step, GNSS outliers and an outage): a
// good drive raises nothing; an INS heading of the other sign convention, or in radians, is named
// with its numbers, withdraws converged, and every output is still produced.
namespace {
simulator::SimulationConfig terrain(double duration_s = 300.0) { return scenario("terrain", 2, duration_s); }
}  // namespace

TEST(Consistency, AGoodTerrainDriveRaisesNothing) {
  for (const double rate_hz : {10.0, 1.0}) {
    simulator::SimulationConfig cfg = terrain();
    cfg.gnss_rate_hz = rate_hz;
    const Dataset d = simulator::simulate(cfg);
    const OfflineParams p = params_for(d);
    const OfflineResult result = run_offline(d, p);
    ASSERT_EQ(result.consistency.size(), 3u);
    for (const dead_reckoning::ConsistencyState& s : result.consistency)
      EXPECT_EQ(s.times_raised, 0u) << rate_hz << " Hz: " << s.text;
    // The heading-rate check did decide (the course turned enough): its ratio is about 1.
    EXPECT_NEAR(result.consistency[0].last_value, 1.0, 0.1) << rate_hz;
    EXPECT_NEAR(result.consistency[2].last_value, 1.0, 0.05) << rate_hz;
    const RunDiagnosis r = diagnose_run(d, p, result);
    for (const RunWarning& w : r.warnings) EXPECT_EQ(w.code.rfind("inconsistent_", 0), std::string::npos) << w.message;
  }
}

TEST(Consistency, AHeadingOfTheOtherSignOrInRadiansIsNamedAndConvergedWithdrawn) {
  const Dataset good = simulator::simulate(terrain());
  const OfflineParams p = params_for(good);
  const std::size_t good_outputs = run_offline(good, p).dr_online.size();
  struct Case {
    const char* name;
    double (*heading)(double);
    const char* words;
  };
  const Case cases[] = {
      {"negated", [](double h) { return std::fmod(2.0 * kPi - h, 2.0 * kPi); }, "turns opposite to the GNSS course"},
      {"radians", [](double h) { return deg_to_rad(h); }, "radians?"},
  };
  for (const Case& c : cases) {
    Dataset d = good;
    for (InsSample& s : d.ins) s.attitude.heading_rad = c.heading(s.attitude.heading_rad);
    const OfflineResult result = run_offline(d, p);
    EXPECT_EQ(result.dr_online.size(), good_outputs) << c.name;  // nothing good lost
    const dead_reckoning::ConsistencyState& s =
        result.consistency[static_cast<int>(dead_reckoning::ConsistencyCheck::kHeadingRate)];
    EXPECT_TRUE(s.raised) << c.name;
    EXPECT_NE(s.text.find(c.words), std::string::npos) << c.name << ": " << s.text;
    if (std::string(c.name) == "negated")
      EXPECT_NEAR(s.last_value, -1.0, 0.1);
    else
      EXPECT_NEAR(1.0 / s.last_value, 57.3, 10.0);
    const RunDiagnosis r = diagnose_run(d, p, result);
    const RunWarning* w = find(r, "inconsistent_heading_rate");
    ASSERT_NE(w, nullptr) << c.name;
    EXPECT_NE(w->message.find("converged withdrawn"), std::string::npos) << w->message;
    nlohmann::json summary = {{"misalignment", {{"converged", true}}}, {"scale_factor", {{"converged", true}}}};
    add_consistency(summary, result.consistency);
    EXPECT_FALSE(summary["misalignment"]["converged"].get<bool>()) << c.name;
    EXPECT_NE(summary["misalignment"]["converged_withdrawn"].get<std::string>().find(c.words), std::string::npos);
    EXPECT_TRUE(summary["consistency"]["heading_rate"]["raised"].get<bool>());
  }
}

TEST(Consistency, AGnssFixAThousandKilometresAwayIsCountedReportedAndKeptOutOfTheAnchoredPosition) {
  const Dataset good = simulator::simulate(terrain(120.0));
  const OfflineParams p = params_for(good);
  const OfflineResult good_result = run_offline(good, p);
  EXPECT_EQ(good_result.gnss_jumps.jumps, 0u);
  Dataset d = good;
  GnssSample& g = d.gnss[600];  // t = 60 s
  g.position.lat_rad += 1000e3 / 6371e3;
  const OfflineResult result = run_offline(d, p);
  EXPECT_EQ(result.gnss_jumps.jumps, 1u);
  EXPECT_EQ(result.gnss_jumps.first_t_s, g.t_s);
  EXPECT_NEAR(result.gnss_jumps.largest_m, 1000e3, 1e3);
  const RunDiagnosis r = diagnose_run(d, p, result);
  const RunWarning* w = find(r, "gnss_position_jumps");
  ASSERT_NE(w, nullptr);
  EXPECT_NE(w->message.find("1 GNSS fix jumped away from the track (first at t = 60 s, the largest 1000"),
            std::string::npos)
      << w->message;
  // Nothing good lost: every output, K as without the jump, and the anchored position but for
  // centimetres (its gate refuses the fix; the refusal itself leaves a trace in the filter), far
  // below the GNSS noise.
  ASSERT_EQ(result.navigation_position.size(), good_result.navigation_position.size());
  double worst_m = 0.0;
  for (std::size_t i = 0; i < result.navigation_position.size(); ++i)
    worst_m =
        std::max(worst_m, (result.navigation_position[i].enu_m - good_result.navigation_position[i].enu_m).norm());
  EXPECT_LT(worst_m, 0.2);
  EXPECT_NEAR(result.identification.back().main.k_m_per_pulse, good_result.identification.back().main.k_m_per_pulse,
              1e-4 * good_result.identification.back().main.k_m_per_pulse);
  EXPECT_EQ(result.misalignment.size(), good_result.misalignment.size());
}

TEST(TruthCheck, TheDrivesOwnTruthMatchesAndAnotherPlaceATimeShiftOrNoOverlapIsRefusedByName) {
  const Dataset d = simulator::simulate(terrain(120.0));
  ASSERT_FALSE(d.truth.empty());
  const auto check = [&](const std::vector<TruthSample>& truth) {
    return truth_mismatch(vector_source(d.gnss)(), vector_source(truth)());
  };
  EXPECT_FALSE(check(d.truth));
  std::vector<TruthSample> elsewhere = d.truth, shifted = d.truth, later = d.truth;
  for (TruthSample& t : elsewhere) t.position.lat_rad += deg_to_rad(5.0);
  for (TruthSample& t : shifted) t.t_s += 60.0;
  for (TruthSample& t : later) t.t_s += 1000.0;
  const auto a = check(elsewhere);
  ASSERT_TRUE(a);
  EXPECT_NE(a->find("truth.csv is 55"), std::string::npos) << *a;  // 5 deg of latitude: 556 km
  EXPECT_NE(a->find(" km from the GNSS fixes (median of 20 moving fixes"), std::string::npos) << *a;
  const auto b = check(shifted);
  ASSERT_TRUE(b);
  EXPECT_NE(b->find("shifted in time?"), std::string::npos) << *b;
  const auto c = check(later);
  ASSERT_TRUE(c);
  EXPECT_NE(c->find("does not overlap the valid GNSS fixes in time"), std::string::npos) << *c;
}

TEST(RunDiagnosis, AShortOneHertzDriveSaysTheMisalignmentDidNotConvergeAndWhatIsMissing) {
  simulator::SimulationConfig cfg = straight(80.0);
  cfg.gnss_rate_hz = 1.0;
  const Dataset d = simulator::simulate(cfg);
  OfflineParams p = params_for(d);
  p.identification.builder.max_interval_s = 1.5;
  const OfflineResult result = run_offline(d, p);
  ASSERT_FALSE(result.misalignment.empty());
  ASSERT_FALSE(result.misalignment.back().converged);
  // The calibration's own reason (the node's Health detail) names the same numbers.
  EXPECT_NE(result.misalignment.back().reason.find(" GNSS epochs used (straight, above 3 m/s), 100 needed"),
            std::string::npos)
      << result.misalignment.back().reason;
  const RunDiagnosis r = diagnose_run(d, p, result);
  const RunWarning* w = find(r, "misalignment_not_converged");
  ASSERT_NE(w, nullptr);
  EXPECT_NE(
      w->message.find("GNSS epochs used while moving (straight, above 3 m/s) of the 100 required (--cal-min-samples)"),
      std::string::npos)
      << w->message;
  // The same drive for 120 s at 10 Hz converges: no such warning.
  const Dataset ok = simulator::simulate(straight(120.0));
  EXPECT_EQ(find(diagnosed(ok), "misalignment_not_converged"), nullptr);
}

TEST(RunDiagnosis, AShortOneHertzDriveSaysKDidNotConvergeAndWhatIsMissing) {
  simulator::SimulationConfig cfg = straight(20.0);  // 15 s of driving after the 5 s standstill
  cfg.gnss_rate_hz = 1.0;
  const Dataset d = simulator::simulate(cfg);
  const OfflineParams p = params_for(d);
  const OfflineResult result = run_offline(d, p);
  ASSERT_FALSE(result.identification.empty());
  ASSERT_TRUE(result.identification.back().main.valid);
  ASSERT_FALSE(result.identification.back().main.converged);
  const RunDiagnosis r = diagnose_run(d, p, result);
  const RunWarning* w = find(r, "k_not_converged");
  ASSERT_NE(w, nullptr);
  // "K did not converge: sigma 0.144 % of K, 0.1 % needed (--converged-rel-sigma) (14 of 21 GNSS
  // epochs accepted); the last K 0.0126892 m/pulse is provisional"
  EXPECT_NE(w->message.find("K did not converge: sigma "), std::string::npos) << w->message;
  EXPECT_NE(w->message.find(" % of K, 0.1 % needed (--converged-rel-sigma)"), std::string::npos) << w->message;
  EXPECT_NE(w->message.find("GNSS epochs accepted); the last K "), std::string::npos) << w->message;
  // The 120 s drive at 10 Hz converges: no such warning (ACleanDriveHasNoWarning).
}

TEST(RunDiagnosis, AShortDriveSaysTheGnssLatencyWasNeverDecidedAndWhy) {
  simulator::SimulationConfig cfg = straight(20.0);
  cfg.gnss_rate_hz = 1.0;
  const Dataset d = simulator::simulate(cfg);
  OfflineParams p = params_for(d);
  const OfflineResult result = run_offline(d, p);
  for (const identification::IdentificationOutput& o : result.identification) {
    EXPECT_FALSE(o.latency_decided) << o.t_s;
    EXPECT_FALSE(o.main.converged) << o.t_s;
  }
  const RunDiagnosis r = diagnose_run(d, p, result);
  const RunWarning* w = find(r, "latency_not_decided");
  ASSERT_NE(w, nullptr);
  // "the GNSS latency was never decided: no estimate: too few samples (13 of 20); K was never
  // published as converged and its sigma includes the latency's uncertainty (give --gnss-latency-s
  // when the receiver's latency is known)"
  EXPECT_NE(w->message.find("the GNSS latency was never decided: no estimate: too few samples ("), std::string::npos)
      << w->message;
  EXPECT_NE(w->message.find("(give --gnss-latency-s when the receiver's latency is known)"), std::string::npos)
      << w->message;
  const RunWarning* k = find(r, "k_not_converged");
  ASSERT_NE(k, nullptr);
  EXPECT_NE(k->message.find("the GNSS latency not decided"), std::string::npos) << k->message;
  // A latency given: nothing to decide.
  p.identification.builder.gnss_latency_fixed_s = 0.0;
  EXPECT_EQ(find(diagnose_run(d, p, run_offline(d, p)), "latency_not_decided"), nullptr);
}

// Braking to a standstill at the end of a drive (docs/ALGORITHM.md §2, "Braking to a standstill"):
// the straight road at 1 Hz GNSS with a 100 ms receiver latency that a 3-minute drive cannot decide
// yet, braking at 1.5 m/s^2 and standing 20 s. Every braking sample reads K high by the latency
// times its deceleration over its speed, and the change detector takes the run of such residuals
// for a change of K: without the rule the stop moved K by +1.4 %. With it, K and the misalignment
// leave the stop as they entered the braking.
TEST(BrakingStop, AStopAtTheEndOfADriveLeavesKAndTheMisalignmentAsBeforeTheBraking) {
  simulator::SimulationConfig cfg = simulator::scenario_config("straight");
  cfg.seed = 1;
  cfg.gnss_rate_hz = 1.0;
  cfg.gnss_latency_s = 0.1;
  cfg.standstill_end_s = 20.0;
  const Dataset d = simulator::simulate(cfg);
  // The braking starts where the true distance per truth row starts to fall for good.
  std::size_t stop = d.truth.size() - 1;
  while (stop > 0 && d.truth[stop].distance_m - d.truth[stop - 1].distance_m < 1e-6) --stop;
  std::size_t brake = stop;
  while (brake > 1 && d.truth[brake].distance_m - d.truth[brake - 1].distance_m <=
                          d.truth[brake - 1].distance_m - d.truth[brake - 2].distance_m + 1e-9)
    --brake;
  const double brake_t = d.truth[brake].t_s;
  ASSERT_GT(d.truth.back().t_s - d.truth[stop].t_s, 19.0);
  const double k_true = cfg.k_true_m_per_pulse;
  auto k_before = [&](const OfflineResult& r) {
    double k = std::nan("");
    for (const identification::IdentificationOutput& o : r.identification)
      if (o.t_s < brake_t - 0.5 && o.main.valid) k = o.main.k_m_per_pulse;
    return k;
  };
  auto mis_before = [&](const OfflineResult& r) {
    Misalignment m;
    for (const calibration::MisalignmentOutput& o : r.misalignment)
      if (o.t_s < brake_t - 0.5) m = o.misalignment;
    return m;
  };

  OfflineParams off = params_for(d);
  off.identification.braking_stop.enabled = false;
  off.calibration.braking_stop.enabled = false;
  const OfflineResult without = run_offline(d, off);
  const double k_end_without = without.identification.back().main.k_m_per_pulse;
  EXPECT_GT(k_end_without / k_before(without) - 1.0, 0.01);  // the defect the rule removes

  const OfflineParams p = params_for(d);
  const OfflineResult with = run_offline(d, p);
  const double kb = k_before(with), ke = with.identification.back().main.k_m_per_pulse;
  EXPECT_NEAR(ke / kb - 1.0, 0.0, 0.001) << "K before the braking " << kb << ", at the end " << ke;
  EXPECT_NEAR(ke / k_true - 1.0, 0.0, 0.002) << ke;
  EXPECT_EQ(with.identification.back().braking_stop.stops, 1u);
  EXPECT_GE(with.identification.back().braking_stop.samples_withdrawn, 4u);
  EXPECT_EQ(with.identification.back().motion_phase, MotionPhase::kStandstill);

  // The misalignment: against its value before the braking and against the truth (the heading
  // estimate holds the INS heading bias, 0.02 deg, docs/ALGORITHM.md §1 "Caveat").
  const Misalignment mb = mis_before(with), me = with.misalignment.back().misalignment;
  EXPECT_NEAR(rad_to_deg(me.heading_rad - mb.heading_rad), 0.0, 0.01);
  EXPECT_NEAR(rad_to_deg(me.pitch_rad - mb.pitch_rad), 0.0, 0.01);
  EXPECT_NEAR(rad_to_deg(me.heading_rad - cfg.misalignment.heading_rad - cfg.ins_heading_bias_rad), 0.0, 0.05);
  EXPECT_NEAR(rad_to_deg(me.pitch_rad - cfg.misalignment.pitch_rad), 0.0, 0.05);
  EXPECT_EQ(with.calibration_counters.braking_stops, 1u);
  EXPECT_GE(with.calibration_counters.braking_withdrawn, 3u);
}
