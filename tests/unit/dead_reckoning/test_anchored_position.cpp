// AnchoredPositionFilter on hand-made tracks: the event-time hold-off, independence from the order in
// which fixes and steps arrive, the gate, the status and the covariance's growth with distance.
#include <gtest/gtest.h>

#include <cmath>
#include <sstream>
#include <string>
#include <stdexcept>
#include <vector>

#include "odonav/config.hpp"
#include "odonav/consumer_rules.hpp"
#include "odonav/dead_reckoning/anchored_position.hpp"
#include "odonav/dead_reckoning/dead_reckoning_options.hpp"
#include "odonav/lever_arm_option.hpp"
#include "odonav/frames.hpp"
#include "odonav/geodesy.hpp"
#include "odonav/stream_buffers.hpp"

using namespace odonav;
using namespace odonav::dead_reckoning;

namespace {
const Geodetic kOrigin{52.5 * kDegToRad, 13.4 * kDegToRad, 80.0};

// DR driving north at 10 m/s from the origin, sampled at 100 Hz.
AnchorDrStep dr_at(double t_s, double speed_mps = 10.0) {
  AnchorDrStep s;
  s.t_s = t_s;
  s.enu_m = Eigen::Vector3d(0.0, speed_mps * t_s, 0.0);
  s.position = move_geodetic(kOrigin, s.enu_m);
  s.distance_m = speed_mps * t_s;
  return s;
}

// A fix that sees the DR offset by `offset` at epoch t_s.
AnchorFix fix_at(double t_s, const Eigen::Vector3d& offset, double sigma_m = 1.0, double speed_mps = 10.0) {
  AnchorFix f;
  f.t_s = t_s;
  f.dr_enu_m = Eigen::Vector3d(0.0, speed_mps * t_s, 0.0);
  f.fix_enu_m = f.dr_enu_m + offset;
  f.dr_distance_m = speed_mps * t_s;
  f.sigma_m = sigma_m;
  return f;
}
}  // namespace

TEST(AnchoredPosition, AFixAppliesFromItsEpochPlusTheHoldOffOnly) {
  AnchoredPositionFilter filter;  // hold-off 0.2 s
  EXPECT_DOUBLE_EQ(filter.applies_from_s(1.0), 1.2 - 1e-6);
  filter.add_fix(fix_at(1.0, Eigen::Vector3d(3.0, -2.0, 0.5)));
  for (int j = 1; j <= 119; ++j) {  // t = 0.01 .. 1.19 s
    const AnchoredPosition p = filter.step(dr_at(0.01 * j));
    ASSERT_EQ(p.status, AnchorStatus::kNotStarted) << p.t_s;
    EXPECT_EQ(p.enu_m, dr_at(0.01 * j).enu_m);  // pure DR until then
    EXPECT_TRUE(std::isnan(p.horizontal_sigma_m()));
  }
  const AnchoredPosition p = filter.step(dr_at(1.2));
  EXPECT_EQ(p.status, AnchorStatus::kAnchored);
  // The first fix sets the offset: DR(1.2) + (3, -2, 0.5).
  EXPECT_NEAR(p.enu_m.x(), 3.0, 1e-12);
  EXPECT_NEAR(p.enu_m.y(), 12.0 - 2.0, 1e-12);
  EXPECT_NEAR(p.enu_m.z(), 0.5, 1e-12);
  // Its geodetic position is the same point (the offset is laid out in the ENU axes at the DR point,
  // which turn by distance / earth radius from the origin's: micrometres here).
  const LocalEnuFrame frame(kOrigin);
  EXPECT_NEAR((frame.to_enu(p.position) - p.enu_m).norm(), 0.0, 1e-4);
  EXPECT_DOUBLE_EQ(p.last_fix_t_s, 1.0);
  EXPECT_NEAR(p.distance_since_fix_m, 2.0, 1e-12);
  // Covariance: the fix's variance, 1 m per horizontal axis and 1.5 m vertical.
  EXPECT_DOUBLE_EQ(p.covariance_enu_m2(0, 0), 1.0);
  EXPECT_DOUBLE_EQ(p.covariance_enu_m2(2, 2), 2.25);
  EXPECT_EQ(p.covariance_enu_m2(0, 1), 0.0);
  // The next step adds the process noise of its 0.1 m: the offset's random walk (the scale and
  // heading errors start at 0 +- 0 by default: the identified K and misalignment taken as right).
  const AnchoredPosition next = filter.step(dr_at(1.21));
  EXPECT_NEAR(next.covariance_enu_m2(0, 0), 1.0 + 0.1 * std::pow(0.15 / 100.0, 2) * 400.0, 1e-12);
  EXPECT_NEAR(next.covariance_enu_m2(1, 1), 1.0 + 0.1 * std::pow(0.15 / 100.0, 2) * 400.0, 1e-12);
  // With a prior on them, the 0.1 m northwards adds the scale's 1 % north and the heading's 0.5 deg east.
  AnchoredPositionParams uncertain;
  uncertain.scale_sigma_percent = 1.0;
  uncertain.heading_sigma_deg = 0.5;
  AnchoredPositionFilter u(uncertain);
  u.add_fix(fix_at(1.0, Eigen::Vector3d(3.0, -2.0, 0.5)));
  u.step(dr_at(1.2));
  const AnchoredPosition un = u.step(dr_at(1.21));
  EXPECT_NEAR(un.covariance_enu_m2(0, 0), next.covariance_enu_m2(0, 0) + std::pow(0.1 * 0.5 * kDegToRad, 2), 1e-12);
  EXPECT_NEAR(un.covariance_enu_m2(1, 1), next.covariance_enu_m2(1, 1) + std::pow(0.1 * 0.01, 2), 1e-12);
  EXPECT_EQ(filter.counters().fixes_applied, 1u);
}

