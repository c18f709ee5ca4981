// Real-sensor conditions with the default settings, against the simulator's truth: 1 Hz GNSS, GNSS
// latency (estimated online), the slow reversing robot without INS; and the real smartLoc drive.
// Parameters come from identification_params_for with no options, as odonav-offline builds them.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "odonav/simulator/simulator.hpp"
#include "odonav/offline/first_metres.hpp"
#include "odonav/config.hpp"
#include "odonav/dataset.hpp"
#include "odonav/identification/identification_options.hpp"
#include "odonav/offline/offline_runner.hpp"
#include "offline_test_params.hpp"
#include "smartloc_k.hpp"
#include "odonav/offline/summary.hpp"

using namespace odonav;
using namespace odonav::offline;
using namespace odonav::offline::test;
using nlohmann::json;

namespace {

Dataset scenario(const std::string& name, double gnss_rate_hz = 0.0, double latency_s = 0.0, uint64_t seed = 1) {
  simulator::SimulationConfig cfg = simulator::scenario_config(name);
  cfg.seed = seed;
  if (gnss_rate_hz > 0.0) cfg.gnss_rate_hz = gnss_rate_hz;
  cfg.gnss_latency_s = latency_s;
  return simulator::simulate(cfg);
}

double vff_rms_percent(const json& s) {
  return s["scale_factor"]["estimators"]["vff_lm_rls"]["rms_rel_error_percent"].get<double>();
}

// VFF-LM-RLS's RMS and final K error against the truth both within bound_percent.
void expect_k_within(const Dataset& d, const OfflineResult& r, const OfflineParams& p, double bound_percent) {
  const json s = summarize(d, r, p);
  SCOPED_TRACE(s["scale_factor"].dump(1));
  const json& vff = s["scale_factor"]["estimators"]["vff_lm_rls"];
  EXPECT_LE(vff["rms_rel_error_percent"].get<double>(), bound_percent);
  EXPECT_LE(std::abs(vff["final_rel_error_percent"].get<double>()), bound_percent);
}

}  // namespace

TEST(SensorRates, TerrainAtOneHertzIdentifiesKWithTheDefaults) {
  const Dataset d = scenario("terrain", 1.0);
  const OfflineParams p = user_params(d);
  const OfflineResult r = run_offline(d, p);
  const json s = summarize(d, r, p);
  SCOPED_TRACE(s["scale_factor"].dump(1));
  // Before the gates followed the data, every 1 Hz interval was a "gap" (0 of 799 accepted).
  EXPECT_EQ(r.builder_counters.gap, 0u);
  EXPECT_GT(r.builder_counters.accepted, 500u);
  // The goal, 0.1 %. Measured 0.085 % (10-seed median 0.077 %, docs/DESIGN_DECISIONS.md); 0.125 %
  // before the change detector cut the window back after the K steps and the trapezoid
  // correction's rates followed the pulse quantisation (docs/ALGORITHM.md §2, §3).
  EXPECT_LE(vff_rms_percent(s), 0.1);
  const double final_error = s["scale_factor"]["estimators"]["vff_lm_rls"]["final_rel_error_percent"].get<double>();
  EXPECT_LE(std::abs(final_error), 0.1);
}

