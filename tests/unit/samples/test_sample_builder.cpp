// Sample builder (docs/ALGORITHM.md §2) on synthetic drives with exactly known K and trajectory.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <iterator>
#include <map>

#include "odonav/sample_builder.hpp"
#include "synthetic_drive.hpp"

using namespace odonav;
using namespace odonav::synthetic;

namespace {

constexpr double kK = 0.0125;

// A growing-memory least-squares K fed back into the builder from the epoch callback, as the
// scale-factor node does (the estimate applies from the next epoch on).
struct FeedbackK {
  double sum_py = 0.0, sum_pp = 0.0;
  void attach(SampleBuilder& b, const SampleBuilderEpoch& e) {
    if (!e.sample) return;
    sum_py += e.sample->phi_pulses * e.sample->y_m;
    sum_pp += e.sample->phi_pulses * e.sample->phi_pulses;
    b.add_scale_factor_estimate(e.t_s, sum_py / sum_pp, 0.0);
  }
};

// Every sample of d into b (processed at finish()).
void feed(SampleBuilder& b, const SyntheticData& d) {
  for (const auto& s : d.odometer) b.add_odometer(s);
  for (const auto& s : d.gnss) b.add_gnss(s);
  for (const auto& s : d.ins) b.add_ins(s);
}

std::vector<SampleBuilderEpoch> run_all(const SyntheticData& d, const SampleBuilderParams& p = {},
                                        bool feedback = false, SampleBuilderCounters* counters = nullptr) {
  SampleBuilder b(p);
  feed(b, d);
  FeedbackK fk;
  auto out = b.finish([&](const SampleBuilderEpoch& e) {
    if (feedback) fk.attach(b, e);
  });
  if (counters) *counters = b.counters();
  return out;
}

// The counters of run_all(d, p, feedback), its epochs left out.
SampleBuilderCounters counters_of(const SyntheticData& d, const SampleBuilderParams& p = {}, bool feedback = false) {
  SampleBuilderCounters c;
  run_all(d, p, feedback, &c);
  return c;
}

SensorConfig accel_config() {
  SensorConfig c;
  c.duration_s = 20.0;
  c.k_m_per_pulse = kK;
  return c;
}
// 5 m/s + 1 m/s^2, heading 30 deg, level: 300 m in 20 s.
Trajectory accel_drive() { return straight(deg_to_rad(30.0), 0.0, 5.0, 1.0); }

std::vector<ScaleFactorSample> samples_of(const std::vector<SampleBuilderEpoch>& epochs) {
  std::vector<ScaleFactorSample> s;
  for (const auto& e : epochs)
    if (e.sample) s.push_back(*e.sample);
  return s;
}

}  // namespace

TEST(SampleBuilder, StraightAccelerationGivesYEqualKPhiToQuantisation) {
  const auto epochs = run_all(simulate(accel_drive(), accel_config()));
  ASSERT_EQ(epochs.size(), 201u);
  EXPECT_EQ(epochs[0].status, EpochStatus::kChainStart);
  const auto samples = samples_of(epochs);
  ASSERT_EQ(samples.size(), 200u);
  for (const auto& s : samples) {
    // The count at each end is off by less than one pulse (floor), so |y - K phi| < 2 K.
    EXPECT_LT(std::abs(s.y_m - kK * s.phi_pulses), 2.0 * kK) << "t=" << s.t_s;
    EXPECT_NEAR(s.dt_s, 0.1, 1e-9);
    EXPECT_TRUE(s.straight);
  }
  // The GNSS position frame starts at the first fix: the last sample is 300 m along azimuth 30 deg.
  EXPECT_NEAR(samples.back().gnss_position_enu_m.x(), 300.0 * std::sin(deg_to_rad(30.0)), 1e-6);
  EXPECT_NEAR(samples.back().gnss_position_enu_m.y(), 300.0 * std::cos(deg_to_rad(30.0)), 1e-6);
}

TEST(SampleBuilder, MeanSpeedFormBeatsEndSpeedFormUnderAcceleration) {
  const auto epochs = run_all(simulate(accel_drive(), accel_config()));
  double sum_y_mean = 0.0, sum_y_end = 0.0, sum_phi = 0.0;
  for (const auto& e : epochs) {
    if (!e.sample) continue;
    sum_y_mean += e.sample->y_m;
    sum_y_end += e.forward_speed_mps * e.sample->dt_s;  // the end-of-interval speed form
    sum_phi += e.sample->phi_pulses;
  }
  const double err_mean = sum_y_mean / sum_phi / kK - 1.0;
  const double err_end = sum_y_end / sum_phi / kK - 1.0;
  // Mean form: exact for a linear speed; what is left is at most 2 pulses of quantisation in 24000.
  EXPECT_LT(std::abs(err_mean), 2.0 / 24000.0 + 1e-9);
  // End form: each interval over-counts a dt^2 / 2 = 5 mm; 200 of them over 300 m = 1 / 300.
  EXPECT_NEAR(err_end, 200 * 0.5 * 1.0 * 0.01 / 300.0, 1e-4);
  EXPECT_LT(std::abs(err_mean) * 20.0, std::abs(err_end));
}

TEST(SampleBuilder, CounterWrapInTheMiddleGivesTheSamePhi) {
  SensorConfig wrapped = accel_config();
  wrapped.pulse_offset = 4294967295u - 12000u;  // wraps after 12000 of the 24000 pulses
  const SyntheticData dw = simulate(accel_drive(), wrapped);
  bool wrap_seen = false;
  for (std::size_t i = 1; i < dw.odometer.size(); ++i) wrap_seen |= dw.odometer[i].pulses < dw.odometer[i - 1].pulses;
  ASSERT_TRUE(wrap_seen);
  const auto a = samples_of(run_all(simulate(accel_drive(), accel_config())));
  const auto b = samples_of(run_all(dw));
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].phi_pulses, b[i].phi_pulses) << i;
    EXPECT_EQ(a[i].y_m, b[i].y_m) << i;
    EXPECT_LT(std::abs(b[i].y_m - kK * b[i].phi_pulses), 2.0 * kK);
  }
}

TEST(SampleBuilder, InvalidFixBreaksTheChainAndIsCounted) {
  SyntheticData d = simulate(accel_drive(), accel_config());
  d.gnss[50].fix = 0;
  d.gnss[60].fix = 6;
  SampleBuilderCounters c;
  const auto e = run_all(d, {}, false, &c);
  EXPECT_EQ(c.invalid_fix, 2u);
  EXPECT_EQ(e[50].status, EpochStatus::kInvalidFix);
  EXPECT_EQ(e[51].status, EpochStatus::kChainStart);
  EXPECT_EQ(c.accepted, 200u - 4u);
  EXPECT_EQ(c.epochs, 201u);
}