TEST(AnchoredPosition, ArrivalOrderChangesNothing) {
  // Fixes at 10 Hz with an alternating offset; once all added before the steps, once each added
  // only when its hold-off is due (the latest a node may have it).
  std::vector<AnchorFix> fixes;
  AnchoredPositionParams white;
  white.fix_correlated_fraction = 0.0;  // independent fixes: the offset converges on their mean
  for (int i = 0; i <= 100; ++i) fixes.push_back(fix_at(0.1 * i, Eigen::Vector3d(i % 2 ? 1.0 : -1.0, 0.5, 0.0)));
  AnchoredPositionFilter early(white), late(white);
  for (const AnchorFix& f : fixes) early.add_fix(f);
  std::size_t next = 0;
  for (int j = 1; j <= 1000; ++j) {
    const double t = 0.01 * j;
    while (next < fixes.size() && late.applies_from_s(fixes[next].t_s) <= t) late.add_fix(fixes[next++]);
    const AnchoredPosition a = early.step(dr_at(t)), b = late.step(dr_at(t));
    ASSERT_EQ(a.enu_m, b.enu_m) << t;
    ASSERT_EQ(a.status, b.status);
  }
  // The offset converged near the fixes' mean (0, 0.5).
  const AnchoredPosition p = early.step(dr_at(10.01));
  EXPECT_NEAR(p.enu_m.x(), 0.0, 0.3);
  EXPECT_NEAR(p.enu_m.y() - 100.1, 0.5, 0.1);
}

TEST(AnchoredPosition, AJumpingFixIsGatedAndCounted) {
  AnchoredPositionFilter filter;
  for (int i = 0; i <= 50; ++i) filter.add_fix(fix_at(0.1 * i, Eigen::Vector3d(i == 30 ? 60.0 : 0.0, 0.0, 0.0)));
  AnchoredPosition p;
  for (int j = 1; j <= 600; ++j) p = filter.step(dr_at(0.01 * j));
  EXPECT_EQ(filter.counters().fixes_rejected_gate, 1u);
  EXPECT_NEAR(filter.counters().last_rejected_innovation_m, 60.0, 1e-9);
  EXPECT_EQ(filter.counters().fixes_applied, 50u);
  EXPECT_NEAR(p.enu_m.x(), 0.0, 1e-9);
  EXPECT_LT(filter.counters().last_rejected_gate_m, 20.0);
}

