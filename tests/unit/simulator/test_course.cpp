// Course geometry, terrain and speed profile of the simulator, checked against independent
// numerical integration and the driver limits.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "odonav/simulator/course.hpp"
#include "odonav/frames.hpp"

using namespace odonav;
using namespace odonav::simulator;

TEST(Course, TrainingGroundLapClosesAndTurnsOnceClockwise) {
  const Course c = Course::training_ground();
  ASSERT_TRUE(c.closed());
  EXPECT_GT(c.lap_length_m(), 2500.0);
  EXPECT_LT(c.lap_length_m(), 4500.0);
  EXPECT_NEAR(c.lap_turning_rad(), 2.0 * kPi, 1e-12);
  // End of the lap is the start, heading +360 deg.
  const CoursePoint end = c.at(c.lap_length_m() - 1e-9);
  EXPECT_LT(end.position_m.norm(), 1e-6);
  EXPECT_NEAR(end.heading_rad, 2.0 * kPi, 1e-9);
  // Arcs of 12-80 m radius, two sharp ones (radius < 20 m), some left turn (the S-bend).
  int sharp = 0, left = 0;
  for (const CourseSegment& s : c.segments()) {
    if (s.curvature_per_m == 0.0) continue;
    const double r = 1.0 / std::abs(s.curvature_per_m);
    EXPECT_GE(r, 12.0);
    EXPECT_LE(r, 80.0);
    sharp += r < 20.0;
    left += s.curvature_per_m < 0.0;
  }
  EXPECT_EQ(sharp, 2);
  EXPECT_GE(left, 1);
}

TEST(Course, PositionsAgreeWithIntegratedHeading) {
  // Independent: integrate (sin h, cos h) ds with the midpoint rule over 2 laps.
  const Course c = Course::training_ground();
  const double ds = 0.01;
  Eigen::Vector2d p = Eigen::Vector2d::Zero();
  double max_err = 0.0;
  const double total = 2.0 * c.lap_length_m();
  for (double s = 0.0; s < total - ds; s += ds) {
    const double h = c.at(s + 0.5 * ds).heading_rad;
    p += ds * Eigen::Vector2d(std::sin(h), std::cos(h));
    max_err = std::max(max_err, (p - c.at(s + ds).position_m).norm());
  }
  EXPECT_LT(max_err, 0.01);
  // Second lap: heading one full turn further.
  EXPECT_NEAR(c.at(c.lap_length_m() + 10.0).heading_rad - c.at(10.0).heading_rad, 2.0 * kPi, 1e-9);
}

TEST(Course, ClosedLoopRejectsBadInput) {
  const std::vector<CourseSegment> half_turn = {{100.0, 0.0, 10.0}, {kPi * 50.0, 1.0 / 50.0, 8.0}, {100.0, 0.0, 10.0}};
  EXPECT_THROW(Course::closed_loop(half_turn, 0.0, 0, 2), std::invalid_argument);  // parallel, half a turn
  EXPECT_THROW(Course::closed_loop(half_turn, 0.0, 0, 1), std::invalid_argument);  // an arc is not free
  EXPECT_THROW(Course::straight(-5.0, 0.0, 10.0), std::invalid_argument);
  EXPECT_THROW(Course::straight(100.0, 0.0, 0.0), std::invalid_argument);
}

TEST(Terrain, SlopeIsTheDerivativeAndLapsCloseInHeight) {
  const Course c = Course::training_ground();
  const TerrainProfile t(0.02, {Undulation{4.0, 570.0, 0.0}, Undulation{1.2, 200.0, 0.5}}, {}, c);
  const double h = 1e-3;
  for (double s = 0.0; s < c.lap_length_m(); s += 37.0) {
    EXPECT_NEAR(t.slope(s), (t.height_m(s + h) - t.height_m(s - h)) / (2.0 * h), 1e-7) << "s=" << s;
  }
  EXPECT_NEAR(t.height_m(0.0), 0.0, 1e-12);
  // Grade is dropped and wavelengths fit the lap: back to the start height after a lap.
  EXPECT_NEAR(t.height_m(c.lap_length_m()), 0.0, 1e-9);
  const Course road = Course::straight(1000.0, 0.0, 10.0);
  const TerrainProfile g(0.02, {}, {}, road);
  EXPECT_NEAR(g.height_m(500.0), 10.0, 1e-12);
}

TEST(SpeedProfile, StartsAndStopsAndRespectsDriverLimits) {
  const Course c = Course::training_ground();
  const DriverLimits lim;  // 1.0 / 1.5 / 1.5 m/s^2
  const SpeedProfile p(c, c.lap_length_m(), lim);
  EXPECT_EQ(p.at(0.0).speed_mps, 0.0);
  EXPECT_NEAR(p.at(p.duration_s()).s_m, c.lap_length_m(), 1e-9);
  EXPECT_EQ(p.at(p.duration_s()).speed_mps, 0.0);
  const double dt = 0.05;
  double v_max = 0.0, v_min_moving = 1e9;
  // One cursor per time series, each read forward (SpeedProfile::at reads from the start each time).
  SpeedProfile::Cursor before(p), now(p), after(p);
  for (double t = dt; t + dt < p.duration_s(); t += dt) {
    const SpeedProfile::State a = before.at(t - dt), b = now.at(t), e = after.at(t + dt);
    // ds/dt is the speed (central difference), accelerations within the limits.
    EXPECT_NEAR((e.s_m - a.s_m) / (2 * dt), b.speed_mps, 0.02) << "t=" << t;
    const double acc = (e.speed_mps - b.speed_mps) / dt;
    EXPECT_LE(acc, lim.accel_mps2 + 1e-6);
    EXPECT_GE(acc, -lim.decel_mps2 - 1e-6);
    const double lat = b.speed_mps * b.speed_mps * std::abs(c.at(b.s_m).curvature_per_m);
    EXPECT_LE(lat, lim.lateral_accel_mps2 * (1.0 + 1e-9)) << "t=" << t;
    v_max = std::max(v_max, b.speed_mps);
    if (t > 20.0 && t < p.duration_s() - 20.0) v_min_moving = std::min(v_min_moving, b.speed_mps);
  }
  // Speeds 3-15 m/s while driving the lap.
  EXPECT_GT(v_max, 13.5);
  EXPECT_LT(v_max, 15.5);
  EXPECT_GT(v_min_moving, 3.0);
  EXPECT_LT(v_min_moving, 5.0);
}

