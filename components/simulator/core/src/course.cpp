#include "odonav/simulator/course.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <deque>
#include <sstream>
#include <stdexcept>

#include "odonav/frames.hpp"

namespace odonav::simulator {

namespace {

Eigen::Vector2d direction(double heading_rad) { return {std::sin(heading_rad), std::cos(heading_rad)}; }

// Displacement along a segment of constant curvature after length_m, from heading heading_rad.
Eigen::Vector2d segment_displacement(double heading_rad, double curvature_per_m, double length_m) {
  if (curvature_per_m == 0.0) return length_m * direction(heading_rad);
  const double end = heading_rad + curvature_per_m * length_m;
  return Eigen::Vector2d(std::cos(heading_rad) - std::cos(end), std::sin(end) - std::sin(heading_rad)) /
         curvature_per_m;
}

void check_segment(const CourseSegment& seg, std::size_t index) {
  if (!(seg.length_m > 0.0) || !std::isfinite(seg.length_m) || !std::isfinite(seg.curvature_per_m) ||
      !(seg.target_speed_mps > 0.0)) {
    std::ostringstream msg;
    msg << "course segment " << index << ": length_m (" << seg.length_m << ") and target_speed_mps ("
        << seg.target_speed_mps << ") must be > 0 and curvature_per_m finite";
    throw std::invalid_argument(msg.str());
  }
}

}  // namespace

void Course::build(double start_heading_rad) {
  start_s_m_.clear();
  start_heading_rad_.clear();
  start_pos_m_.clear();
  double s = 0.0, heading = start_heading_rad;
  Eigen::Vector2d pos = Eigen::Vector2d::Zero();
  for (std::size_t i = 0; i < segments_.size(); ++i) {
    check_segment(segments_[i], i);
    start_s_m_.push_back(s);
    start_heading_rad_.push_back(heading);
    start_pos_m_.push_back(pos);
    pos += segment_displacement(heading, segments_[i].curvature_per_m, segments_[i].length_m);
    heading += segments_[i].curvature_per_m * segments_[i].length_m;
    s += segments_[i].length_m;
  }
  lap_length_m_ = s;
  lap_turning_rad_ = heading - start_heading_rad;
}

Course Course::straight(double length_m, double heading_rad, double speed_mps) {
  Course c;
  c.segments_ = {CourseSegment{length_m, 0.0, speed_mps}};
  c.closed_ = false;
  c.build(heading_rad);
  return c;
}

Course Course::closed_loop(std::vector<CourseSegment> segments, double start_heading_rad, std::size_t free_a,
                           std::size_t free_b) {
  if (free_a >= segments.size() || free_b >= segments.size() || free_a == free_b ||
      segments[free_a].curvature_per_m != 0.0 || segments[free_b].curvature_per_m != 0.0) {
    throw std::invalid_argument("Course::closed_loop: free_a and free_b must be two different straight segments");
  }
  Course c;
  c.segments_ = std::move(segments);
  c.closed_ = true;
  // Lengths of straights do not change headings, so the displacement is linear in the two free
  // lengths: d_fixed + L_a * dir(h_a) + L_b * dir(h_b) = 0.
  c.segments_[free_a].length_m = 1.0;
  c.segments_[free_b].length_m = 1.0;
  c.build(start_heading_rad);
  const double turns = c.lap_turning_rad_ / (2.0 * kPi);
  if (std::abs(turns - std::round(turns)) > 1e-9 || std::round(turns) == 0.0) {
    throw std::invalid_argument("Course::closed_loop: the segments turn " + std::to_string(turns) +
                                " times; a closed lap needs a non-zero whole number");
  }
  const Eigen::Vector2d da = direction(c.start_heading_rad_[free_a]);
  const Eigen::Vector2d db = direction(c.start_heading_rad_[free_b]);
  Eigen::Vector2d d_fixed = Eigen::Vector2d::Zero();
  {
    double heading = start_heading_rad;
    for (std::size_t i = 0; i < c.segments_.size(); ++i) {
      if (i != free_a && i != free_b) {
        d_fixed += segment_displacement(heading, c.segments_[i].curvature_per_m, c.segments_[i].length_m);
      }
      heading += c.segments_[i].curvature_per_m * c.segments_[i].length_m;
    }
  }
  Eigen::Matrix2d a;
  a.col(0) = da;
  a.col(1) = db;
  if (std::abs(a.determinant()) < 1e-6) {
    throw std::invalid_argument("Course::closed_loop: the two free straights are parallel");
  }
  const Eigen::Vector2d lengths = a.inverse() * (-d_fixed);
  if (!(lengths.x() > 1.0) || !(lengths.y() > 1.0)) {
    std::ostringstream msg;
    msg << "Course::closed_loop: solved free straight lengths " << lengths.x() << " m and " << lengths.y()
        << " m; both must be positive: lengthen or shorten the fixed segments";
    throw std::invalid_argument(msg.str());
  }
  c.segments_[free_a].length_m = lengths.x();
  c.segments_[free_b].length_m = lengths.y();
  c.build(start_heading_rad);
  return c;
}

Course Course::training_ground() {
  const double deg = kPi / 180.0;
  // Arc helper: a right turn of angle_deg (negative: left) on radius_m, at a speed the driver would
  // like (cornering limits it further in SpeedProfile).
  auto arc = [deg](double angle_deg, double radius_m, double speed_mps) {
    const double sign = angle_deg >= 0 ? 1.0 : -1.0;
    return CourseSegment{std::abs(angle_deg) * deg * radius_m, sign / radius_m, speed_mps};
  };
  auto straight = [](double length_m, double speed_mps) { return CourseSegment{length_m, 0.0, speed_mps}; };
  std::vector<CourseSegment> s = {
      straight(600.0, 14.0),   // 0: north-bound main straight
      arc(90.0, 60.0, 12.0),   // 1: -> east
      straight(400.0, 12.0),   // 2
      arc(-40.0, 50.0, 10.0),  // 3: S-bend, left ...
      arc(40.0, 50.0, 10.0),   // 4: ... and right again, -> east
      straight(1.0, 14.6),     // 5: free length (east)
      arc(90.0, 12.0, 5.0),    // 6: sharp turn -> south
      straight(500.0, 5.0),    // 7: rough section, slow
      straight(1.0, 14.0),     // 8: free length (south)
      arc(45.0, 80.0, 12.0),   // 9: -> south-west
      straight(350.0, 12.0),   // 10
      arc(45.0, 80.0, 12.0),   // 11: -> west
      straight(700.0, 14.6),   // 12
      arc(60.0, 40.0, 10.0),   // 13: -> north-north-west
      straight(300.0, 10.0),   // 14
      arc(30.0, 15.0, 6.0),    // 15: sharp turn -> north, back to the start
  };
  return closed_loop(std::move(s), 0.0, 5, 8);
}

CoursePoint Course::at(double s_m) const {
  double s = std::max(0.0, s_m);
  double heading_offset = 0.0;
  if (closed_) {
    const double lap = std::floor(s / lap_length_m_);
    s -= lap * lap_length_m_;
    heading_offset = lap * lap_turning_rad_;
  }
  std::size_t i =
      static_cast<std::size_t>(std::upper_bound(start_s_m_.begin(), start_s_m_.end(), s) - start_s_m_.begin()) - 1;
  const CourseSegment& seg = segments_[i];
  const double u = s - start_s_m_[i];  // for an open road may exceed the segment: runs on straight
  CoursePoint p;
  p.target_speed_mps = seg.target_speed_mps;
  if (!closed_ && u > seg.length_m) {
    const double end_heading = start_heading_rad_[i] + seg.curvature_per_m * seg.length_m;
    p.heading_rad = end_heading + heading_offset;
    p.curvature_per_m = 0.0;
    p.position_m = start_pos_m_[i] + segment_displacement(start_heading_rad_[i], seg.curvature_per_m, seg.length_m) +
                   (u - seg.length_m) * direction(end_heading);
    return p;
  }
  p.heading_rad = start_heading_rad_[i] + seg.curvature_per_m * u + heading_offset;
  p.curvature_per_m = seg.curvature_per_m;
  p.position_m = start_pos_m_[i] + segment_displacement(start_heading_rad_[i], seg.curvature_per_m, u);
  return p;
}

TerrainProfile::TerrainProfile(double grade, std::vector<Undulation> hills, std::vector<Undulation> cross_slopes,
                               const Course& course)
    : grade_(course.closed() ? 0.0 : grade), hills_(std::move(hills)), cross_(std::move(cross_slopes)) {
  for (auto* list : {&hills_, &cross_}) {
    for (Undulation& u : *list) {
      if (!(u.wavelength_m > 0.0) || !std::isfinite(u.amplitude)) {
        throw std::invalid_argument("terrain undulation: wavelength_m must be > 0 and amplitude finite");
      }
      if (course.closed()) {
        const double n = std::max(1.0, std::round(course.lap_length_m() / u.wavelength_m));
        u.wavelength_m = course.lap_length_m() / n;
      }
    }
  }
}

double TerrainProfile::height_m(double s_m) const {
  double h = grade_ * s_m;
  // Each wave starts at zero height so the road starts at the start height.
  for (const Undulation& u : hills_) {
    h += u.amplitude * (std::sin(2.0 * kPi * s_m / u.wavelength_m + u.phase_rad) - std::sin(u.phase_rad));
  }
  return h;
}

double TerrainProfile::slope(double s_m) const {
  double d = grade_;
  for (const Undulation& u : hills_) {
    d += u.amplitude * 2.0 * kPi / u.wavelength_m * std::cos(2.0 * kPi * s_m / u.wavelength_m + u.phase_rad);
  }
  return d;
}

double TerrainProfile::cross_slope_rad(double s_m) const {
  double r = 0.0;
  for (const Undulation& u : cross_) r += u.amplitude * std::sin(2.0 * kPi * s_m / u.wavelength_m + u.phase_rad);
  return r;
}

// The grid nodes of a SpeedProfile in order, each with its speed after both passes and its
// arrival time. The forward (acceleration) pass runs node by node. The backward (braking) pass
// over a block of nodes ahead is run twice from the block's last node: from the forward speed
// there (an upper bound of the final speed) and from 0 (a lower bound). Both passes are monotone,
// so the final speed of every node lies between the two; at the first node (going back) where the
// two agree, the final speed is known, and every node below it follows from it exactly as in the
// pass over the whole grid. Those nodes are handed out; the block is lengthened when the bounds
// do not meet in it (braking from a high speed reaches further than the block). Memory: a block.
class SpeedProfile::Nodes {
 public:
  struct Node {
    double speed_mps;
    double time_s;
  };
  explicit Nodes(const SpeedProfile& profile)
      : p_(profile),
        accel_term_(2.0 * profile.limits_.accel_mps2 * profile.step_m_),
        decel_term_(2.0 * profile.limits_.decel_mps2 * profile.step_m_),
        time_step_(2.0 * profile.step_m_) {}
  bool done() const { return next_ == p_.n_; }
  /// The next node (done() must be false).
  Node next() {
    if (ready_.empty()) settle_more();
    const double v = ready_.front();
    ready_.pop_front();
    // Constant acceleration in a cell: time = 2 ds / (v0 + v1), finite even from standstill.
    const double t = next_ == 0 ? 0.0 : time_s_ + time_step_ / (speed_mps_ + v);
    ++next_;
    speed_mps_ = v;
    time_s_ = t;
    return Node{v, t};
  }

