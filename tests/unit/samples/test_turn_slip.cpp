// Track slip in turns (turn_slip.hpp): the estimator alone on samples of a known slip gain, and the
// sample builder making those samples from a synthetic circle whose odometer slips.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "odonav/checkpoint_file.hpp"
#include "odonav/sample_builder.hpp"
#include "odonav/turn_slip.hpp"
#include "synthetic_drive.hpp"

using namespace odonav;
using namespace odonav::synthetic;

namespace {

constexpr double kK = 0.0125;

// Samples of a 10 Hz receiver in turns of 0.1-0.6 rad/s at 4-10 m/s: the GNSS distance is
// K sum n / (1 + s) exactly (one step per sample), plus velocity noise of sigma_v.
std::vector<TurnSlipSample> turn_samples(double g, double threshold, int n, double sigma_v, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> rate(0.1, 0.6), speed(4.0, 10.0);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::vector<TurnSlipSample> out;
  for (int i = 0; i < n; ++i) {
    const double w = rate(rng), v = speed(rng), dt = 0.1;
    const double s = turn_slip_fraction(g, threshold, w);
    TurnSlipSample t;
    t.t_s = 0.1 * i;
    t.dt_s = dt;
    t.phi_pulses = v * dt * (1.0 + s) / kK;
    t.turn_pulses_radps = t.phi_pulses * std::max(0.0, w - threshold);
    t.k_m_per_pulse = kK;
    t.sigma_y_m = std::sqrt(regression_noise_variance_m2(sigma_v, dt, kK));
    t.y_m = v * dt + sigma_v * dt * noise(rng);
    out.push_back(t);
  }
  return out;
}

}  // namespace

TEST(TurnSlip, FractionIsTheGainTimesTheRateBeyondTheThresholdWithinItsGuards) {
  EXPECT_DOUBLE_EQ(turn_slip_fraction(0.05, 0.05, 0.45), 0.05 * 0.4);
  EXPECT_DOUBLE_EQ(turn_slip_fraction(0.05, 0.05, -0.45), 0.05 * 0.4);  // either direction of turn
  EXPECT_EQ(turn_slip_fraction(0.05, 0.05, 0.04), 0.0);                 // below the yaw-rate gate: inside K
  EXPECT_EQ(turn_slip_fraction(0.05, 0.05, 1e6), 0.5);                  // a wild rate is capped
  EXPECT_EQ(turn_slip_fraction(0.05, 0.05, std::nan("")), 0.0);
  EXPECT_EQ(turn_slip_gain_to_apply(true, 0.05), 0.05);
  EXPECT_EQ(turn_slip_gain_to_apply(false, 0.05), 0.0);
  EXPECT_EQ(turn_slip_gain_to_apply(true, -0.01), 0.0);
}

TEST(TurnSlip, TheGainOfSlippingTurnsIsFoundWithinItsSigmaAndApplies) {
  // 300 samples, noise 0.05 m/s; true g 0.05 s/rad over rates up to 0.6 rad/s (slip up to 2.7 %).
  TurnSlipEstimator e;
  for (const TurnSlipSample& s : turn_samples(0.05, 0.0524, 300, 0.05, 7)) e.update(s);
  const TurnSlipEstimate r = e.estimate();
  ASSERT_TRUE(r.applies) << r.reason;
  EXPECT_EQ(r.samples, 300u);
  EXPECT_GT(r.sigma_s_per_rad, 0.0);
  EXPECT_LT(r.sigma_s_per_rad, 0.005);
  // First-order model against the exact 1 / (1 + s): a bias of about s/2 relative, 1 % of g here.
  EXPECT_NEAR(r.g_s_per_rad, 0.05, 3.0 * r.sigma_s_per_rad + 0.002);
  EXPECT_EQ(r.applied_s_per_rad(), r.g_s_per_rad);
}

TEST(TurnSlip, NoSlipTooFewSamplesOrLessSlipInTurnsIsNotAppliedAndSaysWhy) {
  TurnSlipEstimator none;
  for (const TurnSlipSample& s : turn_samples(0.0, 0.0524, 300, 0.05, 8)) none.update(s);
  const TurnSlipEstimate n = none.estimate();
  EXPECT_FALSE(n.applies);
  EXPECT_LT(std::abs(n.g_s_per_rad), 3.0 * n.sigma_s_per_rad);
  EXPECT_NE(n.reason.find("< 3 sigma"), std::string::npos) << n.reason;
  EXPECT_EQ(n.applied_s_per_rad(), 0.0);

  TurnSlipEstimator few;
  for (const TurnSlipSample& s : turn_samples(0.05, 0.0524, 12, 0.05, 9)) few.update(s);
  EXPECT_FALSE(few.estimate().applies);
  EXPECT_EQ(few.estimate().reason, "12 turn samples < 30");

  // Fewer pulses per metre in turns (what an uncompensated lever arm looks like): never applied.
  TurnSlipEstimator negative;
  std::vector<TurnSlipSample> v = turn_samples(0.05, 0.0524, 300, 0.02, 10);
  for (TurnSlipSample& s : v) s.y_m = 2.0 * kK * s.phi_pulses - s.y_m;  // mirror the residual
  for (const TurnSlipSample& s : v) negative.update(s);
  const TurnSlipEstimate r = negative.estimate();
  EXPECT_LT(r.g_s_per_rad, 0.0);
  EXPECT_FALSE(r.applies);
  EXPECT_NE(r.reason.find("not track slip"), std::string::npos) << r.reason;

  TurnSlipEstimator empty;
  EXPECT_EQ(empty.estimate().reason, "no turn samples yet");
  EXPECT_EQ(empty.estimate().sigma_s_per_rad, -1.0);
}