TEST(SampleBuilder, MinimumFixQualityGate) {
  SyntheticData d = simulate(accel_drive(), accel_config());
  for (std::size_t i = 100; i < d.gnss.size(); ++i) d.gnss[i].fix = 4;  // RTK fixed from t = 10 s
  SampleBuilderParams p;
  p.min_fix_rank = 2;
  SampleBuilderCounters c = counters_of(d, p, false);
  EXPECT_EQ(c.low_fix_quality, 100u);
  EXPECT_EQ(c.chain_starts, 1u);
  EXPECT_EQ(c.accepted, 100u);
}

TEST(SampleBuilder, MinimumSpeedAtBothEnds) {
  SensorConfig cfg = accel_config();
  const SyntheticData d = simulate(straight(0.0, 0.0, 0.0, 1.0), cfg);  // from standstill, 1 m/s^2
  SampleBuilderParams p;
  p.min_speed_mps = 2.05;
  SampleBuilderCounters c;
  const auto e = run_all(d, p, false, &c);
  // Epochs 0.1 .. 2.0 s end below 2.05 m/s; the epoch at 2.1 s starts at 2.0 m/s.
  EXPECT_EQ(c.min_speed, 21u);
  EXPECT_EQ(e[21].status, EpochStatus::kMinSpeed);
  EXPECT_EQ(e[22].status, EpochStatus::kAccepted);
  EXPECT_EQ(c.accepted, 179u);
}

TEST(SampleBuilder, ReversingFlagAndNegativeSpeedAreGated) {
  SyntheticData d = simulate(accel_drive(), accel_config());
  for (auto& o : d.odometer)
    if (o.t_s > 4.99 && o.t_s < 5.05) o.direction = -1;  // samples at 5.00, 5.02, 5.04
  d.gnss[80].vel_enu_mps = -d.gnss[80].vel_enu_mps;
  SampleBuilderCounters c;
  const auto e = run_all(d, {}, false, &c);
  EXPECT_EQ(c.reversing, 2u);  // intervals (4.9, 5.0] and (5.0, 5.1]
  EXPECT_EQ(e[50].status, EpochStatus::kReversing);
  EXPECT_EQ(e[51].status, EpochStatus::kReversing);
  EXPECT_EQ(c.negative_speed, 1u);
  EXPECT_EQ(e[80].status, EpochStatus::kNegativeSpeed);
  EXPECT_EQ(e[81].status, EpochStatus::kChainStart);
}

TEST(SampleBuilder, DrivingBackwardsGivesTheSameSamplesAsForwards) {
  // The same drive backwards: the body points the other way than it moves (GNSS velocity negated,
  // the INS attitude unchanged, so the forward speed is negative) and the odometer says -1 on every
  // sample. The pulses and the distance are those of the forward drive, so the samples must be too.
  const SyntheticData forwards = simulate(accel_drive(), accel_config());
  SyntheticData backwards = forwards;
  for (auto& o : backwards.odometer) o.direction = -1;
  for (auto& g : backwards.gnss) g.vel_enu_mps = -g.vel_enu_mps;
  SampleBuilderCounters c;
  const auto f = samples_of(run_all(forwards, {}, true));
  const auto b = samples_of(run_all(backwards, {}, true, &c));
  ASSERT_EQ(f.size(), 200u);  // epochs 0.1 .. 20 s
  ASSERT_EQ(b.size(), f.size());
  for (std::size_t i = 0; i < f.size(); ++i) {
    EXPECT_EQ(b[i].t_s, f[i].t_s);
    EXPECT_EQ(b[i].phi_pulses, f[i].phi_pulses);
    EXPECT_NEAR(b[i].y_m, f[i].y_m, 1e-12) << i;
    EXPECT_NEAR(b[i].y_m / b[i].phi_pulses, kK, 0.02 * kK) << i;
  }
  EXPECT_EQ(c.reversing_accepted, f.size());
  EXPECT_EQ(c.negative_speed, 0u);
  // Without INS the speed is |v| anyway: the same samples again.
  SampleBuilderParams no_ins;
  no_ins.use_ins = false;
  const auto f2 = samples_of(run_all(forwards, no_ins));
  const auto b2 = samples_of(run_all(backwards, no_ins));
  ASSERT_EQ(b2.size(), f2.size());
  for (std::size_t i = 0; i < f2.size(); ++i) EXPECT_NEAR(b2[i].y_m, f2[i].y_m, 1e-12) << i;
  // With reversing samples off, nothing backwards makes a sample: every epoch's forward speed is
  // negative.
  SampleBuilderParams off;
  off.reversing_samples = false;
  const auto e = run_all(backwards, off, false, &c);
  EXPECT_EQ(c.accepted, 0u);
  EXPECT_EQ(c.negative_speed, e.size());
  off.use_ins = false;
  c = counters_of(backwards, off, false);
  EXPECT_EQ(c.accepted, 0u);
  EXPECT_EQ(c.reversing, e.size() - 1);
}

TEST(SampleBuilder, GnssOutageBreaksTheChain) {
  SyntheticData d = simulate(accel_drive(), accel_config());
  d.gnss.erase(d.gnss.begin() + 100, d.gnss.begin() + 110);  // 1 s without GNSS
  SampleBuilderCounters c;
  const auto e = run_all(d, {}, false, &c);
  EXPECT_EQ(c.gap, 1u);
  EXPECT_EQ(e[100].status, EpochStatus::kGap);  // the first epoch after the outage
  EXPECT_EQ(c.accepted, 190u - 1u);
}

TEST(SampleBuilder, YawRateGateAndStraightFlag) {
  SensorConfig cfg = accel_config();
  cfg.duration_s = 10.0;
  // 10 m/s on a 20 m radius: 28.6 deg/s.
  SampleBuilderCounters c = counters_of(simulate(circle(20.0, 10.0, 0.0), cfg), {}, false);
  EXPECT_EQ(c.yaw_rate, 100u);
  EXPECT_EQ(c.accepted, 0u);
  SampleBuilderParams off;
  off.yaw_rate_gate_enabled = false;
  const auto e = run_all(simulate(circle(20.0, 10.0, 0.0), cfg), off, false, &c);
  EXPECT_EQ(c.yaw_rate, 0u);
  EXPECT_EQ(c.accepted, 100u);
  for (const auto& s : samples_of(e)) {
    EXPECT_FALSE(s.straight);
    // On the circle the odometer and GNSS agree too: the chord-free mean speed is exact.
    EXPECT_LT(std::abs(s.y_m - kK * s.phi_pulses), 2.0 * kK);
  }
  // 200 m radius: 2.9 deg/s passes the 10 deg/s gate but is not straight (> 1 deg/s).
  const auto wide = samples_of(run_all(simulate(circle(200.0, 10.0, 0.0), cfg)));
  ASSERT_EQ(wide.size(), 100u);
  EXPECT_FALSE(wide[50].straight);
}

