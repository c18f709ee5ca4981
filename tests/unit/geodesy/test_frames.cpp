// Frames: the sign conventions of docs/DATASET.md pinned by rotating known vectors.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "odonav/frames.hpp"

using namespace odonav;

TEST(Frames, ForwardAxisPointsAlongHeadingAndPitch) {
  // Heading 90 deg (east), pitch +10 deg (nose up): forward is east and up.
  const Attitude att{deg_to_rad(90.0), deg_to_rad(10.0), 0.0};
  const Eigen::Vector3d f = body_to_enu(att) * Eigen::Vector3d::UnitX();
  EXPECT_NEAR(f.x(), std::cos(deg_to_rad(10.0)), 1e-12);
  EXPECT_NEAR(f.y(), 0.0, 1e-12);
  EXPECT_NEAR(f.z(), std::sin(deg_to_rad(10.0)), 1e-12);
  // Heading 0 (north): the left axis points west.
  const Eigen::Vector3d l = body_to_enu(Attitude{0.0, 0.0, 0.0}) * Eigen::Vector3d::UnitY();
  EXPECT_NEAR(l.x(), -1.0, 1e-12);
  EXPECT_NEAR(l.y(), 0.0, 1e-12);
}

TEST(Frames, PositiveRollPutsRightSideDown) {
  // Heading north, roll +20 deg: the left axis rises, so the up component of left is positive.
  const Attitude att{0.0, 0.0, deg_to_rad(20.0)};
  const Eigen::Vector3d l = body_to_enu(att) * Eigen::Vector3d::UnitY();
  EXPECT_NEAR(l.z(), std::sin(deg_to_rad(20.0)), 1e-12);
}

TEST(Frames, MisalignmentAxisMatchesDatasetConvention) {
  const Misalignment mis{deg_to_rad(0.8), deg_to_rad(-0.5)};
  const Eigen::Vector3d u = odometer_to_body(mis) * Eigen::Vector3d::UnitX();
  EXPECT_NEAR(u.x(), std::cos(mis.heading_rad) * std::cos(mis.pitch_rad), 1e-15);
  EXPECT_NEAR(u.y(), std::sin(mis.heading_rad) * std::cos(mis.pitch_rad), 1e-15);
  EXPECT_NEAR(u.z(), std::sin(mis.pitch_rad), 1e-15);
  EXPECT_GT(u.y(), 0.0);  // turned to the left
  EXPECT_LT(u.z(), 0.0);  // negative pitch misalignment points down
  EXPECT_LT((u - odometer_axis_in_body(mis)).norm(), 1e-15);
}

TEST(Frames, ForwardSpeedAlongOdometerOfKnownVelocity) {
  // Vehicle heading 30 deg, the odometer axis 2 deg left of the INS axis; motion along the
  // odometer axis at 10 m/s must project to exactly 10 m/s.
  const Attitude att{deg_to_rad(30.0), deg_to_rad(3.0), deg_to_rad(-4.0)};
  const Misalignment mis{deg_to_rad(2.0), deg_to_rad(1.0)};
  const Eigen::Vector3d v_n = body_to_enu(att) * odometer_to_body(mis) * Eigen::Vector3d(10.0, 0, 0);
  EXPECT_NEAR(forward_speed_along_odometer(v_n, att, mis), 10.0, 1e-12);
  // Without the misalignment the INS-forward projection is 10 cos(2 deg) cos(1 deg).
  EXPECT_NEAR(forward_speed_along_odometer(v_n, att, Misalignment{}),
              10.0 * std::cos(deg_to_rad(2.0)) * std::cos(deg_to_rad(1.0)), 1e-12);
}

TEST(Frames, AttitudeInterpolationTakesShortestHeadingArc) {
  const Attitude a{deg_to_rad(350.0), 0.0, 0.0}, b{deg_to_rad(10.0), deg_to_rad(2.0), 0.0};
  const Attitude m = interpolate_attitude(a, b, 0.5);
  EXPECT_NEAR(rad_to_deg(wrap_pi(m.heading_rad)), 0.0, 1e-9);
  EXPECT_NEAR(rad_to_deg(m.pitch_rad), 1.0, 1e-9);
}

TEST(Frames, ExactDegreesAndRadiansInvertTheConversionsToTheLastBit) {
  // deg_to_rad(exact_degrees_of(r)) == r for every r that came from degrees (what a file holds), and
  // rad_to_deg(exact_radians_of(d)) == d for every d that came from radians (what a message holds),
  // although the plain round trips rad_to_deg(deg_to_rad(d)) miss by an ulp for some of them.
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> deg(-180.0, 180.0);
  int plain_degree_misses = 0, plain_radian_misses = 0;
  for (int i = 0; i < 20000; ++i) {
    const double r = deg_to_rad(deg(rng));
    ASSERT_EQ(deg_to_rad(exact_degrees_of(r)), r);
    plain_degree_misses += deg_to_rad(rad_to_deg(r)) != r;
    const double d = rad_to_deg(deg_to_rad(deg(rng)) * 0.999);
    ASSERT_EQ(rad_to_deg(exact_radians_of(d)), d);
    plain_radian_misses += rad_to_deg(deg_to_rad(d)) != d;
  }
  EXPECT_GT(plain_degree_misses, 100);  // the walk is needed
  EXPECT_GT(plain_radian_misses, 100);
  EXPECT_EQ(exact_degrees_of(deg_to_rad(45.0)), 45.0);
  EXPECT_EQ(exact_radians_of(rad_to_deg(0.5)), 0.5);
  EXPECT_TRUE(std::isnan(exact_radians_of(std::nan(""))));
  EXPECT_EQ(exact_degrees_of(-std::numeric_limits<double>::infinity()), -std::numeric_limits<double>::infinity());
}