 private:
  static constexpr std::size_t kBlock = 4096;

  // Extends the forward pass to node `end` (exclusive).
  void forward_to(std::size_t end) {
    for (; forward_end_ < end; ++forward_end_) {
      const std::size_t i = forward_end_;
      double v = p_.limit_mps(i);
      if (i > 0) v = std::min(v, std::sqrt(forward_last_ * forward_last_ + accel_term_));
      forward_.push_back(v);
      forward_last_ = v;
    }
  }

  // Moves the nodes from settled_ on whose final speed is known into ready_.
  void settle_more() {
    for (std::size_t block = kBlock;; block *= 2) {
      const std::size_t end = std::min(p_.n_, settled_ + block);
      forward_to(end);
      // At the last grid node the final speed is the forward one (the braking pass starts there).
      const bool at_road_end = end == p_.n_;
      double upper = forward_[end - 1 - settled_];
      double lower = at_road_end ? upper : 0.0;
      std::size_t meet = upper == lower ? end - 1 : p_.n_;
      backward_.assign(end - settled_, 0.0);
      backward_[end - 1 - settled_] = upper;
      for (std::size_t i = end - 1; i-- > settled_;) {
        const double f = forward_[i - settled_];
        upper = std::min(f, std::sqrt(upper * upper + decel_term_));
        backward_[i - settled_] = upper;
        if (meet == p_.n_) {
          lower = std::min(f, std::sqrt(lower * lower + decel_term_));
          if (lower == upper) meet = i;
        }
      }
      if (meet == p_.n_) continue;  // not settled in this block: look further ahead
      const std::size_t count = meet + 1 - settled_;
      ready_.insert(ready_.end(), backward_.begin(), backward_.begin() + static_cast<std::ptrdiff_t>(count));
      forward_.erase(forward_.begin(), forward_.begin() + static_cast<std::ptrdiff_t>(count));
      settled_ += count;
      return;
    }
  }