TEST(SampleBuilder, MissingOdometerOrAttitudeIsCounted) {
  SyntheticData d = simulate(accel_drive(), accel_config());
  auto cut_odo = std::remove_if(d.odometer.begin(), d.odometer.end(),
                                [](const OdometerSample& s) { return s.t_s > 10.05 && s.t_s < 11.45; });
  d.odometer.erase(cut_odo, d.odometer.end());
  auto cut_ins =
      std::remove_if(d.ins.begin(), d.ins.end(), [](const InsSample& s) { return s.t_s > 15.05 && s.t_s < 16.45; });
  d.ins.erase(cut_ins, d.ins.end());
  SampleBuilderCounters c;
  const auto e = run_all(d, {}, false, &c);
  EXPECT_EQ(c.no_odometer, 14u);  // epochs 10.1 .. 11.4: the bracket [10.04, 11.46] is longer than 1 s
  EXPECT_EQ(c.no_attitude, 14u);
  EXPECT_EQ(e[115].status, EpochStatus::kChainStart);
  EXPECT_EQ(e[165].status, EpochStatus::kChainStart);
  EXPECT_EQ(c.accepted, 200u - 30u);
}

TEST(SampleBuilder, StuckOdometerGivesNoPulses) {
  SyntheticData d = simulate(accel_drive(), accel_config());
  uint32_t frozen = 0;
  for (auto& o : d.odometer) {
    if (o.t_s < 14.999) continue;
    if (frozen == 0) frozen = o.pulses;
    o.pulses = frozen;
  }
  SampleBuilderCounters c = counters_of(d, {}, false);
  EXPECT_EQ(c.no_pulses, 50u);  // every interval after 15 s
  EXPECT_EQ(c.accepted, 150u);
}

TEST(SampleBuilder, TenMetrePerSecondSpikeIsRejectedWithoutContaminatingNeighbours) {
  SyntheticData d = simulate(accel_drive(), accel_config());
  const Eigen::Vector3d u = accel_drive().direction(0.0);
  d.gnss[100].vel_enu_mps += 10.0 * u;
  SampleBuilderCounters c;
  const auto e = run_all(d, {}, true, &c);
  EXPECT_EQ(e[100].status, EpochStatus::kSpeedJump);
  EXPECT_EQ(e[101].status, EpochStatus::kChainStart);  // the spike enters no sample
  EXPECT_EQ(e[102].status, EpochStatus::kAccepted);
  EXPECT_EQ(c.speed_jump, 1u);
  EXPECT_EQ(c.accepted, 198u);
  for (const auto& s : samples_of(e)) EXPECT_LT(std::abs(s.y_m - kK * s.phi_pulses), 2.0 * kK) << s.t_s;
}

TEST(SampleBuilder, InnovationGateRejectsAnOutlierTheSpeedJumpGateLetsThrough) {
  SyntheticData d = simulate(accel_drive(), accel_config());
  const Eigen::Vector3d u = accel_drive().direction(0.0);
  d.gnss[150].vel_enu_mps += 2.5 * u;  // at 20 m/s: y off by 0.125 m of 2 m
  SampleBuilderParams p;
  p.speed_jump_margin_mps = 3.0;          // 2.5 m/s passes the jump gate (bound 3.6 m/s)
  p.innovation_k_change_fraction = 0.02;  // bound 5 * 0.0087 + 0.04 = 0.084 m
  SampleBuilderCounters c;
  const auto e = run_all(d, p, true, &c);
  EXPECT_EQ(c.speed_jump, 0u);
  EXPECT_EQ(c.innovation, 1u);
  EXPECT_EQ(e[150].status, EpochStatus::kInnovation);
  EXPECT_EQ(e[151].status, EpochStatus::kChainStart);
  for (const auto& s : samples_of(e)) EXPECT_LT(std::abs(s.y_m - kK * s.phi_pulses), 2.0 * kK) << s.t_s;
  // Without a K estimate the same outlier passes (the innovation test needs K^).
  c = counters_of(d, p, false);
  EXPECT_EQ(c.innovation, 0u);
}

TEST(SampleBuilder, CrossTrackGateRejectsAVelocityGlitchAcrossTheOdometerAxis) {
  // A receiver glitch of 3 m/s at right angles to the travel (heading 30 deg): the forward speed
  // barely moves (the speed-jump and innovation gates cannot see it), the odometer-frame velocity
  // across the axis is 3 m/s against a bound of 5 x 0.1 + tan(5 deg) x 12 m/s = 1.55 m/s.
  SyntheticData d = simulate(accel_drive(), accel_config());
  const Eigen::Vector3d u = accel_drive().direction(0.0);
  const Eigen::Vector3d across(u.y(), -u.x(), 0.0);
  d.gnss[70].vel_enu_mps += 3.0 * across;
  SampleBuilderCounters c;
  const auto e = run_all(d, {}, true, &c);
  EXPECT_EQ(e[70].status, EpochStatus::kCrossTrack);
  EXPECT_STREQ(to_string(e[70].status), "cross_track");
  EXPECT_EQ(e[71].status, EpochStatus::kChainStart);  // the glitch enters no sample
  EXPECT_EQ(c.cross_track, 1u);
  EXPECT_EQ(c.accepted, 198u);
  // Clean epochs never trip it (straight, level, misalignment 0: the cross-track velocity is noise).
  SampleBuilderCounters clean = counters_of(simulate(accel_drive(), accel_config()), {}, true);
  EXPECT_EQ(clean.cross_track, 0u);
  // Off, the same glitch is accepted: at right angles it leaves the forward speed as it is, so no
  // other gate rejects it.
  SampleBuilderParams off;
  off.cross_track_gate_enabled = false;
  c = counters_of(d, off, true);
  EXPECT_EQ(c.cross_track, 0u);
  EXPECT_EQ(c.accepted, 200u);
}

TEST(SampleBuilder, InnovationGateIsSuspendedAfterALongRunSoAKJumpCanBeTracked) {
  SyntheticData d = simulate(accel_drive(), accel_config());
  // K drops 20 % at 10 s (e.g. a track change): the odometer counts 25 % more pulses from then on.
  const uint32_t at10 = d.odometer[500].pulses;
  for (std::size_t i = 501; i < d.odometer.size(); ++i)
    d.odometer[i].pulses = at10 + static_cast<uint32_t>(std::llround((d.odometer[i].pulses - at10) * 1.25));
  SampleBuilderParams p;
  p.innovation_max_consecutive_rejections = 10;
  SampleBuilderCounters c = counters_of(d, p, true);
  EXPECT_EQ(c.innovation, 10u);
  EXPECT_GT(c.innovation_suspended, 0u);
  EXPECT_GT(c.accepted, 170u);
}

TEST(SampleBuilder, WithoutInsTheSpeedIsTheGroundSpeedNorm) {
  SensorConfig cfg = accel_config();
  // On a 5 deg slope, |v_ENU| is the along-track speed the odometer measures.
  const SyntheticData d = simulate(straight(deg_to_rad(10.0), deg_to_rad(5.0), 8.0, 0.0), cfg);
  SampleBuilderParams p;
  p.use_ins = false;
  const auto e = run_all(d, p);
  const auto s = samples_of(e);
  ASSERT_EQ(s.size(), 200u);
  EXPECT_NEAR(e[10].forward_speed_mps, 8.0, 1e-12);
  for (const auto& x : s) EXPECT_LT(std::abs(x.y_m - kK * x.phi_pulses), 2.0 * kK);
}