TEST(AnchoredPosition, BridgesAGapByDeadReckoningAndItsSigmaGrowsWithDistanceOnly) {
  AnchoredPositionFilter filter;
  for (int i = 0; i <= 20; ++i) filter.add_fix(fix_at(0.1 * i, Eigen::Vector3d(2.0, 0.0, 0.0)));
  AnchoredPosition p;
  for (int j = 1; j <= 220; ++j) p = filter.step(dr_at(0.01 * j));
  ASSERT_EQ(p.status, AnchorStatus::kAnchored);
  const double sigma_at_last_fix = p.horizontal_sigma_m();
  // No fix after t = 2 s: at 2 + 2.5 s the position is still anchored, after it dead reckoning.
  for (int j = 221; j <= 450; ++j) p = filter.step(dr_at(0.01 * j));
  EXPECT_EQ(p.status, AnchorStatus::kAnchored);
  p = filter.step(dr_at(4.51));
  EXPECT_EQ(p.status, AnchorStatus::kDeadReckoning);
  EXPECT_NEAR(p.distance_since_fix_m, 25.1, 1e-9);
  EXPECT_NEAR(p.enu_m.x(), 2.0, 1e-9);  // the DR carried on from the last corrected state
  const double sigma_moving = p.horizontal_sigma_m();
  EXPECT_GT(sigma_moving, sigma_at_last_fix);
  // Standing still (the DR does not move) adds nothing.
  AnchorDrStep still = dr_at(4.51);
  for (int j = 1; j <= 100; ++j) {
    still.t_s = 4.51 + 0.01 * j;
    p = filter.step(still);
  }
  EXPECT_DOUBLE_EQ(p.horizontal_sigma_m(), sigma_moving);
}

TEST(AnchoredPosition, BadParametersAndInputAreNamed) {
  AnchoredPositionParams p;
  p.hold_off_s = -0.1;
  try {
    AnchoredPositionFilter f(p);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("hold_off_s"), std::string::npos);
  }
  AnchoredPositionFilter filter;
  filter.add_fix(fix_at(1.0, Eigen::Vector3d::Zero()));
  EXPECT_THROW(filter.add_fix(fix_at(1.0, Eigen::Vector3d::Zero())), StreamInputError);
  AnchorFix nan = fix_at(2.0, Eigen::Vector3d::Zero());
  nan.fix_enu_m.x() = std::nan("");
  EXPECT_THROW(filter.add_fix(nan), StreamInputError);
}

TEST(AnchoredPosition, AGateThatStaysShutRestartsOnTheFixesAndCountsIt) {
  // The fixes jump 60 m for good at t = 3 s (the DR, say, lost its heading): five are gated, the
  // sixth restarts the filter on them.
  AnchoredPositionFilter filter;
  for (int i = 0; i <= 60; ++i) filter.add_fix(fix_at(0.1 * i, Eigen::Vector3d(i >= 30 ? 60.0 : 0.0, 0.0, 0.0)));
  AnchoredPosition p;
  for (int j = 1; j <= 700; ++j) p = filter.step(dr_at(0.01 * j));
  EXPECT_EQ(filter.counters().fixes_rejected_gate, 5u);
  EXPECT_EQ(filter.counters().gate_restarts, 1u);
  EXPECT_NEAR(p.enu_m.x(), 60.0, 1e-9);
  EXPECT_EQ(p.status, AnchorStatus::kAnchored);
}