  const SpeedProfile& p_;
  const double accel_term_, decel_term_, time_step_;
  std::deque<double> forward_;  // forward-pass speeds of nodes [settled_, forward_end_)
  std::size_t forward_end_ = 0;
  double forward_last_ = 0.0;
  std::vector<double> backward_;  // scratch of settle_more
  std::deque<double> ready_;      // final speeds of nodes [next_, settled_)
  std::size_t settled_ = 0;
  std::size_t next_ = 0;
  double speed_mps_ = 0.0, time_s_ = 0.0;  // node next_ - 1
};

SpeedProfile::SpeedProfile(const Course& course, double total_length_m, const DriverLimits& limits, double grid_step_m)
    : course_(course), limits_(limits), total_length_m_(total_length_m) {
  if (!(grid_step_m > 0.0) || !(total_length_m >= 4.0 * grid_step_m) || !std::isfinite(total_length_m)) {
    throw std::invalid_argument("SpeedProfile: total_length_m (" + std::to_string(total_length_m) +
                                ") must be finite and at least 4 grid steps of " + std::to_string(grid_step_m) + " m");
  }
  if (!(limits.accel_mps2 > 0.0) || !(limits.decel_mps2 > 0.0) || !(limits.lateral_accel_mps2 > 0.0) ||
      !(limits.speed_variation_mps >= 0.0)) {
    throw std::invalid_argument(
        "SpeedProfile: accel_mps2, decel_mps2, lateral_accel_mps2 must be > 0, "
        "speed_variation_mps >= 0");
  }
  n_ = static_cast<std::size_t>(std::ceil(total_length_m / grid_step_m)) + 1;
  step_m_ = total_length_m / static_cast<double>(n_ - 1);
  // The arrival time at the last node, read through once.
  Nodes nodes(*this);
  double time_s = 0.0;
  while (!nodes.done()) time_s = nodes.next().time_s;
  duration_s_ = time_s;
}

double SpeedProfile::limit_mps(std::size_t i) const {
  auto limit_at = [&](double s) {
    const CoursePoint p = course_.at(s);
    // Slow wander so the speed is never perfectly constant (two incommensurate wavelengths).
    const double wander = limits_.speed_variation_mps *
                          (0.6 * std::sin(2.0 * kPi * s / 350.0) + 0.4 * std::sin(2.0 * kPi * s / 90.0 + 1.0));
    double v = std::max(0.5, p.target_speed_mps + wander);
    if (p.curvature_per_m != 0.0) v = std::min(v, std::sqrt(limits_.lateral_accel_mps2 / std::abs(p.curvature_per_m)));
    return v;
  };
  // Standstill at both ends.
  if (i == 0 || i + 1 == n_) return 0.0;
  const double s = step_m_ * static_cast<double>(i);
  // The node's limit covers the cells either side (segments are longer than a step), so v^2,
  // linear in between, cannot exceed a limit anywhere in a cell that touches an arc.
  return std::min({limit_at(s - step_m_), limit_at(s - 0.5 * step_m_), limit_at(s), limit_at(s + 0.5 * step_m_),
                   limit_at(s + step_m_)});
}

SpeedProfile::Cursor::Cursor(const SpeedProfile& profile) : profile_(&profile) { restart(); }
SpeedProfile::Cursor::~Cursor() = default;
SpeedProfile::Cursor::Cursor(Cursor&&) noexcept = default;
SpeedProfile::Cursor& SpeedProfile::Cursor::operator=(Cursor&&) noexcept = default;

void SpeedProfile::Cursor::restart() {
  nodes_ = std::make_unique<Nodes>(*profile_);
  const Nodes::Node a = nodes_->next(), b = nodes_->next();
  index_ = 0;
  a_speed_mps_ = a.speed_mps;
  a_time_s_ = a.time_s;
  b_speed_mps_ = b.speed_mps;
  b_time_s_ = b.time_s;
}

SpeedProfile::State SpeedProfile::Cursor::at(double time_s) {
  const SpeedProfile& p = *profile_;
  State st;
  if (time_s <= 0.0) return st;
  if (time_s >= p.duration_s_) {
    st.s_m = p.total_length_m_;
    return st;
  }
  if (time_s < a_time_s_) restart();
  // The cell [index_, index_ + 1] with a_time_s_ <= time_s < b_time_s_ (time_s is before the last
  // node's time, so the nodes do not run out).
  while (b_time_s_ <= time_s) {
    const Nodes::Node n = nodes_->next();
    ++index_;
    a_speed_mps_ = b_speed_mps_;
    a_time_s_ = b_time_s_;
    b_speed_mps_ = n.speed_mps;
    b_time_s_ = n.time_s;
  }
  const double v0 = a_speed_mps_, v1 = b_speed_mps_;
  const double a = (v1 * v1 - v0 * v0) / (2.0 * p.step_m_);
  const double tau = time_s - a_time_s_;
  st.speed_mps = std::max(0.0, v0 + a * tau);
  st.s_m = std::min(p.step_m_ * static_cast<double>(index_) + v0 * tau + 0.5 * a * tau * tau,
                    p.step_m_ * static_cast<double>(index_ + 1));
  return st;
}

SpeedProfile::State SpeedProfile::at(double time_s) const { return Cursor(*this).at(time_s); }

MotionPlan::State MotionPlan::end() const {
  if (phases_.empty()) return State{};
  const Phase& p = phases_.back();
  return State{p.s0_m + p.v0_mps * p.duration_s + 0.5 * p.accel_mps2 * p.duration_s * p.duration_s,
               p.v0_mps + p.accel_mps2 * p.duration_s};
}

void MotionPlan::add(double accel_mps2, double length_s) {
  if (!(length_s > 0.0)) return;
  const State e = end();
  phases_.push_back(Phase{this->duration_s(), e.s_m, e.speed_mps, accel_mps2, length_s});
  const State after = end();
  max_s_m_ = std::max({max_s_m_, e.s_m, after.s_m});
}

void MotionPlan::go(double speed_mps, double accel_mps2, double hold_s) {
  if (!std::isfinite(speed_mps) || !(std::abs(accel_mps2) > 0.0) || !(hold_s >= 0.0))
    throw std::invalid_argument("MotionPlan::go: speed must be finite, |accel| > 0, hold >= 0");
  const double v0 = end().speed_mps;
  const double a = std::copysign(std::abs(accel_mps2), speed_mps - v0);
  add(a, std::abs(speed_mps - v0) / std::abs(accel_mps2));
  // The end speed exactly (no rounding left over for the hold or the next phase).
  if (!phases_.empty()) {
    Phase& last = phases_.back();
    last.accel_mps2 = (speed_mps - last.v0_mps) / last.duration_s;
  }
  add(0.0, hold_s);
}

void MotionPlan::dwell(double dwell_s) {
  if (end().speed_mps != 0.0) throw std::invalid_argument("MotionPlan::dwell: the vehicle must stand still first");
  add(0.0, dwell_s);
}

MotionPlan::State MotionPlan::at(double time_s) const {
  if (phases_.empty() || time_s <= 0.0) return State{};
  if (time_s >= duration_s()) return State{end().s_m, 0.0};
  const auto it =
      std::upper_bound(phases_.begin(), phases_.end(), time_s, [](double t, const Phase& p) { return t < p.t0_s; });
  const Phase& p = *(it - 1);
  const double tau = time_s - p.t0_s;
  return State{p.s0_m + p.v0_mps * tau + 0.5 * p.accel_mps2 * tau * tau, p.v0_mps + p.accel_mps2 * tau};
}

}  // namespace odonav::simulator