TEST(TurnSlip, AVelocityOutlierIsDroppedAndCountedNotFitted) {
  TurnSlipEstimator with, without;
  std::vector<TurnSlipSample> v = turn_samples(0.05, 0.0524, 100, 0.05, 11);
  for (const TurnSlipSample& s : v) without.update(s);
  v[50].y_m += 0.5;  // a 5 m/s glitch along the track over 0.1 s
  for (const TurnSlipSample& s : v) with.update(s);
  EXPECT_EQ(with.estimate().outliers, 1u);
  EXPECT_EQ(with.estimate().samples, 99u);
  EXPECT_NEAR(with.estimate().g_s_per_rad, without.estimate().g_s_per_rad, 0.002);
}

TEST(TurnSlip, SaveAndRestoreContinueExactly) {
  const std::vector<TurnSlipSample> v = turn_samples(0.05, 0.0524, 80, 0.05, 12);
  TurnSlipEstimator a, b;
  for (int i = 0; i < 40; ++i) a.update(v[i]);
  b.restore_state(a.save_state());
  for (int i = 40; i < 80; ++i) {
    a.update(v[i]);
    b.update(v[i]);
  }
  EXPECT_EQ(a.estimate().g_s_per_rad, b.estimate().g_s_per_rad);
  EXPECT_EQ(a.estimate().sigma_s_per_rad, b.estimate().sigma_s_per_rad);
  EXPECT_EQ(a.save_state(), b.save_state());
  TurnSlipEstimator c;
  EXPECT_EQ(a.save_state().dump(), b.save_state().dump());
  StateJson not_finite = a.save_state();
  not_finite["shr"] = "nan";
  EXPECT_THROW(c.restore_state(not_finite), CheckpointError);
  StateJson missing = a.save_state();
  missing.erase("samples");
  EXPECT_THROW(c.restore_state(missing), CheckpointError);
  const StateJson untouched = c.save_state();
  try {
    c.restore_state(not_finite);
  } catch (const CheckpointError& e) {
    EXPECT_EQ(std::string(e.what()), "field 'turn_slip.shr' is not finite");
  }
  EXPECT_EQ(c.save_state(), untouched) << "a refused state changes nothing";
}

namespace {

// A 20 m circle at 5 m/s (0.25 rad/s) whose odometer counts 1 + s times the distance, s from the
// model with g = 0.05 s/rad beyond the 3 deg/s yaw-rate gate (about 1 %), through the builder at
// the given GNSS period; returns the slip estimate and checks every turn sample's X on the way.
TurnSlipEstimate circle_slip_estimate(double gnss_period_s, int& turns) {
  const double g = 0.05, threshold = 3.0 * kDegToRad, w = 5.0 / 20.0;
  const double s = turn_slip_fraction(g, threshold, w);
  Trajectory tr = circle(20.0, 5.0, 0.0);
  const auto true_distance = tr.distance_m;
  tr.distance_m = [=](double t) { return true_distance(t) * (1.0 + s); };  // what the odometer counts
  SensorConfig c;
  c.duration_s = 300.0;
  c.k_m_per_pulse = kK;
  c.odometer_period_s = 0.01;
  c.gnss_period_s = gnss_period_s;
  const SyntheticData d = simulate(tr, c);
  SampleBuilder b;
  b.add_scale_factor_estimate(-1.0, kK, 1e-6);  // the K straight driving gave
  add_whole_drive(b, d);
  TurnSlipEstimator e;
  turns = 0;
  for (const SampleBuilderEpoch& ep : b.finish()) {
    EXPECT_FALSE(ep.sample.has_value()) << "a turn of 14 deg/s must not reach K (t=" << ep.t_s << ")";
    if (!ep.turn_sample) continue;
    ++turns;
    EXPECT_EQ(ep.status, EpochStatus::kYawRate);
    const TurnSlipSample& t = *ep.turn_sample;
    // X = pulses times the rate beyond the gate, summed over the interval's 0.1 s steps.
    EXPECT_NEAR(t.turn_pulses_radps, t.phi_pulses * (w - threshold), 1e-3 * t.phi_pulses);
    e.update(t);
  }
  return e.estimate();
}

}  // namespace

TEST(TurnSlip, TheBuilderMeasuresTheSlipOfACircleWhoseOdometerSlipsAtTenAndOneHertz) {
  for (const double period_s : {0.1, 1.0}) {
    SCOPED_TRACE(period_s);
    int turns = 0;
    const TurnSlipEstimate r = circle_slip_estimate(period_s, turns);
    EXPECT_GT(turns, 0.9 * 300.0 / period_s);
    ASSERT_TRUE(r.applies) << r.reason;
    // Pulse quantisation (no velocity noise here) is the only error: g within 5 % of the truth 0.05.
    EXPECT_NEAR(r.g_s_per_rad, 0.05, 0.05 * 0.05);
  }
}