TEST(SampleBuilder, MisalignmentInForceIsUsedForTheProjection) {
  SensorConfig cfg = accel_config();
  cfg.misalignment = Misalignment{deg_to_rad(3.0), deg_to_rad(-2.0)};
  const SyntheticData d = simulate(accel_drive(), cfg);
  // Without the misalignment the projection is short by cos 3 cos 2; with it, exact.
  const auto wrong = samples_of(run_all(d));
  SampleBuilder b;
  b.add_misalignment(0.0, cfg.misalignment);
  for (const auto& s : d.odometer) b.add_odometer(s);
  for (const auto& s : d.gnss) b.add_gnss(s);
  for (const auto& s : d.ins) b.add_ins(s);
  const auto right = samples_of(b.finish());
  ASSERT_EQ(wrong.size(), right.size());
  double sy_w = 0, sy_r = 0, sp = 0;
  for (std::size_t i = 0; i < right.size(); ++i) {
    sy_w += wrong[i].y_m;
    sy_r += right[i].y_m;
    sp += right[i].phi_pulses;
  }
  EXPECT_NEAR(sy_w / sy_r, std::cos(deg_to_rad(3.0)) * std::cos(deg_to_rad(2.0)), 1e-12);
  EXPECT_NEAR(sy_r / sp / kK, 1.0, 1e-4);
}

TEST(SampleBuilder, DifferentInterleavingsGiveBitIdenticalSamples) {
  SensorConfig cfg = accel_config();
  cfg.velocity_noise_mps = 0.05;
  cfg.seed = 11;
  cfg.misalignment = Misalignment{deg_to_rad(0.8), deg_to_rad(-0.5)};
  SyntheticData d = simulate(accel_drive(), cfg);
  d.gnss[40].fix = 0;
  d.gnss[120].vel_enu_mps += Eigen::Vector3d(6.0, 0.0, 0.0);
  const Misalignment m1{deg_to_rad(0.5), 0.0}, m2{deg_to_rad(0.8), deg_to_rad(-0.5)};

  // A: everything first, one finish().
  SampleBuilder a;
  a.add_misalignment(0.0, m1);
  a.add_misalignment(7.05, m2);
  for (const auto& s : d.ins) a.add_ins(s);
  for (const auto& s : d.gnss) a.add_gnss(s);
  for (const auto& s : d.odometer) a.add_odometer(s);
  FeedbackK fa;
  const auto ea = a.finish([&](const SampleBuilderEpoch& e) { fa.attach(a, e); });

  // B: streams fed with different lags in random bursts; process_until at the minimum watermark.
  SampleBuilder b;
  b.add_misalignment(0.0, m1);
  b.add_misalignment(7.05, m2);
  FeedbackK fb;
  std::vector<SampleBuilderEpoch> eb;
  auto sink = [&](const SampleBuilderEpoch& e) {
    fb.attach(b, e);
    eb.push_back(e);
  };
  feed_in_random_bursts(d, b, 5, 40, [&](double w) { b.process_until(w, sink); });
  b.finish(sink);

  ASSERT_EQ(ea.size(), eb.size());
  std::size_t accepted = 0;
  for (std::size_t i = 0; i < ea.size(); ++i) {
    EXPECT_EQ(ea[i].t_s, eb[i].t_s);
    EXPECT_EQ(ea[i].status, eb[i].status) << i;
    EXPECT_EQ(std::memcmp(&ea[i].forward_speed_mps, &eb[i].forward_speed_mps, sizeof(double)), 0) << i;
    ASSERT_EQ(ea[i].sample.has_value(), eb[i].sample.has_value()) << i;
    if (!ea[i].sample) continue;
    ++accepted;
    EXPECT_EQ(ea[i].sample->phi_pulses, eb[i].sample->phi_pulses);
    EXPECT_EQ(ea[i].sample->y_m, eb[i].sample->y_m);
    EXPECT_EQ(ea[i].sample->dt_s, eb[i].sample->dt_s);
    EXPECT_EQ(ea[i].sample->gnss_position_enu_m, eb[i].sample->gnss_position_enu_m);
    EXPECT_EQ(ea[i].sample->straight, eb[i].sample->straight);
  }
  EXPECT_GT(accepted, 190u);  // the comparison covered real samples
  EXPECT_EQ(a.counters().invalid_fix, 1u);
  EXPECT_EQ(a.counters().cross_track, 1u);  // the 6 m/s east spike is mostly across the 30 deg track
}

TEST(SampleBuilder, BadInputAndParamsAreRejectedWithClearErrors) {
  SampleBuilderParams bad;
  bad.max_interval_s = -1.0;
  EXPECT_THROW(SampleBuilder{bad}, std::invalid_argument);
  SampleBuilder b;
  GnssSample g;
  g.t_s = 1.0;
  g.vel_enu_mps = Eigen::Vector3d(std::numeric_limits<double>::quiet_NaN(), 0, 0);
  try {
    b.add_gnss(g);
    FAIL();
  } catch (const StreamInputError& e) {
    EXPECT_NE(std::string(e.what()).find("gnss"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("t=1"), std::string::npos);
  }
  EXPECT_THROW(b.add_scale_factor_estimate(1.0, -0.01, 0.0), StreamInputError);
  EXPECT_THROW(b.process_until(std::numeric_limits<double>::quiet_NaN()), std::invalid_argument);
}

// --- pulse jumps (a counter glitch is not distance): rejected and counted, the regression never sees them ---

TEST(SampleBuilder, MillionfoldPulseStepIsRejectedCountedAndTheSamplesAfterItAreRight) {
  const SyntheticData clean = simulate(accel_drive(), accel_config());
  SyntheticData d = clean;
  // Odometer at 50 Hz: sample 501 is t = 10.02 s, where the speed is 15 m/s (24 pulses per
  // sample). From there on the counter reads a million times that too high.
  const uint32_t jump = 1000000u * 24u;
  for (std::size_t i = 501; i < d.odometer.size(); ++i) d.odometer[i].pulses += jump;
  SampleBuilderCounters c;
  const auto samples = samples_of(run_all(d, {}, false, &c));
  EXPECT_EQ(c.odometer_jumps_rejected, 1u);
  EXPECT_EQ(c.odometer_rebases, 1u);
  EXPECT_EQ(c.accepted, 200u);  // nothing lost: every GNSS interval still makes a sample
  const auto reference = samples_of(run_all(clean));
  ASSERT_EQ(samples.size(), reference.size());
  double sum_phi = 0.0, sum_phi_clean = 0.0;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    sum_phi += samples[i].phi_pulses;
    sum_phi_clean += reference[i].phi_pulses;
    // Only the interval [10.0, 10.1] s holds the estimated 20 ms; the rest is bit-identical.
    if (std::abs(samples[i].t_s - 10.1) > 1e-6) {
      EXPECT_EQ(samples[i].phi_pulses, reference[i].phi_pulses) << samples[i].t_s;
    }
    EXPECT_LT(std::abs(samples[i].y_m - kK * samples[i].phi_pulses), 3.0 * kK) << samples[i].t_s;
  }
  // 24000 pulses in all; the one estimated interval is off by less than one pulse.
  EXPECT_NEAR(sum_phi, sum_phi_clean, 1.0);
}