TEST(SensorRates, GnssLatencySweepIsEstimatedWithin5msAndKStaysAccurate) {
  const Dataset d0 = scenario("terrain");
  const OfflineParams p0 = user_params(d0);
  const double rms0 = vff_rms_percent(summarize(d0, run_offline(d0, p0), p0));
  EXPECT_LE(rms0, 0.1);
  for (const double latency_s : {0.05, 0.1, 0.2}) {
    const Dataset d = scenario("terrain", 0.0, latency_s);
    const OfflineParams p = user_params(d);
    const OfflineResult r = run_offline(d, p);
    const json s = summarize(d, r, p);
    SCOPED_TRACE(s["scale_factor"].dump(1));
    // Seed 1 is the worst of ten seeds: -3.0 / -3.0 / -3.1 ms at 50 / 100 / 200 ms (docs/DESIGN_DECISIONS.md).
    const GnssLatencyEstimate& l = r.identification.back().latency;
    EXPECT_NEAR(l.applied_s, latency_s, 0.004) << latency_s;
    EXPECT_GT(l.sigma_s, 0.0);
    EXPECT_LT(l.sigma_s, 0.002);
    EXPECT_NEAR(s["scale_factor"]["gnss_latency_error_s"].get<double>(), 0.0, 0.004);
    // Applied early: the first epoch with the latency in force within 10 ms (measured 29.4-29.9 s
    // after the start; 87 s at 100 ms while the sums waited for a K that held still for 20 s).
    double first_applied_s = -1.0;
    for (const identification::IdentificationOutput& o : r.identification)
      if (std::abs(o.latency.applied_s - latency_s) < 0.01) {
        first_applied_s = o.t_s - d.odometer.front().t_s;
        break;
      }
    EXPECT_GT(first_applied_s, 0.0) << latency_s;
    EXPECT_LT(first_applied_s, 40.0) << latency_s;
    // Without the estimate a 0.2 s latency gave 1.1 %; with it, within 10 % of the zero-latency
    // figure (measured 0.058 / 0.057 / 0.056 % against 0.055 %; 0.077 % at 100 ms before the
    // sums had a K of their own).
    EXPECT_LE(vff_rms_percent(s), 1.1 * rms0) << latency_s;
    // Dead reckoning from the start: before any latency is decided, the K published for the
    // accelerating start is the latency search's (SampleBuilder::start_latency_k), not the
    // estimator's, whose samples were off by the latency times their speed change (-9 % to -2 %
    // over the first 30 s at 200 ms). Max %D after 500 m without the start offset, measured 0.073 /
    // 0.320 / 0.418 % (0.273 / 0.548 / 0.913 % before; 0.074 % at zero latency).
    const FirstMetres f = evaluate_first_metres(d, r.dr_online);
    EXPECT_LE(f.drift_max_after_500m_percent, 0.5) << latency_s;
  }
}

TEST(SensorRates, AtOneHertzALatencyIsAppliedWithinTheFirstMinutesAndKKeepsItsZeroLatencyAccuracy) {
  // The minimum of the latency estimate is 20 s of samples, not 200 samples: 20 at 1 Hz. With 200
  // the 100 ms of seed 1 were applied after 307 s and K was 0.179 % RMS; now after 91 s, 0.096 %
  // against 0.085 % without a latency (docs/DESIGN_DECISIONS.md).
  const Dataset d0 = scenario("terrain", 1.0);
  const OfflineParams p0 = user_params(d0);
  const double rms0 = vff_rms_percent(summarize(d0, run_offline(d0, p0), p0));
  const Dataset d = scenario("terrain", 1.0, 0.1);
  const OfflineParams p = user_params(d);
  const OfflineResult r = run_offline(d, p);
  const json s = summarize(d, r, p);
  SCOPED_TRACE(s["scale_factor"].dump(1));
  double first_applied_s = -1.0;
  double first_sigma_s = -1.0;
  for (const identification::IdentificationOutput& o : r.identification)
    if (o.latency.applied_s != 0.0) {
      first_applied_s = o.t_s - d.odometer.front().t_s;
      first_sigma_s = o.latency.applied_sigma_s;
      break;
    }
  EXPECT_GT(first_applied_s, 0.0);
  EXPECT_LT(first_applied_s, 120.0);
  EXPECT_LE(vff_rms_percent(s), 1.2 * rms0);
  // What is applied first at 1 Hz is a coarse estimate (sigma 10-12 ms; 133.7 ms here, the worst of
  // ten seeds). It is refined once a later estimate's sigma is half of it: 114.0 ms at sigma 5.5 ms.
  // Kept until the end, the coarse value was -14 to +34 ms off on the ten seeds, refined -14 to
  // +14 ms (docs/DESIGN_DECISIONS.md). The 10 Hz receiver's latency is within 4 ms (test above).
  const GnssLatencyEstimate& last = r.identification.back().latency;
  EXPECT_GT(first_sigma_s, 0.008);
  EXPECT_GT(last.applied_sigma_s, 0.0);
  EXPECT_LE(last.applied_sigma_s, 0.5 * first_sigma_s);
  EXPECT_NEAR(last.applied_s, 0.1, 0.02);
}