namespace {
// The truth of a DR whose increments are 2 % short and turned 1 deg clockwise: the vehicle drives
// north-north-east at 10.2 m/s while the DR believes due north at 10 m/s.
constexpr double kScaleError = 0.02, kHeadingError_rad = 1.0 * kDegToRad;
Eigen::Vector3d truth_of(const Eigen::Vector3d& dr_enu_m) {
  const double c = std::cos(kHeadingError_rad), s = std::sin(kHeadingError_rad);
  return (1.0 + kScaleError) *
         Eigen::Vector3d(c * dr_enu_m.x() - s * dr_enu_m.y(), s * dr_enu_m.x() + c * dr_enu_m.y(), 0.0);
}
}  // namespace

TEST(AnchoredPosition, LearnsTheScaleAndHeadingErrorsOfTheDrAndBridgesAGapWithThem) {
  // Precise white fixes (5 cm) at 1 Hz for 120 s (1.2 km), then 60 s (600 m) without GNSS: the pure
  // DR misses 2 % and 1 deg of it, 12 m along and 10.5 m across the track.
  AnchoredPositionParams p;
  p.fix_correlated_fraction = 0.0;
  p.scale_sigma_percent = 3.0;  // a DR on a nominal K, heading not calibrated
  p.heading_sigma_deg = 2.0;
  AnchoredPositionFilter filter(p);
  for (int i = 0; i <= 120; ++i) {
    AnchorFix f = fix_at(i, Eigen::Vector3d::Zero(), 0.05);
    f.fix_enu_m = truth_of(f.dr_enu_m);
    filter.add_fix(f);
  }
  AnchoredPosition pos;
  for (int j = 1; j <= 18000; ++j) pos = filter.step(dr_at(0.01 * j));
  // The states are linear in the increment: s = (1 + 2 %) cos(1 deg) - 1, psi = (1 + 2 %) sin(1 deg).
  EXPECT_NEAR(pos.scale_error, (1.0 + kScaleError) * std::cos(kHeadingError_rad) - 1.0, 1e-4);
  EXPECT_NEAR(pos.heading_error_rad, (1.0 + kScaleError) * std::sin(kHeadingError_rad), 1e-4);
  EXPECT_EQ(pos.status, AnchorStatus::kDeadReckoning);
  const double error_m = (pos.enu_m - truth_of(dr_at(180.0).enu_m)).head<2>().norm();
  const double pure_dr_error_m = (dr_at(180.0).enu_m - truth_of(dr_at(180.0).enu_m)).head<2>().norm();
  EXPECT_GT(pure_dr_error_m, 45.0);  // 2 % and 1 deg of 1.8 km: 36 m along, 32 m across
  EXPECT_LT(error_m, 0.3);           // 0.02 % of the 600 m gap, not 2 %
  // And the reported sigma covers it without claiming centimetres after 600 m of DR.
  EXPECT_GT(pos.horizontal_sigma_m(), error_m);
  EXPECT_LT(pos.horizontal_sigma_m(), 3.0);
}