TEST(SampleBuilder, MillionfoldPulseSpikeIsRejectedAndChangesNoSample) {
  const SyntheticData clean = simulate(accel_drive(), accel_config());
  SyntheticData d = clean;
  d.odometer[501].pulses += 1000000u * 24u;  // one bad value at t = 10.02 s
  SampleBuilderCounters c;
  const auto samples = samples_of(run_all(d, {}, false, &c));
  EXPECT_EQ(c.odometer_jumps_rejected, 1u);
  EXPECT_EQ(c.odometer_rebases, 0u);
  const auto reference = samples_of(run_all(clean));
  ASSERT_EQ(samples.size(), reference.size());
  // The GNSS epochs at 10.0 and 10.1 s are bracketed by good odometer samples: every phi is exact.
  for (std::size_t i = 0; i < samples.size(); ++i) EXPECT_EQ(samples[i].phi_pulses, reference[i].phi_pulses) << i;
}

TEST(SampleBuilder, JumpGateUsesTheConfiguredNominalKAndMaximumSpeed) {
  // At 25 m/s top speed and 0.0125 m/pulse the gate is 2000 pulses/s: 40 + 2 per 20 ms. The
  // accelerating drive makes at most 24 per sample, so nothing is rejected; a slower gate of
  // 10 m/s (16 + 2 per sample) rejects every sample above 18 pulses, i.e. above 11.25 m/s.
  SampleBuilderParams fast;
  fast.odometer_jump_gate.max_speed_mps = 25.0;
  SampleBuilderCounters c = counters_of(simulate(accel_drive(), accel_config()), fast, false);
  EXPECT_EQ(c.odometer_jumps_rejected, 0u);
  SampleBuilderParams slow;
  slow.odometer_jump_gate.max_speed_mps = 10.0;
  c = counters_of(simulate(accel_drive(), accel_config()), slow, false);
  EXPECT_GT(c.odometer_jumps_rejected, 100u);
  SampleBuilderParams bad;
  bad.odometer_jump_gate.k_m_per_pulse = 0.0;
  EXPECT_THROW(SampleBuilder{bad}, std::invalid_argument);
}

TEST(SampleBuilder, EpochStatusTableNamesAndCountsEveryStatus) {
  const char* const names[] = {"accepted",    "chain_start", "invalid_fix",    "low_fix_quality",
                               "no_odometer", "no_attitude", "negative_speed", "speed_jump",
                               "gap",         "min_speed",   "reversing",      "yaw_rate",
                               "no_pulses",   "innovation",  "cross_track"};
  ASSERT_EQ(std::size(names), static_cast<std::size_t>(kLastEpochStatus) + 1);
  SampleBuilderCounters c;
  uint64_t* const fields[] = {&c.accepted,    &c.chain_starts, &c.invalid_fix,    &c.low_fix_quality,
                              &c.no_odometer, &c.no_attitude,  &c.negative_speed, &c.speed_jump,
                              &c.gap,         &c.min_speed,    &c.reversing,      &c.yaw_rate,
                              &c.no_pulses,   &c.innovation,   &c.cross_track};
  for (std::size_t i = 0; i < std::size(fields); ++i) *fields[i] = 100 + i;
  c.epochs = 7;
  c.innovation_suspended = 9;
  for (std::size_t i = 0; i < std::size(names); ++i) {
    const auto status = static_cast<EpochStatus>(i);
    EXPECT_STREQ(to_string(status), names[i]) << i;
    EXPECT_EQ(c.count(status), 100 + i) << names[i];
  }
  EXPECT_STREQ(to_string(static_cast<EpochStatus>(99)), "unknown");
  EXPECT_EQ(c.count(static_cast<EpochStatus>(99)), 0u);
}

TEST(SampleBuilder, EveryEpochIsCountedOnceUnderItsStatus) {
  SyntheticData d = simulate(accel_drive(), accel_config());
  ASSERT_EQ(d.gnss.size(), 201u);
  d.gnss[50].fix = 0;              // invalid fix, then a chain start
  d.gnss[100].vel_enu_mps *= 3.0;  // speed jump (15 -> 45 m/s in 0.1 s), then a chain start
  SampleBuilderCounters c;
  const auto e = run_all(d, {}, true, &c);
  std::map<EpochStatus, uint64_t> seen;
  for (const auto& epoch : e) ++seen[epoch.status];
  uint64_t total = 0;
  for (std::size_t i = 0; i <= static_cast<std::size_t>(kLastEpochStatus); ++i) {
    const auto status = static_cast<EpochStatus>(i);
    EXPECT_EQ(c.count(status), seen[status]) << to_string(status);
    total += c.count(status);
  }
  EXPECT_EQ(total, c.epochs);
  EXPECT_EQ(c.epochs, e.size());
  EXPECT_EQ(c.invalid_fix, 1u);
  EXPECT_EQ(c.speed_jump, 1u);
  EXPECT_EQ(c.chain_starts, 3u);
  EXPECT_EQ(c.accepted, 196u);
}

TEST(SampleBuilder, InnovationBoundFollowsTheNoiseModelPlusTheKChangeAllowance) {
  SampleBuilderParams p;
  p.innovation_n_sigma = 5.0;
  p.innovation_k_change_fraction = 0.1;
  // sigma_v 0.1 m/s over 0.1 s, K 0.0125 m/pulse, sigma_K 1e-5 m/pulse, 80 pulses:
  // sigma_gate^2 = 0.5 * 0.01^2 + 0.0125^2 / 6 + (1e-5 * 80)^2 = 7.668e-5 m^2, sigma_gate 8.757 mm;
  // bound = 5 * 8.757 mm + 0.1 * |0.0125 * 80| = 0.04378 + 0.1 m.
  EXPECT_NEAR(innovation_bound_m(p, 0.1, 0.0125, 1e-5, 80.0, 0.1), 0.1437840343808867, 1e-15);
  // Without the K uncertainty and the allowance only the noise model is left.
  p.innovation_k_change_fraction = 0.0;
  EXPECT_NEAR(innovation_bound_m(p, 0.1, 0.0125, 0.0, 80.0, 0.1),
              5.0 * std::sqrt(regression_noise_variance_m2(0.1, 0.1, 0.0125)), 1e-17);
  EXPECT_NEAR(innovation_bound_m(p, 0.1, 0.0125, 0.0, 80.0, 0.1), 5.0 * std::sqrt(7.60416666666667e-05), 1e-15);
}

