// The consistency monitor's findings (consistency_monitor.hpp): the pure wording functions, and the
// monitor fed a synthetic drive: circles at 8 m/s with GNSS at 10 Hz, the INS heading given as is,
// negated, in radians, or the track drifting from GNSS.
#include <gtest/gtest.h>

#include <cmath>

#include "odonav/dead_reckoning/dead_reckoning_health.hpp"
#include "odonav/dead_reckoning/consistency_monitor.hpp"
#include "odonav/dead_reckoning/scale_factor_selection.hpp"
#include "dr_health_facts.hpp"

using namespace odonav;
using namespace odonav::dead_reckoning;

TEST(ConsistencyFindings, EachCauseIsNamedWithItsNumbers) {
  EXPECT_FALSE(heading_rate_finding(0.95, 2.0, 0.3));
  EXPECT_FALSE(heading_rate_finding(1.29, 2.0, 0.3));
  const auto negated = heading_rate_finding(-0.98, deg_to_rad(200.0), 0.3);
  ASSERT_TRUE(negated);
  EXPECT_NE(negated->find("INS heading turns opposite to the GNSS course (ratio -0.98 over 200 deg of turns)"),
            std::string::npos)
      << *negated;
  EXPECT_NE(negated->find("sign convention?"), std::string::npos);
  const auto radians = heading_rate_finding(1.0 / 57.0, deg_to_rad(200.0), 0.3);
  ASSERT_TRUE(radians);
  EXPECT_NE(radians->find("INS heading moves 57 times less than the GNSS course"), std::string::npos) << *radians;
  EXPECT_NE(radians->find("radians?"), std::string::npos);
  const auto other = heading_rate_finding(0.5, 2.0, 0.3);
  ASSERT_TRUE(other);
  EXPECT_NE(other->find("0.50 times as much"), std::string::npos) << *other;

  EXPECT_FALSE(drift_growth_finding(9.0, 1.0, 10.0));    // below the floor
  EXPECT_FALSE(drift_growth_finding(14.0, 15.0, 10.0));  // within what the sigmas allow
  const auto drift = drift_growth_finding(180.0, 1.0, 10.0);
  ASSERT_TRUE(drift);
  EXPECT_NE(drift->find("180.0 %D"), std::string::npos) << *drift;
  EXPECT_NE(drift->find("10.0 %D allowed"), std::string::npos) << *drift;

  EXPECT_FALSE(odometer_speed_finding(1.15, 0.2));
  const auto speed = odometer_speed_finding(2.0, 0.2);
  ASSERT_TRUE(speed);
  EXPECT_NE(speed->find("2.000 times the GNSS distance"), std::string::npos) << *speed;
  EXPECT_THROW(ConsistencyMonitor(ConsistencyParams{0.0}), std::invalid_argument);
}

namespace {
// A vehicle circling at 8 m/s with a 100 m radius (0.08 rad/s), counter-clockwise from above, for
// duration_s; GNSS at 10 Hz, outputs at 100 Hz whose heading is heading_of(true heading).
struct Drive {
  double heading_scale = 1.0;    // the heading the DR uses: scale * true (mod 2 pi)
  bool radians = false;          // the heading the DR uses: the true heading in degrees read as radians / 57.3
  double dr_error_per_m = 0.0;   // the DR drifts from GNSS by this per metre driven (east)
  double negated_until_s = 0.0;  // before this time the heading the DR uses is negated too
  bool anchor_fixes = true;      // the outputs carry the GNSS fixes (10 Hz) the drift check compares with
  double misalignment_rad = deg_to_rad(0.01);  // the calibrated heading misalignment, converged
};

ConsistencyMonitor run(const Drive& drive, double duration_s, ConsistencyParams params = {}) {
  ConsistencyMonitor m(params);
  m.set_scale_factor(0.0125, 1e-5, true);
  m.set_misalignment(drive.misalignment_rad, true);
  const double v = 8.0, r = 100.0, w = v / r;
  for (int i = 0; i <= static_cast<int>(duration_s * 100.0); ++i) {
    const double t = i * 0.01;
    // Heading (clockwise from north) of a counter-clockwise circle: decreasing.
    const double heading = wrap_two_pi(-w * t);
    if (i % 10 == 0) {
      GnssSample g;
      g.t_s = t;
      g.vel_enu_mps = Eigen::Vector3d(v * std::sin(heading), v * std::cos(heading), 0.0);
      m.add_gnss(g);
    }
    DeadReckoningOutput o;
    o.t_s = t;
    o.distance_m = v * t;
    const double scale = t < drive.negated_until_s ? -drive.heading_scale : drive.heading_scale;
    o.heading_rad = drive.radians ? deg_to_rad(heading) : wrap_two_pi(scale * heading);
    if (drive.anchor_fixes && i % 10 == 0) {
      AnchorFix f;
      f.t_s = t;
      f.dr_distance_m = o.distance_m;
      f.fix_enu_m = Eigen::Vector3d(r * std::cos(w * t), r * std::sin(w * t), 0.0);
      f.dr_enu_m = f.fix_enu_m + Eigen::Vector3d(drive.dr_error_per_m * o.distance_m, 0.0, 0.0);
      f.sigma_m = 1.0;
      o.gnss_fixes.push_back(f);
    }
    m.on_output(o);
  }
  return m;
}
}  // namespace

