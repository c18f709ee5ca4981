#pragma once
// The simulated vehicle's road: horizontal geometry (straights and circular arcs), the height
// profile along it, and the speed profile a driver would follow on it.
//
// Everything here is a function of the HORIZONTAL arc length s_m along the road (metres from the
// start of the road). Headings are true azimuths, clockwise from north, in radians, and are kept
// unwrapped (a clockwise lap adds +2*pi) so lap counts can be read off them. Curvature is positive
// for a right (clockwise) turn, in 1/m.
#include <Eigen/Dense>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

namespace odonav::simulator {

/// One piece of road: a straight (curvature 0) or a circular arc of constant curvature.
struct CourseSegment {
  double length_m = 0.0;          ///< horizontal length, > 0.
  double curvature_per_m = 0.0;   ///< +1/radius for a right turn, -1/radius for a left turn, 0 straight.
  double target_speed_mps = 0.0;  ///< the speed the driver aims for on this piece (> 0), m/s.
};

/// The road at one point.
struct CoursePoint {
  double heading_rad = 0.0;                              ///< azimuth of the direction of travel, unwrapped.
  double curvature_per_m = 0.0;                          ///< see CourseSegment.
  double target_speed_mps = 0.0;                         ///< driver's aim before lateral-acceleration limits.
  Eigen::Vector2d position_m = Eigen::Vector2d::Zero();  ///< (east, north) on a flat plane from the start, m.
};

/// A road made of segments; either an open road driven once, or a closed lap driven repeatedly
/// (s beyond one lap continues on the next lap, with headings increasing by the lap's turning).
class Course {
 public:
  /// A straight road of length_m (> 0) at azimuth heading_rad, aimed at speed_mps (> 0).
  static Course straight(double length_m, double heading_rad, double speed_mps);

  /// The closed training-ground lap used by the ring and terrain scenarios: straights joined by
  /// arcs of 40-80 m radius, an S-bend and two sharp turns (12 m and 15 m radius), driven
  /// clockwise (heading +2*pi per lap), starting north-bound at the origin. Two straight lengths are
  /// solved so the lap closes exactly. About 4.0 km per lap.
  static Course training_ground();

  /// A closed course from segments; free_a and free_b are the indices of two straights with
  /// non-parallel directions whose lengths are solved so the lap closes in position. The total
  /// turning of the segments must be a multiple of 2*pi. Throws std::invalid_argument otherwise, or
  /// if the solved lengths are not positive.
  static Course closed_loop(std::vector<CourseSegment> segments, double start_heading_rad, std::size_t free_a,
                            std::size_t free_b);

  bool closed() const { return closed_; }
  /// Horizontal length of the road (open) or of one lap (closed), metres.
  double lap_length_m() const { return lap_length_m_; }
  /// Heading change over one lap, radians (2*pi for a clockwise closed lap, 0 for a straight road).
  double lap_turning_rad() const { return lap_turning_rad_; }
  const std::vector<CourseSegment>& segments() const { return segments_; }

  /// The road at horizontal arc length s_m (>= 0). For an open road s_m beyond the end continues
  /// straight on; for a closed course it wraps into the following laps.
  CoursePoint at(double s_m) const;

 private:
  std::vector<CourseSegment> segments_;
  std::vector<double> start_s_m_;             // arc length at the start of each segment (one lap)
  std::vector<double> start_heading_rad_;     // heading at the start of each segment
  std::vector<Eigen::Vector2d> start_pos_m_;  // position at the start of each segment
  double lap_length_m_ = 0.0;
  double lap_turning_rad_ = 0.0;
  bool closed_ = false;
  void build(double start_heading_rad);
};

/// One sinusoidal undulation of the ground along the road.
struct Undulation {
  double amplitude = 0.0;     ///< metres for heights, radians for cross-slope roll.
  double wavelength_m = 1.0;  ///< along the road, > 0. On a closed course it is rounded so a whole
                              ///< number of waves fits in one lap (the lap closes in height).
  double phase_rad = 0.0;
};

/// Ground shape along the road: height above the start and the cross-slope (roll of the ground).
class TerrainProfile {
 public:
  /// grade: constant slope dh/ds (dimensionless, 0.01 = 1 %), forced to 0 on a closed course.
  TerrainProfile(double grade, std::vector<Undulation> hills, std::vector<Undulation> cross_slopes,
                 const Course& course);
  /// Height above the start of the road at s_m, metres.
  double height_m(double s_m) const;
  /// dh/ds at s_m (dimensionless); the road's pitch is atan of it.
  double slope(double s_m) const;
  /// Roll of the ground at s_m, radians, positive right side down.
  double cross_slope_rad(double s_m) const;

