// The dead-reckoning component's estimate rules, and odonav-offline's in-process transport: every
// estimate reaches its consumer before the outputs it applies to, so a run gives exactly the outputs
// of a dead reckoner that was handed every estimate in advance.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <vector>

#include "odonav/simulator/simulator.hpp"
#include "odonav/consumer_rules.hpp"
#include "odonav/dead_reckoning/dead_reckoning_component.hpp"
#include "odonav/wire_time.hpp"
#include "odonav/offline/offline_pipeline.hpp"
#include "offline_test_params.hpp"

using namespace odonav;
using namespace odonav::offline;

namespace {

Dataset short_terrain(double duration_s) {
  simulator::SimulationConfig cfg = simulator::scenario_config("terrain");
  cfg.duration_s = duration_s;
  return simulator::simulate(cfg);
}

template <class F>
void for_each_sensor_sample(const Dataset& d, F&& f) {
  std::size_t o = 0, g = 0, i = 0;
  const double end = INFINITY;
  while (o < d.odometer.size() || g < d.gnss.size() || i < d.ins.size()) {
    const double to = o < d.odometer.size() ? d.odometer[o].t_s : end;
    const double tg = g < d.gnss.size() ? d.gnss[g].t_s : end;
    const double ti = i < d.ins.size() ? d.ins[i].t_s : end;
    if (tg <= ti && tg <= to)
      f(d.gnss[g++]);
    else if (ti <= to)
      f(d.ins[i++]);
    else
      f(d.odometer[o++]);
  }
}

struct Feeder {
  dead_reckoning::DeadReckoningComponent& c;
  void operator()(const OdometerSample& s) { c.add_odometer(s); }
  void operator()(const GnssSample& s) { c.add_gnss(s); }
  void operator()(const InsSample& s) { c.add_ins(s); }
};

// The same, with each stamp as the pipeline's nodes (and OfflinePipeline) read it from the
// gateway's message: rounded to the nanosecond.
struct WireFeeder {
  dead_reckoning::DeadReckoningComponent& c;
  template <class Sample>
  static Sample wired(Sample s) {
    s.t_s = wire_time_s(s.t_s);
    return s;
  }
  void operator()(const OdometerSample& s) { c.add_odometer(wired(s)); }
  void operator()(const GnssSample& s) { c.add_gnss(wired(s)); }
  void operator()(const InsSample& s) { c.add_ins(wired(s)); }
};

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

}  // namespace

TEST(DeadReckoningComponent, AKAppliesFromItsEpochPlusTheHoldOffAndAProvisionalOneOnFewSamplesNever) {
  const Dataset d = short_terrain(40.0);
  const OfflineParams params = test::user_params(d);
  dead_reckoning::DeadReckoningComponent c(params.dead_reckoning, params.anchored);
  const double nominal = params.dead_reckoning.nominal_k_m_per_pulse;
  for_each_sensor_sample(d, Feeder{c});
  PublishedScaleFactor provisional;  // far from the nominal, but on 2 samples: not applicable
  provisional.t_s = 10.0;
  provisional.k_m_per_pulse = 2.0 * nominal;
  provisional.sigma_m_per_pulse = 1e-6;
  provisional.samples_accepted = 2;
  provisional.source = "identification";
  c.on_scale_factor(provisional, 0.0);
  PublishedScaleFactor converged = provisional;
  converged.t_s = 20.0;
  converged.k_m_per_pulse = 1.02 * nominal;
  converged.converged = true;
  converged.samples_accepted = 150;
  c.on_scale_factor(converged, 0.0);
  const double from_s = estimate_applies_from_s(20.0, params.dead_reckoning.estimate_hold_off_s);
  std::size_t before = 0, after = 0;
  for (const dead_reckoning::DeadReckoningOutput& o : c.finish()) {
    const dead_reckoning::DeadReckoningStep s = c.publish(o);
    if (s.output.t_s < from_s) {
      EXPECT_EQ(s.output.k_m_per_pulse, nominal) << s.output.t_s;
      EXPECT_EQ(s.output.k_source, dead_reckoning::ScaleFactorSource::kNominal);
      ++before;
    } else {
      EXPECT_EQ(s.output.k_m_per_pulse, 1.02 * nominal) << s.output.t_s;
      EXPECT_EQ(s.output.k_source, dead_reckoning::ScaleFactorSource::kIdentified);
      ++after;
    }
  }
  EXPECT_GT(before, 500u);
  EXPECT_GT(after, 500u);
  EXPECT_EQ(c.k_selection().counters().k_applied, 1u);
}

TEST(DeadReckoningComponent, OnlyAnApplicableMisalignmentIsAppliedAndEachOutputNamesTheOneInForce) {
  const Dataset d = short_terrain(30.0);
  const OfflineParams params = test::user_params(d);
  dead_reckoning::DeadReckoningComponent c(params.dead_reckoning, params.anchored);
  for_each_sensor_sample(d, Feeder{c});
  PublishedMisalignment early;  // 3 epochs, not converged: under kProvisionalMinSamples
  early.t_s = 5.0;
  early.heading_rad = 0.02;
  early.heading_std_rad = 1e-4;
  early.pitch_std_rad = 1e-4;
  early.samples_used = 3;
  c.on_misalignment(early);
  EXPECT_EQ(c.consumer().misalignments_applied, 0u);
  PublishedMisalignment good = early;
  good.t_s = 15.0;
  good.heading_rad = 0.014;
  good.pitch_rad = -0.009;
  good.converged = true;
  good.samples_used = 120;
  c.on_misalignment(good);
  EXPECT_EQ(c.consumer().misalignments_applied, 1u);
  const double from_s = estimate_applies_from_s(15.0, params.dead_reckoning.estimate_hold_off_s);
  for (const dead_reckoning::DeadReckoningOutput& o : c.finish()) {
    const dead_reckoning::DeadReckoningStep s = c.publish(o);
    EXPECT_EQ(s.misalignment.heading_rad, s.output.t_s < from_s ? 0.0 : 0.014) << s.output.t_s;
    EXPECT_EQ(s.misalignment.pitch_rad, s.output.t_s < from_s ? 0.0 : -0.009) << s.output.t_s;
  }
}