TEST(ConsistencyMonitor, AGoodDriveIsConsistentAndMeasuresRatiosOfOne) {
  const ConsistencyMonitor m = run(Drive{}, 120.0);
  EXPECT_TRUE(m.consistent()) << m.reason();
  EXPECT_NEAR(m.state(ConsistencyCheck::kHeadingRate).last_value, 1.0, 1e-6);
  EXPECT_NEAR(m.state(ConsistencyCheck::kOdometerSpeed).last_value, 1.0, 1e-3);
  EXPECT_NEAR(m.state(ConsistencyCheck::kDriftGrowth).last_value, 0.0, 1e-6);
}

TEST(ConsistencyMonitor, ANegatedHeadingIsRaisedAfterThePersistenceAndNamed) {
  const ConsistencyMonitor m = run(Drive{-1.0}, 60.0);
  const ConsistencyState& s = m.state(ConsistencyCheck::kHeadingRate);
  EXPECT_FALSE(m.consistent());
  EXPECT_TRUE(s.raised);
  EXPECT_EQ(s.times_raised, 1u);
  EXPECT_NEAR(s.last_value, -1.0, 1e-6);
  // Decided once 10 turning intervals (1 s each, 0.08 rad) and 1 rad of turns are in: t = 13 s,
  // then raised 5 s later.
  EXPECT_NEAR(s.raised_at_s, 18.0, 1.1);
  EXPECT_NE(m.reason().find("sign convention?"), std::string::npos) << m.reason();
}

TEST(ConsistencyMonitor, ARadianHeadingIsNamed) {
  const ConsistencyMonitor m = run(Drive{1.0, true}, 60.0);
  EXPECT_NE(m.reason().find("57 times less"), std::string::npos) << m.reason();
}

TEST(ConsistencyMonitor, ATrackDriftingFromGnssWhileConvergedIsRaisedAndNotWithoutConvergence) {
  // 20 %D against the 10 %D floor.
  const ConsistencyMonitor m = run(Drive{1.0, false, 0.2}, 120.0);
  const ConsistencyState& s = m.state(ConsistencyCheck::kDriftGrowth);
  EXPECT_TRUE(s.raised);
  EXPECT_NEAR(s.last_value, 20.0, 0.01);
  EXPECT_TRUE(m.state(ConsistencyCheck::kHeadingRate).last_value > 0.99);
  // 5 %D: within the floor.
  EXPECT_TRUE(run(Drive{1.0, false, 0.05}, 120.0).consistent());
}

TEST(ConsistencyMonitor, AFindingClearsWhenTheEvidenceAgreesAgainForThePersistence) {
  ConsistencyParams p;
  p.window_s = 20.0;  // the window forgets the negated part quickly
  Drive drive;
  drive.negated_until_s = 40.0;  // 120 s: negated for the first 40 s, right after
  drive.anchor_fixes = false;
  drive.misalignment_rad = 1e-4;
  const ConsistencyMonitor m = run(drive, 120.0, p);
  const ConsistencyState& s = m.state(ConsistencyCheck::kHeadingRate);
  EXPECT_FALSE(s.raised);
  EXPECT_EQ(s.times_raised, 1u);
  EXPECT_TRUE(m.consistent());
  EXPECT_NEAR(s.raised_at_s, 18.0, 1.1);
  EXPECT_FALSE(s.text.empty());  // the last finding is kept for the record
}

TEST(DeadReckoningHealth, AnInconsistencyWarnsWithItsFinding) {
  DeadReckoningHealthFacts f = odonav::test::running_dr_facts(1, 1);
  EXPECT_EQ(dead_reckoning_health(f).level, ComponentHealth::Level::kOk);
  f.inconsistency = "INS heading turns opposite to the GNSS course (ratio -1.00 over 200 deg of turns)";
  const ComponentHealth h = dead_reckoning_health(f);
  EXPECT_EQ(h.level, ComponentHealth::Level::kWarn);
  EXPECT_EQ(h.reason, "inconsistent: " + f.inconsistency);
}