TEST(SensorRates, AtOneHertzWithA200msLatencyTheStartOfTheDriveKeepsTheDeadReckoningWithinTheGoal) {
  // An unknown latency biases the estimator's K low while the vehicle accelerates off (-3.5 % at
  // 14 s on seed 8). Two things keep that out of the DR: the latency search's start K is published
  // at 1 Hz too, and each later estimate of the identification replaces the K in force even when
  // it is within 3 sigma of the nominal. Seed 1: DR final 0.095 %D before both, 0.054 %D with them
  // (ten seeds: median 0.099 -> 0.060 %D, docs/DESIGN_DECISIONS.md).
  const Dataset d = scenario("terrain", 1.0, 0.2);
  const OfflineParams p = user_params(d);
  const OfflineResult r = run_offline(d, p);
  int start_k_epochs = 0;
  for (const identification::IdentificationOutput& o : r.identification)
    start_k_epochs += o.k_from_start_latency ? 1 : 0;
  EXPECT_GT(start_k_epochs, 0);
  const FirstMetres f = evaluate_first_metres(d, r.dr_online);
  SCOPED_TRACE(describe(f));
  EXPECT_LE(f.final_percent, 0.07);
}

TEST(SensorRates, AtOneHertzASidewaysVelocityErrorInTheFirstHalfMinuteCostsTheCalibrationNothing) {
  // Seed 8 at 1 Hz has a GNSS velocity with a sideways error about 25 s in. Had the calibrator's
  // innovation test waited for 20 epochs (the first 20 s at 1 Hz), that epoch moved the heading to
  // -1 deg, the calibration ended the drive 0.031 deg off and still calibrating, and the DR at
  // 0.153 %D; armed after 5 epochs, it rejects the epoch: converged, 0.029 deg, 0.076 %D
  // (docs/DESIGN_DECISIONS.md).
  const Dataset d = scenario("terrain", 1.0, 0.0, 8);
  const OfflineParams p = user_params(d);
  const OfflineResult r = run_offline(d, p);
  ASSERT_FALSE(r.misalignment.empty());
  const calibration::MisalignmentOutput& last = r.misalignment.back();
  EXPECT_TRUE(last.converged);
  EXPECT_GE(r.calibration_counters.outlier, 1u);
  EXPECT_NEAR(rad_to_deg(last.misalignment.heading_rad), *d.meta.truth_misalignment_heading_deg, 0.05);
  // From the start on, not only at the end: every published estimate after the first minute is
  // within 0.25 deg (armed at 20, the estimate at 60 s was not).
  for (const calibration::MisalignmentOutput& m : r.misalignment) {
    if (m.t_s >= d.odometer.front().t_s + 60.0) {
      ASSERT_NEAR(rad_to_deg(m.misalignment.heading_rad), *d.meta.truth_misalignment_heading_deg, 0.25)
          << "t " << m.t_s;
    }
  }
  const FirstMetres f = evaluate_first_metres(d, r.dr_online);
  SCOPED_TRACE(describe(f));
  EXPECT_LE(f.final_percent, 0.1);
}

TEST(SensorRates, SlowReversingRobotWithoutInsGetsKWithin03Percent) {
  const Dataset d = scenario("slow_robot");
  ASSERT_FALSE(d.has_ins());
  const OfflineParams p = user_params(d);
  const OfflineResult r = run_offline(d, p);
  expect_k_within(d, r, p, 0.3);
  // The intervals driven backwards make samples too (direction flag of the odometer, -1 throughout);
  // those in which the direction changes start or end below the minimum speed.
  const SampleBuilderCounters& c = r.builder_counters;
  // Measured on seed 1: 9 samples backwards (reversing at 0.6 m/s for 8 s after every third stop).
  EXPECT_GE(c.reversing_accepted, 5u) << c.accepted;
  EXPECT_GT(c.accepted, 300u);
  // Without them (--no-reversing-samples) each backwards interval is rejected and counted instead.
  OfflineParams off = p;
  off.identification.builder.reversing_samples = false;
  const OfflineResult r_off = run_offline(d, off);
  EXPECT_EQ(r_off.builder_counters.reversing_accepted, 0u);
  EXPECT_GE(r_off.builder_counters.reversing, c.reversing_accepted);
  EXPECT_LE(r_off.builder_counters.accepted + c.reversing_accepted, c.accepted + 2);
}