// What the in-process transport must guarantee, checked against an oracle: a dead reckoner given
// every estimate of the run before it computes anything. A scale factor or misalignment delivered
// after an output it applies to would change that output's K, misalignment or error.
TEST(OfflinePipeline, EveryEstimateArrivesBeforeTheOutputsItAppliesToSoTheRunEqualsOneWithEveryEstimateKnown) {
  const Dataset d = short_terrain(150.0);
  OfflineParams params = test::user_params(d);
  PipelineConfig config;
  config.calibration = params.calibration;
  config.identification = params.identification;
  config.dead_reckoning = params.dead_reckoning;
  config.anchored = params.anchored;

  struct Recorder : PipelineSink {
    std::vector<calibration::MisalignmentOutput> misalignment;
    std::vector<identification::IdentificationOutput> scale_factor;
    std::vector<dead_reckoning::DeadReckoningStep> steps;
    // For each step: the estimates delivered before it.
    std::vector<std::size_t> misalignments_before, scale_factors_before;
    void on_misalignment(const calibration::MisalignmentOutput& m) override { misalignment.push_back(m); }
    void on_scale_factor(const identification::IdentificationOutput& k) override { scale_factor.push_back(k); }
    void on_dead_reckoning(dead_reckoning::DeadReckoningStep s) override {
      misalignments_before.push_back(misalignment.size());
      scale_factors_before.push_back(scale_factor.size());
      steps.push_back(std::move(s));
    }
  } run;
  OfflinePipeline pipeline(config, run);
  for_each_sensor_sample(d, [&](const auto& s) {
    using T = std::decay_t<decltype(s)>;
    if constexpr (std::is_same_v<T, OdometerSample>)
      pipeline.add_odometer(s);
    else if constexpr (std::is_same_v<T, GnssSample>)
      pipeline.add_gnss(s);
    else
      pipeline.add_ins(s);
  });
  pipeline.finish();
  ASSERT_GT(run.steps.size(), 10000u);
  ASSERT_GT(run.scale_factor.size(), 1000u);

  // The delivery order: at each output, every estimate applying at or before it was there. And the
  // transport did not hold the whole drive back: outputs came while estimates were still to come.
  const double hold_off_s = params.dead_reckoning.estimate_hold_off_s;
  std::size_t interleaved = 0;
  for (std::size_t i = 0; i < run.steps.size(); ++i) {
    const double t = run.steps[i].output.t_s;
    std::size_t due_k = 0, due_m = 0;
    while (due_k < run.scale_factor.size() && estimate_applies_from_s(run.scale_factor[due_k].t_s, hold_off_s) <= t)
      ++due_k;
    while (due_m < run.misalignment.size() && estimate_applies_from_s(run.misalignment[due_m].t_s, hold_off_s) <= t)
      ++due_m;
    ASSERT_GE(run.scale_factors_before[i], due_k) << "output at t=" << t;
    ASSERT_GE(run.misalignments_before[i], due_m) << "output at t=" << t;
    if (run.scale_factors_before[i] < run.scale_factor.size()) ++interleaved;
  }
  EXPECT_GT(interleaved, run.steps.size() * 9 / 10);

  // The oracle.
  dead_reckoning::DeadReckoningComponent oracle(params.dead_reckoning, params.anchored);
  for_each_sensor_sample(d, WireFeeder{oracle});
  for (const calibration::MisalignmentOutput& m : run.misalignment)
    oracle.on_misalignment(calibration::published_misalignment(m));
  for (const identification::IdentificationOutput& k : run.scale_factor)
    oracle.on_scale_factor(identification::published_scale_factor(k, "identification"), 0.0);
  std::vector<dead_reckoning::DeadReckoningOutput> expected = oracle.finish();
  ASSERT_EQ(expected.size(), run.steps.size());
  std::size_t identified = 0;
  for (std::size_t i = 0; i < expected.size(); ++i) {
    const dead_reckoning::DeadReckoningStep e = oracle.publish(expected[i]);
    const dead_reckoning::DeadReckoningStep& a = run.steps[i];
    ASSERT_TRUE(same_bits(a.output.t_s, e.output.t_s)) << i;
    ASSERT_TRUE(same_bits(a.output.position.lat_rad, e.output.position.lat_rad)) << a.output.t_s;
    ASSERT_TRUE(same_bits(a.output.position.lon_rad, e.output.position.lon_rad)) << a.output.t_s;
    ASSERT_TRUE(same_bits(a.output.k_m_per_pulse, e.output.k_m_per_pulse)) << a.output.t_s;
    ASSERT_TRUE(same_bits(a.output.horizontal_error_m, e.output.horizontal_error_m) ||
                (std::isnan(a.output.horizontal_error_m) && std::isnan(e.output.horizontal_error_m)))
        << a.output.t_s;
    ASSERT_TRUE(same_bits(a.misalignment.heading_rad, e.misalignment.heading_rad)) << a.output.t_s;
    ASSERT_TRUE(same_bits(a.navigation.position.lat_rad, e.navigation.position.lat_rad)) << a.output.t_s;
    if (a.output.k_source == dead_reckoning::ScaleFactorSource::kIdentified) ++identified;
  }
  EXPECT_GT(identified, expected.size() / 2);  // the identified K was in force for most of the drive
}