// The navigation position's parameters come from the DR's options, through the one function both
// odonav-offline and odonav-dead-reckoning call: its hold-off is the DR's --estimate-hold-off-s.
TEST(AnchoredPosition, ParametersComeFromTheDrOptionsAndTheHoldOffIsTheDrs) {
  Options o("odonav-test", "anchored position options");
  add_dead_reckoning_options(o);
  add_lever_arm_option(o);
  std::ostringstream help;
  ASSERT_EQ(o.parse({"--estimate-hold-off-s", "0.35", "--anchor-drift-percent", "0.3", "--anchor-scale-sigma-percent",
                     "2", "--anchor-scale-walk-percent-per-sqrt-km", "0.1", "--anchor-heading-sigma-deg", "1.5",
                     "--anchor-heading-walk-deg-per-sqrt-s", "0.001", "--anchor-gnss-correlation-s", "30",
                     "--anchor-gnss-correlated-fraction", "0.5", "--anchor-gate-sigma", "8"},
                    help),
            ParseResult::kRun);
  DeadReckoningFacts facts = dead_reckoning_facts_from(o);
  AnchoredPositionParams p = anchored_position_params(facts);
  EXPECT_EQ(p.hold_off_s, 0.35);
  EXPECT_EQ(p.drift_percent_distance, 0.3);
  EXPECT_EQ(p.scale_sigma_percent, 2.0);
  EXPECT_EQ(p.scale_random_walk_percent_per_sqrt_km, 0.1);
  EXPECT_EQ(p.heading_sigma_deg, 1.5);
  EXPECT_EQ(p.heading_random_walk_deg_per_sqrt_s, 0.001);
  EXPECT_EQ(p.fix_correlation_time_s, 30.0);
  EXPECT_EQ(p.fix_correlated_fraction, 0.5);
  EXPECT_EQ(p.gate_sigma, 8.0);
  AnchoredPositionFilter filter(p);
  EXPECT_EQ(filter.applies_from_s(10.0), estimate_applies_from_s(10.0, 0.35));
  // Without INS the offset walk is at least the degraded mode's.
  facts.use_ins = false;
  EXPECT_EQ(anchored_position_params(facts).drift_percent_distance, kDegradedAnchorDriftPercent);

  Options none("odonav-test", "defaults");
  add_dead_reckoning_options(none);
  add_lever_arm_option(none);
  ASSERT_EQ(none.parse(std::vector<std::string>{}, help), ParseResult::kRun);
  const AnchoredPositionParams d = anchored_position_params(dead_reckoning_facts_from(none));
  const AnchoredPositionParams defaults;
  EXPECT_EQ(d.hold_off_s, kDefaultEstimateHoldOff_s);
  EXPECT_EQ(d.drift_percent_distance, defaults.drift_percent_distance);
  EXPECT_EQ(d.fix_correlated_fraction, defaults.fix_correlated_fraction);
  EXPECT_EQ(d.scale_sigma_percent, 0.0);
}

TEST(AnchoredPosition, TheOffsetKeepsItsDirectionAcrossAPole) {
  // The filter works in the ENU frame of the DR origin, 1500 m from the North Pole on meridian 0;
  // the DR has driven across the pole to 300 m beyond it, where east and north point the other way
  // round. The anchored position is the DR plus the offset in the origin's frame wherever that is
  // (laid out in the local frame, the offset would land 2 |offset| away: 7.2 m here).
  const Geodetic origin{0.5 * kPi - 1500.0 / wgs84_radii(0.5 * kPi).meridian_m, 0.0, 10.0};
  const LocalEnuFrame frame(origin);
  const Geodetic beyond{0.5 * kPi - 300.0 / wgs84_radii(0.5 * kPi).meridian_m, kPi * 0.999, 10.0};
  AnchoredPositionFilter filter;
  const Eigen::Vector3d offset(3.0, -2.0, 0.0);
  AnchorFix fix;
  fix.t_s = 1.0;
  fix.dr_enu_m = frame.to_enu(beyond);
  fix.fix_enu_m = fix.dr_enu_m + offset;
  fix.sigma_m = 1.0;
  fix.dr_distance_m = 1800.0;
  filter.add_fix(fix);
  AnchorDrStep s;
  s.t_s = 1.2;
  s.position = beyond;
  s.enu_m = fix.dr_enu_m;
  s.distance_m = 1800.0;
  s.origin_to_local = frame.rotation_to_local(beyond);
  const AnchoredPosition p = filter.step(s);
  ASSERT_EQ(p.status, AnchorStatus::kAnchored);
  // (The step's height follows the surface, the frame's plane does not: d^2 / 2R = 1e-6 m up.)
  EXPECT_LT((frame.to_enu(p.position) - (s.enu_m + offset)).head<2>().norm(), 1e-6);
  // The published variances are those of the local axes: the same here (east and north equal; the
  // two up axes differ by 1800 m / R, which moves 1e-7 m^2 between vertical and horizontal).
  EXPECT_NEAR(p.covariance_enu_m2(0, 0), 1.0, 1e-6);
  EXPECT_NEAR(p.covariance_enu_m2(1, 1), 1.0, 1e-6);
  EXPECT_NEAR(p.covariance_enu_m2(2, 2), 2.25, 1e-6);
}