TEST(SensorRates, SlowReversingRobotWithInsTakesTheBackwardsSamplesRight) {
  // The same robot with an INS: backwards, the forward speed along the odometer axis is negative,
  // and the samples take the distance driven backwards.
  simulator::SimulationConfig cfg = simulator::scenario_config("slow_robot");
  cfg.seed = 1;
  cfg.has_ins = true;
  const Dataset d = simulator::simulate(cfg);
  const OfflineParams p = user_params(d);
  const OfflineResult r = run_offline(d, p);
  expect_k_within(d, r, p, 0.3);
  // Without them each backwards epoch is rejected for its negative speed instead. (Standing still,
  // the speed's noise is negative half of the time while the odometer says forward: those stay
  // rejected either way.)
  OfflineParams off = p;
  off.identification.builder.reversing_samples = false;
  const OfflineResult r_off = run_offline(d, off);
  const SampleBuilderCounters& c = r.builder_counters;
  const SampleBuilderCounters& c_off = r_off.builder_counters;
  EXPECT_GE(c.reversing_accepted, 5u);
  EXPECT_GE(c_off.negative_speed, c.negative_speed + c.reversing_accepted);
  EXPECT_EQ(c_off.reversing_accepted, 0u);
  std::ostringstream counts;
  counts << "on: accepted " << c.accepted << ", reversing_accepted " << c.reversing_accepted << ", negative_speed "
         << c.negative_speed << ", reversing " << c.reversing << "; off: accepted " << c_off.accepted
         << ", negative_speed " << c_off.negative_speed << ", reversing " << c_off.reversing;
  RecordProperty("counts", counts.str());
  // Measured on seed 1: 15 of 423 samples backwards, K RMS 0.137 % (0.139 % without them, 408
  // samples).
}

TEST(SensorRates, DeadReckoningFollowsTheGnssPeriodAtOneHertzAndOnTheSlowRobot) {
  // The DR's GNSS gap (reference, and without INS the course) derives from the observed GNSS period;
  // with a fixed 0.5 s the 1 Hz fixes were never bridged: the slow robot's DR (no INS) did not move
  // (86 %D) and terrain at 1 Hz had no reference between fixes.
  {
    const Dataset d = scenario("slow_robot");
    const OfflineParams p = user_params(d);
    const json s = summarize(d, run_offline(d, p), p);
    SCOPED_TRACE(s["dead_reckoning"].dump(1));
    // Measured 0.114 %D over 782 m with two reversing manoeuvres at 0.6 m/s.
    EXPECT_LE(s["dead_reckoning"]["online_k"]["final_error_percent"].get<double>(), 0.2);
  }
  {
    const Dataset d = scenario("terrain", 1.0);
    const OfflineParams p = user_params(d);
    const json s = summarize(d, run_offline(d, p), p);
    SCOPED_TRACE(s["dead_reckoning"].dump(1));
    // Measured 0.015 %D (0.41 %D before the provisional estimates, the derived gap and the VFF
    // forgetting per second; 0.098 %D with the first two).
    EXPECT_LE(s["dead_reckoning"]["online_k"]["final_error_percent"].get<double>(), 0.15);
  }
}

TEST(SensorRates, SmartLocDriveKWithin03PercentOfTheReferenceRatio) {
  const SmartLocK k = smartloc_k(user_params);
  const double median = k.median_m_per_pulse, k_reference = k.reference_m_per_pulse;
  std::printf("smartLoc: median K %.7f m/pulse, reference %.7f m/pulse, ratio - 1 = %+.3f %%\n", median, k_reference,
              100.0 * (median / k_reference - 1.0));
  expect_smartloc_k_near_reference(k, 0.003);
}