namespace {

// The speed profile built over the whole grid at once (both passes over every stored node), as
// SpeedProfile did before it generated its nodes as they are read: the reference the streamed
// grid must match bit for bit.
class WholeGridProfile {
 public:
  WholeGridProfile(const Course& course, double total_length_m, const DriverLimits& limits, double grid_step_m)
      : total_length_m_(total_length_m) {
    const std::size_t n = static_cast<std::size_t>(std::ceil(total_length_m / grid_step_m)) + 1;
    step_m_ = total_length_m / static_cast<double>(n - 1);
    v_.assign(n, 0.0);
    auto limit_at = [&](double s) {
      const CoursePoint p = course.at(s);
      const double wander = limits.speed_variation_mps *
                            (0.6 * std::sin(2.0 * kPi * s / 350.0) + 0.4 * std::sin(2.0 * kPi * s / 90.0 + 1.0));
      double v = std::max(0.5, p.target_speed_mps + wander);
      if (p.curvature_per_m != 0.0) v = std::min(v, std::sqrt(limits.lateral_accel_mps2 / std::abs(p.curvature_per_m)));
      return v;
    };
    for (std::size_t i = 0; i < n; ++i) {
      const double s = step_m_ * static_cast<double>(i);
      v_[i] = std::min({limit_at(s - step_m_), limit_at(s - 0.5 * step_m_), limit_at(s), limit_at(s + 0.5 * step_m_),
                        limit_at(s + step_m_)});
    }
    v_.front() = 0.0;
    v_.back() = 0.0;
    for (std::size_t i = 1; i < n; ++i)
      v_[i] = std::min(v_[i], std::sqrt(v_[i - 1] * v_[i - 1] + 2.0 * limits.accel_mps2 * step_m_));
    for (std::size_t i = n - 1; i-- > 0;)
      v_[i] = std::min(v_[i], std::sqrt(v_[i + 1] * v_[i + 1] + 2.0 * limits.decel_mps2 * step_m_));
    t_.assign(n, 0.0);
    for (std::size_t i = 1; i < n; ++i) t_[i] = t_[i - 1] + 2.0 * step_m_ / (v_[i - 1] + v_[i]);
  }
  double duration_s() const { return t_.back(); }
  SpeedProfile::State at(double time_s) const {
    SpeedProfile::State st;
    if (time_s <= 0.0) return st;
    if (time_s >= t_.back()) {
      st.s_m = total_length_m_;
      return st;
    }
    const std::size_t i = static_cast<std::size_t>(std::upper_bound(t_.begin(), t_.end(), time_s) - t_.begin()) - 1;
    const double v0 = v_[i], v1 = v_[i + 1];
    const double a = (v1 * v1 - v0 * v0) / (2.0 * step_m_);
    const double tau = time_s - t_[i];
    st.speed_mps = std::max(0.0, v0 + a * tau);
    st.s_m = std::min(step_m_ * static_cast<double>(i) + v0 * tau + 0.5 * a * tau * tau,
                      step_m_ * static_cast<double>(i + 1));
    return st;
  }

 private:
  double total_length_m_, step_m_;
  std::vector<double> v_, t_;
};

void expect_same_profile(const Course& course, double length_m, double step_m, double dt_s) {
  const DriverLimits limits;
  const WholeGridProfile reference(course, length_m, limits, step_m);
  const SpeedProfile streamed(course, length_m, limits, step_m);
  ASSERT_EQ(streamed.duration_s(), reference.duration_s());
  SpeedProfile::Cursor cursor(streamed);
  std::size_t differing = 0, n = 0;
  for (double t = -1.0; t < reference.duration_s() + 1.0; t += dt_s, ++n) {
    const SpeedProfile::State a = cursor.at(t), b = reference.at(t);
    if (a.s_m != b.s_m || a.speed_mps != b.speed_mps) ++differing;
  }
  EXPECT_EQ(differing, 0u) << "of " << n;
  // An earlier time starts the cursor again; SpeedProfile::at reads from the start.
  const double t_mid = 0.5 * reference.duration_s();
  EXPECT_EQ(cursor.at(t_mid).s_m, reference.at(t_mid).s_m);
  EXPECT_EQ(streamed.at(t_mid).speed_mps, reference.at(t_mid).speed_mps);
}

}  // namespace

TEST(SpeedProfile, StreamedGridIsBitForBitTheWholeGridPasses) {
  // Three laps of the training ground on the default 0.25 m grid (about 48 000 nodes).
  const Course ring = Course::training_ground();
  expect_same_profile(ring, 3.0 * ring.lap_length_m(), 0.25, 0.01);
  // A 1 cm grid: braking from 14 m/s spans about 6 500 nodes, more than one block of nodes, so the
  // look-ahead has to grow before the bounds meet.
  expect_same_profile(Course::straight(300.0, 0.3, 14.0), 300.0, 0.01, 0.001);
}