 private:
  double grade_;
  std::vector<Undulation> hills_, cross_;
};

/// Limits of the driver (all > 0).
struct DriverLimits {
  double accel_mps2 = 1.0;           ///< forward acceleration of a heavy tracked vehicle.
  double decel_mps2 = 1.5;           ///< braking.
  double lateral_accel_mps2 = 1.5;   ///< cornering: speed in an arc <= sqrt(a_lat * radius).
  double speed_variation_mps = 0.4;  ///< amplitude of the slow speed wander on top of the target.
};

/// A drive along the road as phases of constant acceleration, forward AND backward (a signed speed
/// along the road's arc length): the stop-and-go and reversing manoeuvres of a slow robot, which
/// the one-way SpeedProfile cannot express. Starts at s = 0, standstill.
class MotionPlan {
 public:
  struct State {
    double s_m = 0.0;        ///< arc length along the road (decreases while reversing).
    double speed_mps = 0.0;  ///< signed ds/dt: negative while reversing.
  };
  /// Accelerates (|accel_mps2| > 0) from the current speed to speed_mps (signed), then holds it
  /// for hold_s seconds (>= 0).
  void go(double speed_mps, double accel_mps2, double hold_s);
  /// Stands still for dwell_s seconds (the speed must already be 0: after go(0, ...)).
  void dwell(double dwell_s);
  double duration_s() const { return phases_.empty() ? 0.0 : phases_.back().t0_s + phases_.back().duration_s; }
  /// Largest arc length reached (the road must be at least this long).
  double max_s_m() const { return max_s_m_; }
  /// State at time_s after the start, clamped to [0, duration_s()].
  State at(double time_s) const;

 private:
  struct Phase {
    double t0_s, s0_m, v0_mps, accel_mps2, duration_s;
  };
  void add(double accel_mps2, double length_s);
  State end() const;
  std::vector<Phase> phases_;
  double max_s_m_ = 0.0;
};

/// The horizontal speed along the road as a function of time: starts from standstill at s = 0,
/// stops at s = total_length_m. Built on a grid of grid_step_m: the speed limit at each node is the
/// segment target (plus a slow deterministic wander), capped by the cornering limit, then forward
/// (acceleration) and backward (braking) passes. Between nodes v^2 is linear in s, i.e. the
/// acceleration is constant, so position and speed at any time are exact closed forms.
///
/// The grid is not stored: the nodes are generated in order when read (Cursor), in memory that does
/// not depend on the road length. The braking pass looks ahead only as far as braking can reach;
/// how far is decided exactly (the pass is run from a lower and an upper bound of the speed ahead
/// until both give the same node speed, after which every node below is the same), so every node
/// has the bits the pass over the whole grid gives.
class SpeedProfile {
 public:
  SpeedProfile(const Course& course, double total_length_m, const DriverLimits& limits, double grid_step_m = 0.25);
  /// Time from start to stop, seconds.
  double duration_s() const { return duration_s_; }
  double total_length_m() const { return total_length_m_; }
  struct State {
    double s_m = 0.0;        ///< horizontal arc length travelled.
    double speed_mps = 0.0;  ///< horizontal speed ds/dt.
  };
  /// State at time_s after the start; clamped to [0, duration_s()]. Reads the grid from the start
  /// up to time_s: for a sequence of times, use a Cursor.
  State at(double time_s) const;

  class Nodes;
  /// Reads the profile forward in time: at() with non-decreasing times costs a bounded amount per
  /// grid node passed; an earlier time than the last one starts again from the beginning. Holds a
  /// pointer to the profile, which must outlive it.
  class Cursor {
   public:
    explicit Cursor(const SpeedProfile& profile);
    ~Cursor();
    Cursor(Cursor&&) noexcept;
    Cursor& operator=(Cursor&&) noexcept;
    /// As SpeedProfile::at.
    State at(double time_s);

   private:
    void restart();
    const SpeedProfile* profile_;
    std::unique_ptr<Nodes> nodes_;
    std::size_t index_ = 0;                                                           // grid index of node a_
    double a_speed_mps_ = 0.0, a_time_s_ = 0.0, b_speed_mps_ = 0.0, b_time_s_ = 0.0;  // nodes index_, index_ + 1
  };

 private:
  double limit_mps(std::size_t i) const;  // node speed limit before the passes
  Course course_;
  DriverLimits limits_;
  double total_length_m_;
  double step_m_;
  std::size_t n_;  // grid nodes, both ends included
  double duration_s_;
};

}  // namespace odonav::simulator
