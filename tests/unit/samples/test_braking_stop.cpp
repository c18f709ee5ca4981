// Braking to a standstill (braking_stop.hpp): the motion phase of an epoch from its speed and the
// speed of an epoch a baseline earlier, alone and over a simulated speed profile.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>

#include "odonav/braking_stop.hpp"

using namespace odonav;

TEST(BrakingStop, ClassifyMotionByTheSpeedAndItsFallOverTheBaseline) {
  const BrakingStopParams p;  // 0.3 m/s^2, 0.3 m/s
  EXPECT_EQ(classify_motion(10.0, 10.0, 1.0, p), MotionPhase::kDriving);
  EXPECT_EQ(classify_motion(10.0, 10.25, 1.0, p), MotionPhase::kDriving);           // accelerating
  EXPECT_EQ(classify_motion(10.0, 9.75, 1.0, p), MotionPhase::kDriving);            // 0.25 m/s^2: a cruise's wander
  EXPECT_EQ(classify_motion(10.0, 8.5, 1.0, p), MotionPhase::kBraking);             // 1.5 m/s^2
  EXPECT_EQ(classify_motion(10.0, 9.35, 2.0, p), MotionPhase::kBraking);            // 0.325 m/s^2 over 2 s
  EXPECT_EQ(classify_motion(-2.0, -1.0, 1.0, p), MotionPhase::kBraking);            // reversing, slowing down
  EXPECT_EQ(classify_motion(-1.0, -2.0, 1.0, p), MotionPhase::kDriving);            // reversing, speeding up
  EXPECT_EQ(classify_motion(1.5, 0.29, 1.0, p), MotionPhase::kStandstill);          // below 0.3 m/s
  EXPECT_EQ(classify_motion(0.0, -0.2, 1.0, p), MotionPhase::kStandstill);          // GNSS noise at rest
  EXPECT_EQ(classify_motion(std::nan(""), 0.1, 0.0, p), MotionPhase::kStandstill);  // no reference needed
  EXPECT_EQ(classify_motion(std::nan(""), 5.0, 1.0, p), MotionPhase::kUnknown);
  EXPECT_EQ(classify_motion(5.0, std::nan(""), 1.0, p), MotionPhase::kUnknown);
  EXPECT_EQ(classify_motion(5.0, 4.0, 0.0, p), MotionPhase::kUnknown);
  BrakingStopParams bad;
  bad.braking_mps2 = 0.0;
  EXPECT_THROW(validate(bad), std::invalid_argument);
  bad = BrakingStopParams{};
  bad.max_reference_age_s = 0.5;  // shorter than the baseline: never a reference
  EXPECT_THROW(validate(bad), std::invalid_argument);
}

// A drive at 10 m/s, braking at 1.5 m/s^2 to a standstill, with 10 Hz GNSS speeds of 0.05 m/s noise
// (fixed seed): the cruise is never braking, the braking is found within 0.3 s of its start, and
// the standstill from the first epoch below 0.3 m/s.
TEST(BrakingStop, TheTrackerFindsTheBrakingAndTheStandstillOfANoisyDrive) {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> noise(0.0, 0.05);
  MotionPhaseTracker tracker;
  const double brake_t = 30.0, decel = 1.5, v0 = 10.0;
  double first_braking = -1.0, first_standstill = -1.0;
  int cruise_braking = 0;
  for (int i = 0; i <= 500; ++i) {
    const double t = 0.1 * i;
    const double v = t < brake_t ? v0 : std::max(0.0, v0 - decel * (t - brake_t));
    const MotionPhase phase = tracker.add(t, v + noise(rng));
    if (t < 1.0 - 1e-9) {
      EXPECT_EQ(phase, MotionPhase::kUnknown) << t;  // no epoch a baseline earlier yet
      continue;
    }
    if (t < brake_t && phase != MotionPhase::kDriving) ++cruise_braking;
    if (t >= brake_t && phase == MotionPhase::kBraking && first_braking < 0.0) first_braking = t;
    if (phase == MotionPhase::kStandstill && first_standstill < 0.0) first_standstill = t;
  }
  EXPECT_EQ(cruise_braking, 0);
  EXPECT_GE(first_braking, brake_t);
  EXPECT_LE(first_braking, brake_t + 0.3 + 1e-9);
  // v = 0.3 m/s at 30 + 9.7 / 1.5 = 36.47 s; the noise moves that by a few epochs at most.
  EXPECT_NEAR(first_standstill, brake_t + (v0 - 0.3) / decel, 0.25);
  // The state round-trips.
  MotionPhaseTracker copy;
  copy.restore(tracker.state());
  EXPECT_EQ(copy.state(), tracker.state());
  EXPECT_THROW(copy.restore({1.0}), std::invalid_argument);
  EXPECT_THROW(copy.restore({2.0, 1.0, 1.0, 1.0}), std::invalid_argument);
}
