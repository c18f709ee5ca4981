// Dead reckoning with the track slip in turns removed (turn_slip.hpp, DeadReckoner::add_turn_slip).
#include <gtest/gtest.h>

#include <cmath>

#include "odonav/dead_reckoning/dead_reckoner.hpp"
#include "synthetic_drive.hpp"

using namespace odonav;
using namespace odonav::dead_reckoning;
using namespace odonav::synthetic;

namespace {

constexpr double kK = 0.0125;

// One lap of a 320 m circle at 10 m/s (0.196 rad/s) whose odometer counts 1 + s pulses per
// pulse of distance, s from g = 0.05 s/rad beyond the 3 deg/s yaw-rate gate: 0.72 %.
struct SlippingLap {
  double g = 0.05;
  double threshold = 3.0 * kDegToRad;
  double slip = 0.0;
  SyntheticData data;
  SlippingLap() {
    const double radius = 320.0 / (2.0 * kPi);
    slip = turn_slip_fraction(g, threshold, 10.0 / radius);
    Trajectory tr = circle(radius, 10.0, deg_to_rad(20.0));
    const auto true_distance = tr.distance_m;
    tr.distance_m = [=](double t) { return true_distance(t) * (1.0 + slip); };
    SensorConfig c;
    c.duration_s = 32.0;
    c.k_m_per_pulse = kK;
    data = simulate(tr, c);
  }
};

std::vector<DeadReckoningOutput> run(const SyntheticData& d, std::optional<std::pair<double, double>> slip,
                                     bool use_ins = true, DeadReckonerCounters* counters = nullptr) {
  DeadReckonerParams p;
  p.nominal_k_m_per_pulse = kK;
  p.use_ins = use_ins;
  DeadReckoner dr(p);
  if (slip) dr.add_turn_slip(0.0, slip->first, slip->second);
  for (const auto& s : d.odometer) dr.add_odometer(s);
  if (use_ins)
    for (const auto& s : d.ins) dr.add_ins(s);
  for (const auto& s : d.gnss) dr.add_gnss(s);
  auto out = dr.finish();
  if (counters) *counters = dr.counters();
  return out;
}

}  // namespace

TEST(DeadReckonerTurnSlip, TheSlipOfALapIsRemovedAndTheLoopCloses) {
  const SlippingLap lap;
  ASSERT_GT(lap.slip, 0.007);
  const auto plain = run(lap.data, std::nullopt);
  const auto compensated = run(lap.data, std::make_pair(lap.g, lap.threshold));
  auto max_error = [](const std::vector<DeadReckoningOutput>& out) {
    double m = 0.0;
    for (const auto& o : out)
      if (std::isfinite(o.horizontal_error_m)) m = std::max(m, o.horizontal_error_m);
    return m;
  };
  // Without the slip the lap is 0.72 % too long (2.3 m of 320 m): a circle 0.72 % too large, off
  // by its diameter times that (0.73 m) half way round, closing again at the end.
  EXPECT_NEAR(plain.back().distance_m, 320.0 * (1.0 + lap.slip), 0.05);
  EXPECT_NEAR(max_error(plain), 320.0 / kPi * lap.slip, 0.05);
  // With it: the distance within pulse quantisation and the track within centimetres all the way.
  EXPECT_NEAR(compensated.back().distance_m, 320.0, 0.05);
  EXPECT_LT(max_error(compensated), 0.05);
  EXPECT_NEAR(compensated.back().turn_slip_fraction, lap.slip, 1e-3);
  EXPECT_EQ(plain.back().turn_slip_fraction, 0.0);
}

TEST(DeadReckonerTurnSlip, AZeroGainOrNoInsChangesNothing) {
  const SlippingLap lap;
  const auto plain = run(lap.data, std::nullopt);
  const auto zero = run(lap.data, std::make_pair(0.0, lap.threshold));
  ASSERT_EQ(plain.size(), zero.size());
  for (std::size_t i = 0; i < plain.size(); ++i) ASSERT_EQ(plain[i].enu_m, zero[i].enu_m) << i;
  // Without INS there is no yaw rate to scale by: the distance as counted.
  const auto no_ins = run(lap.data, std::make_pair(lap.g, lap.threshold), false);
  EXPECT_NEAR(no_ins.back().distance_m, 320.0 * (1.0 + lap.slip), 0.05);
}

TEST(DeadReckonerTurnSlip, BadGainsAreRefusedStaleOnesCounted) {
  DeadReckoner dr(DeadReckonerParams{});
  EXPECT_THROW(dr.add_turn_slip(1.0, -0.01, 0.05), StreamInputError);
  EXPECT_THROW(dr.add_turn_slip(1.0, std::nan(""), 0.05), StreamInputError);
  EXPECT_THROW(dr.add_turn_slip(1.0, 0.05, -1.0), StreamInputError);
  dr.add_turn_slip(2.0, 0.05, 0.05);
  dr.add_turn_slip(2.0, 0.06, 0.05);
  EXPECT_EQ(dr.counters().turn_slip_stale, 1u);
}