// ---- rates and scales from the data, GNSS latency ----------------------------------------------

TEST(SampleBuilder, OneHertzGnssIsAcceptedBecauseTheGapGateFollowsTheObservedPeriod) {
  SensorConfig c = accel_config();
  c.gnss_period_s = 1.0;
  SampleBuilder b;
  const SyntheticData d = simulate(accel_drive(), c);
  for (const auto& s : d.odometer) b.add_odometer(s);
  for (const auto& s : d.gnss) b.add_gnss(s);
  for (const auto& s : d.ins) b.add_ins(s);
  const auto epochs = b.finish();
  ASSERT_EQ(epochs.size(), 21u);
  // The old fixed 0.5 s would have rejected every interval as a gap.
  EXPECT_EQ(b.counters().gap, 0u);
  EXPECT_EQ(b.counters().accepted, 20u);
  EXPECT_DOUBLE_EQ(b.gnss_period_s(), 1.0);
  EXPECT_DOUBLE_EQ(b.max_interval_in_force_s(), 2.5);
  EXPECT_EQ(b.innovation_rejections_before_suspension(), 5);  // 5 s at 1 Hz
  for (const auto& s : samples_of(epochs)) {
    EXPECT_NEAR(s.dt_s, 1.0, 1e-9);
    // Linear speed: the trapezoid is exact, so only quantisation is left: a pulse in phi and in the
    // correction's shifted count, and the correction's two pulse rates (count differences over 2h,
    // each weighted T / 2: one pulse in each is T / 4h, h = 0.1 s here from K = 0.0125 m/pulse and
    // the default sigma_v 0.1 m/s: 1.2 pulses at T = 1 s).
    EXPECT_LT(std::abs(s.y_m - kK * s.phi_pulses), 5.0 * kK) << s.t_s;
  }
  // At 10 Hz the derived gap is the 0.5 s floor; an explicit value still wins.
  EXPECT_DOUBLE_EQ(effective_max_interval_s(SampleBuilderParams{}, 0.1), 0.5);
  SampleBuilderParams fixed;
  fixed.max_interval_s = 0.7;
  EXPECT_DOUBLE_EQ(effective_max_interval_s(fixed, 1.0), 0.7);
}

TEST(SampleBuilder, TrapezoidRatesAreReadOverAWindowWhoseQuantisationIsAQuarterOfTheGnssNoise) {
  // The rate over +-h carries |K| sqrt(2/12) / (2h) m/s of quantisation; h makes that sigma_v / 4.
  const SampleBuilderParams p;  // pulse_rate_half_window_s 0.05 s
  const double q = std::sqrt(2.0 / 12.0);
  // terrain: 0.0127 m/pulse, 0.05 m/s at 1 Hz: h = 0.0127 q / (2 * 0.0125) = 0.207 s.
  EXPECT_NEAR(trapezoid_rate_half_window_s(p, 0.0127, 0.05, 1.0), 0.0127 * q / 0.025, 1e-12);
  EXPECT_NEAR(trapezoid_rate_half_window_s(p, 0.0127, 0.05, 1.0), 0.207, 0.001);
  // The rule's own check: the quantisation over the chosen window is sigma_v / 4.
  const double h = trapezoid_rate_half_window_s(p, 0.0127, 0.05, 1.0);
  EXPECT_NEAR(0.0127 * q / (2.0 * h), 0.05 / 4.0, 1e-12);
  // The slow robot's encoder (0.59 mm/pulse, RTK 0.02 m/s): already far below, the 0.05 s floor.
  EXPECT_DOUBLE_EQ(trapezoid_rate_half_window_s(p, 0.000589, 0.02, 1.0), 0.05);
  // A coarse encoder: never beyond a quarter of the interval (0.25 s at 1 Hz, 0.125 s at 2 Hz).
  EXPECT_DOUBLE_EQ(trapezoid_rate_half_window_s(p, 0.05, 0.05, 1.0), 0.25);
  EXPECT_DOUBLE_EQ(trapezoid_rate_half_window_s(p, 0.05, 0.05, 0.5), 0.125);
  // No GNSS velocity sigma: the widest window.
  EXPECT_DOUBLE_EQ(trapezoid_rate_half_window_s(p, 0.0127, 0.0, 1.0), 0.25);
}

TEST(SampleBuilder, TheMinimumPulsesGateRejectsSamplesWithTooFewPulses) {
  // 5 to 7 m/s at 10 Hz with K = 0.05 m/pulse: 10 to 14 pulses per sample, all below 16.
  SensorConfig c = accel_config();
  c.k_m_per_pulse = 0.05;
  c.duration_s = 2.0;
  SampleBuilderParams p;
  p.odometer_jump_gate.k_m_per_pulse = 0.05;
  SampleBuilderCounters counters = counters_of(simulate(accel_drive(), c), p, false);
  EXPECT_EQ(counters.accepted, 0u);
  EXPECT_EQ(counters.min_speed, 20u);
  p.min_pulses = 8.0;
  counters = counters_of(simulate(accel_drive(), c), p, false);
  EXPECT_EQ(counters.accepted, 20u);
}

TEST(SampleBuilder, GnssLatencyIsEstimatedOnlineAndCompensated) {
  for (const double latency_s : {0.0, 0.1}) {
    SensorConfig c;
    c.duration_s = 300.0;
    c.velocity_noise_mps = 0.02;
    c.gnss_latency_s = latency_s;
    const SyntheticData d = simulate(wavy_drive(), c);
    SampleBuilder b;
    for (const auto& s : d.odometer) b.add_odometer(s);
    for (const auto& s : d.gnss) b.add_gnss(s);
    for (const auto& s : d.ins) b.add_ins(s);
    FeedbackK fk;
    double sum_err2 = 0.0;
    int late = 0;
    b.finish([&](const SampleBuilderEpoch& e) {
      fk.attach(b, e);
      // Once the latency is in force every sample is y = K phi up to noise.
      if (e.sample && e.t_s > 200.0) {
        sum_err2 += std::pow(e.sample->y_m - kK * e.sample->phi_pulses, 2);
        ++late;
      }
    });
    const GnssLatencyEstimate& l = b.latency();
    EXPECT_FALSE(l.fixed);
    EXPECT_NEAR(l.estimate_s, latency_s, 0.003) << latency_s;
    EXPECT_NEAR(l.applied_s, latency_s, 0.003) << latency_s;
    EXPECT_GT(l.sigma_s, 0.0);
    EXPECT_LT(l.sigma_s, 0.002);
    EXPECT_TRUE(l.reason.empty()) << l.reason;
    // Residual RMS: GNSS noise 0.02 m/s over 0.1 s and quantisation, about 5 mm; an uncompensated
    // 0.1 s latency would add 0.1 s x the speed change per interval (up to 0.1 m/s): 10 mm.
    ASSERT_GT(late, 500);
    EXPECT_LT(std::sqrt(sum_err2 / late), 0.0065) << latency_s;
  }
}

// Whether an estimate differs significantly from the latency in force is judged against its sigma
// times the residuals' correlation factor (set_latency_sigma_factor, K's): the estimate itself does
// not change, only the decision to apply it. A factor below 1 never makes the test stricter.
TEST(SampleBuilder, GnssLatencyIsAppliedOnlyWhenItsChangeIsSignificantAgainstTheHonestSigma) {
  SensorConfig c;
  c.duration_s = 300.0;
  c.velocity_noise_mps = 0.02;
  c.gnss_latency_s = 0.1;
  const SyntheticData d = simulate(wavy_drive(), c);
  const auto run = [&](double factor) {
    SampleBuilder b;
    b.set_latency_sigma_factor(factor);
    for (const auto& s : d.odometer) b.add_odometer(s);
    for (const auto& s : d.gnss) b.add_gnss(s);
    for (const auto& s : d.ins) b.add_ins(s);
    FeedbackK fk;
    b.finish([&](const SampleBuilderEpoch& e) { fk.attach(b, e); });
    return b.latency();
  };
  const GnssLatencyEstimate plain = run(1.0);
  EXPECT_NEAR(plain.applied_s, 0.1, 0.003);
  // 100 ms against a sigma below 2 ms: 50 plain sigmas, but not 5 of 1000 times that.
  const GnssLatencyEstimate strict = run(1000.0);
  EXPECT_EQ(strict.applied_s, 0.0);
  EXPECT_NEAR(strict.estimate_s, 0.1, 0.003);
  EXPECT_LT(strict.sigma_s, 0.002);
  const GnssLatencyEstimate below_one = run(0.5);
  EXPECT_EQ(below_one.applied_s, plain.applied_s);
}

// The latency sums fit a K of their own per candidate and block: the K estimate fed back only arms
// the innovation gate. Here the true K steps by +3 % halfway while the estimate fed back stays at
// the old value (off by 3 % for the second half, as a lagging estimator is for a while): the
// latency is still found to a millisecond, applied within the first half minute, and the one
// block that holds the step (one K cannot describe it) is left out.
TEST(SampleBuilder, GnssLatencyNeedsNoKEstimateAndAStepOfTheTrueKDoesNotPullIt) {
  SensorConfig c;
  c.duration_s = 300.0;
  c.velocity_noise_mps = 0.02;
  c.gnss_latency_s = 0.1;
  const Trajectory tr = wavy_drive();
  SyntheticData d = simulate(tr, c);
  // From t_step on every pulse stands for 3 % more distance (wheel wear, tyre pressure).
  const double t_step = 145.0, k_after = 1.03 * kK;
  const double pulses_at_step = tr.distance_m(t_step) / kK;
  for (OdometerSample& o : d.odometer) {
    if (o.t_s <= t_step) continue;
    const double pulses = std::floor(pulses_at_step + (tr.distance_m(o.t_s) - tr.distance_m(t_step)) / k_after + 1e-7);
    o.pulses = static_cast<uint32_t>(c.pulse_offset + static_cast<uint64_t>(pulses));
  }
  SampleBuilder b;
  for (const auto& s : d.odometer) b.add_odometer(s);
  for (const auto& s : d.gnss) b.add_gnss(s);
  for (const auto& s : d.ins) b.add_ins(s);
  std::optional<double> first_applied_t_s;
  double worst_after_first_s = 0.0;  // from the first application on
  double worst_after_step_s = 0.0;
  b.finish([&](const SampleBuilderEpoch& e) {
    b.add_scale_factor_estimate(e.t_s, kK, 1e-6);  // the pre-step K, precise: the gate is armed
    const double error_s = std::abs(e.latency.applied_s - 0.1);
    if (!first_applied_t_s && error_s < 0.01) first_applied_t_s = e.t_s;
    if (first_applied_t_s) worst_after_first_s = std::max(worst_after_first_s, error_s);
    if (e.t_s > t_step) worst_after_step_s = std::max(worst_after_step_s, error_s);
  });
  const GnssLatencyEstimate& l = b.latency();
  EXPECT_NEAR(l.estimate_s, 0.1, 0.0015);
  EXPECT_NEAR(l.applied_s, 0.1, 0.0015);
  EXPECT_GT(l.sigma_s, 0.0);
  EXPECT_LT(l.sigma_s, 0.001);
  EXPECT_TRUE(l.reason.empty()) << l.reason;
  EXPECT_EQ(l.blocks_left_out, 1u);
  // Every accepted sample after the restart at the first application (about 20 s), but the 30 s
  // block with the step.
  EXPECT_GT(l.samples, 2400u);
  EXPECT_LT(l.samples, 2600u);
  ASSERT_TRUE(first_applied_t_s.has_value());
  EXPECT_LT(*first_applied_t_s, 30.0);  // measured 20.9 s
  // The first value applied is the coarse one (5 sigma from 0, sigma 2.4 ms: measured -3.7 ms);
  // across and after the step it stays within 2 ms (measured 1.2 ms; 5.6 ms when the block holding
  // the step weighed as much as the others).
  EXPECT_LT(worst_after_first_s, 0.005);
  EXPECT_LT(worst_after_step_s, 0.002);
}

TEST(SampleBuilder, BeforeAnyLatencyIsDecidedTheStartKIsTheOneOfTheBestLatencyCandidate) {
  // 100 ms of latency on the wavy drive, and a running K estimate fed back precise (the gate is
  // armed): the builder's own samples are off by the latency times their speed change until the
  // latency is applied; the K of the latency search's best candidate is not.
  SensorConfig c;
  c.duration_s = 60.0;
  c.velocity_noise_mps = 0.02;
  c.gnss_latency_s = 0.1;
  SampleBuilder b;
  feed(b, simulate(wavy_drive(), c));
  int given = 0, given_after_application = 0;
  double worst_k_rel = 0.0, worst_latency_s = 0.0;
  double sum_yphi = 0.0, sum_phiphi = 0.0, samples_k_rel = 0.0;  // least squares over the samples
  b.finish([&](const SampleBuilderEpoch& e) {
    b.add_scale_factor_estimate(e.t_s, kK, 1e-6);
    if (e.sample) {
      sum_yphi += e.sample->y_m * e.sample->phi_pulses;
      sum_phiphi += e.sample->phi_pulses * e.sample->phi_pulses;
    }
    const auto start = b.start_latency_k();
    if (!start) return;
    if (e.latency.applied_s != 0.0) ++given_after_application;
    ++given;
    worst_k_rel = std::max(worst_k_rel, std::abs(start->k_m_per_pulse / kK - 1.0));
    worst_latency_s = std::max(worst_latency_s, std::abs(start->latency_s - 0.1));
    samples_k_rel = std::max(samples_k_rel, std::abs(sum_yphi / sum_phiphi / kK - 1.0));
  });
  ASSERT_NE(b.latency().applied_s, 0.0);  // applied after about 20 s (the test above)
  // Given on 185 epochs, none after the latency was applied. Its K within 0.20 % and its latency
  // within 17 ms at every one of them, while the least-squares K of the builder's own samples so
  // far was off by up to 0.86 % at the same epochs.
  EXPECT_GT(given, 50);
  EXPECT_EQ(given_after_application, 0);
  EXPECT_LT(worst_k_rel, 0.003);
  EXPECT_LT(worst_latency_s, 0.025);
  EXPECT_GT(samples_k_rel, 0.005);

  // At 1 Hz too: the search compares the trapezoid of two speeds with the trapezoid of two pulse
  // rates, like with like, so its K has no bias of its own.
  SensorConfig slow = c;
  slow.gnss_period_s = 1.0;
  SampleBuilder b1;
  feed(b1, simulate(wavy_drive(), slow));
  int given_1hz = 0;
  double worst_k_rel_1hz = 0.0;
  b1.finish([&](const SampleBuilderEpoch& e) {
    b1.add_scale_factor_estimate(e.t_s, kK, 1e-6);
    const auto start = b1.start_latency_k();
    if (!start) return;
    ++given_1hz;
    worst_k_rel_1hz = std::max(worst_k_rel_1hz, std::abs(start->k_m_per_pulse / kK - 1.0));
  });
  // Given on 12 epochs, within 0.19 % at every one of them.
  EXPECT_GE(given_1hz, 5);
  EXPECT_LT(worst_k_rel_1hz, 0.004);
}

TEST(SampleBuilder, AFixedGnssLatencyIsUsedAsGiven) {
  SensorConfig c;
  c.duration_s = 30.0;
  c.gnss_latency_s = 0.1;
  SampleBuilderParams p;
  p.gnss_latency_fixed_s = 0.1;
  const auto epochs = run_all(simulate(wavy_drive(), c), p);
  const auto samples = samples_of(epochs);
  ASSERT_GT(samples.size(), 250u);
  for (const auto& s : samples) EXPECT_LT(std::abs(s.y_m - kK * s.phi_pulses), 2.0 * kK + 0.001) << s.t_s;
  EXPECT_TRUE(epochs.back().latency.fixed);
  EXPECT_DOUBLE_EQ(epochs.back().latency.applied_s, 0.1);
  EXPECT_DOUBLE_EQ(epochs.back().latency.sigma_s, 0.0);
  // Without compensation the same samples are off by the speed change over the latency.
  SampleBuilderParams off;
  off.latency_estimation_enabled = false;
  double worst = 0.0;
  for (const auto& s : samples_of(run_all(simulate(wavy_drive(), c), off)))
    worst = std::max(worst, std::abs(s.y_m - kK * s.phi_pulses));
  EXPECT_GT(worst, 0.008);
}

// An epoch needs nothing after its own sensor time: fed in time order, each GNSS epoch is processed
// as soon as the odometer and the INS have reached it, although the latency search looks up to
// 0.25 s past it (its sums are deferred). The result, the latency decisions included, is the one
// of a single finish() over the whole data.
TEST(SampleBuilder, AnEpochLeavesWhenItsOwnDataIsInAndTheDeferredLatencySearchIsChunkingFree) {
  for (const double period_s : {0.1, 1.0}) {
    SensorConfig c;
    c.duration_s = 300.0;
    c.velocity_noise_mps = 0.02;
    c.gnss_latency_s = 0.1;
    c.gnss_period_s = period_s;
    const SyntheticData d = simulate(wavy_drive(), c);
    SampleBuilderParams p;
    p.lever_arm_body_m = Eigen::Vector3d(-0.5, 0.3, 2.2);
    if (period_s > 0.5) p.latency_min_samples = 100;

    SampleBuilder a(p);
    for (const auto& s : d.odometer) a.add_odometer(s);
    for (const auto& s : d.gnss) a.add_gnss(s);
    for (const auto& s : d.ins) a.add_ins(s);
    FeedbackK fa;
    std::vector<SampleBuilderEpoch> ea;
    a.finish([&](const SampleBuilderEpoch& e) {
      fa.attach(a, e);
      ea.push_back(e);
    });

    SampleBuilder b(p);
    FeedbackK fb;
    std::vector<SampleBuilderEpoch> eb;
    auto sink = [&](const SampleBuilderEpoch& e) {
      fb.attach(b, e);
      eb.push_back(e);
    };
    std::size_t io = 0, ii = 0;
    std::size_t late_epochs = 0;
    for (const GnssSample& g : d.gnss) {
      // The odometer and INS up to their first sample at or after the epoch, nothing later.
      while (io < d.odometer.size() && (io == 0 || d.odometer[io - 1].t_s < g.t_s)) b.add_odometer(d.odometer[io++]);
      while (ii < d.ins.size() && (ii == 0 || d.ins[ii - 1].t_s < g.t_s)) b.add_ins(d.ins[ii++]);
      b.add_gnss(g);
      b.process_until(g.t_s, sink);
      // (The last fix, stamped after the last odometer sample, waits for the end of data.)
      if (b.pending_epochs() != 0 && g.t_s <= d.odometer.back().t_s) ++late_epochs;
    }
    while (io < d.odometer.size()) b.add_odometer(d.odometer[io++]);
    while (ii < d.ins.size()) b.add_ins(d.ins[ii++]);
    b.finish(sink);
    EXPECT_EQ(late_epochs, 0u) << period_s;

    ASSERT_EQ(ea.size(), eb.size()) << period_s;
    std::size_t accepted = 0;
    for (std::size_t i = 0; i < ea.size(); ++i) {
      ASSERT_EQ(ea[i].status, eb[i].status) << i;
      EXPECT_EQ(ea[i].latency.applied_s, eb[i].latency.applied_s) << i;
      EXPECT_EQ(ea[i].latency.samples, eb[i].latency.samples) << i;
      ASSERT_EQ(ea[i].sample.has_value(), eb[i].sample.has_value()) << i;
      if (!ea[i].sample) continue;
      ++accepted;
      EXPECT_EQ(ea[i].sample->y_m, eb[i].sample->y_m) << i;
      EXPECT_EQ(ea[i].sample->phi_pulses, eb[i].sample->phi_pulses) << i;
    }
    EXPECT_GT(accepted, static_cast<std::size_t>(0.9 * c.duration_s / period_s)) << period_s;
    // The deferred search still finds the receiver's latency, and it was applied during the run.
    EXPECT_NEAR(a.latency().applied_s, 0.1, 0.005) << period_s;
    // At 10 Hz it is applied during the run (at 1 Hz it wanders by tens of ms before it settles).
    if (period_s < 0.5) {
      EXPECT_NEAR(ea[ea.size() * 3 / 4].latency.applied_s, 0.1, 0.01);
    }
    EXPECT_EQ(a.latency().applied_s, b.latency().applied_s) << period_s;
  }
}
