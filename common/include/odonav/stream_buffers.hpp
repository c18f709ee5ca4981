#pragma once
// Per-stream buffers shared by the event-time cores (sample builder, misalignment calibrator, dead
// reckoner): each buffers one input stream in increasing time and answers "what was the value at
// time t" by interpolation, so every core computes its outputs from time stamps alone, never from
// the order in which different streams were fed.
//
// Completeness rule used by every core (the "bracket"): a value at time t is computed from the last
// sample at or before t and the first sample at or after t, and only if they are at most
// max_bracket_s apart. Because each stream arrives in increasing time, once a sample at or after t is
// buffered the bracket is final; if none has arrived by the watermark t + max_bracket_s, no valid
// bracket can ever exist. Either way the answer depends on the data only.
#include <cmath>
#include <cstdint>
#include <deque>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>

#include "odonav/dataset.hpp"
#include "odonav/frames.hpp"

namespace odonav {

/// Thrown by the add_* methods of the cores and buffers on bad input (non-finite or non-increasing
/// time, non-finite values). what() names the stream, the time and the reason.
class StreamInputError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

namespace detail {
/// Checks that t_s is finite and strictly after last_t_s (when there is one); throws
/// StreamInputError naming the stream otherwise.
inline void check_stream_time(const char* stream, double t_s, const std::optional<double>& last_t_s) {
  if (!std::isfinite(t_s)) {
    std::ostringstream m;
    m << stream << ": time stamp is not finite (" << t_s << ")";
    throw StreamInputError(m.str());
  }
  if (last_t_s && !(t_s > *last_t_s)) {
    std::ostringstream m;
    m.precision(17);
    m << stream << ": time " << t_s << " s does not increase (previous " << *last_t_s << " s)";
    throw StreamInputError(m.str());
  }
}
}  // namespace detail

/// Outcome of asking a buffer for a value at a time.
enum class BracketState {
  kReady,     ///< a valid bracket exists: the value is available.
  kPending,   ///< no sample at or after t yet, and the watermark does not exclude one: wait.
  kMissing,   ///< no valid bracket can exist (gap, or t before the first sample): the value is absent.
};

/// The odometer stream. Holds the accumulated count unwrapped: each increment is taken modulo 2^32
/// (pulse_increment), so a counter wrap is not a jump. The unwrapped count starts at 0 at the first
/// sample ever added (independent of pruning, so answers never depend on when pruning happened).
class OdometerBuffer {
 public:
  struct Entry {
    double t_s = 0.0;
    int64_t count = 0;  ///< unwrapped accumulated pulses since the first sample.
    uint32_t raw_pulses = 0;
    int direction = 1;
  };

  /// max_bracket_s: the longest gap between two samples across which the count is interpolated (s, > 0).
  explicit OdometerBuffer(double max_bracket_s = 1.0) : max_bracket_s_(max_bracket_s) {}

  /// Adds one sample; its time must be finite and increase; direction must be -1, 0 or +1.
  /// Throws StreamInputError otherwise.
  void add(const OdometerSample& s) {
    detail::check_stream_time("odometer", s.t_s, last_t_s_);
    if (s.direction < -1 || s.direction > 1) {
      std::ostringstream m;
      m << "odometer: at t=" << s.t_s << " s, direction " << s.direction << " is not -1, 0 or +1";
      throw StreamInputError(m.str());
    }
    Entry e;
    e.t_s = s.t_s;
    e.raw_pulses = s.pulses;
    e.direction = s.direction;
    e.count = last_raw_ ? last_count_ + static_cast<int64_t>(pulse_increment(*last_raw_, s.pulses)) : 0;
    last_raw_ = s.pulses;
    last_count_ = e.count;
    last_t_s_ = s.t_s;
    entries_.push_back(e);
  }

  /// Whether the count at t_s (s) can be known, given that every sample with stamp <= watermark_s
  /// has been added.
  BracketState state_at(double t_s, double watermark_s) const {
    std::size_t lo = 0, hi = 0;
    return bracket(t_s, watermark_s, lo, hi);
  }

  /// Unwrapped count at t_s (pulses, linear between the bracketing samples); nullopt unless kReady.
  std::optional<double> count_at(double t_s, double watermark_s) const {
    std::size_t lo = 0, hi = 0;
    if (bracket(t_s, watermark_s, lo, hi) != BracketState::kReady) return std::nullopt;
    const Entry& a = entries_[lo];
    const Entry& b = entries_[hi];
    if (lo == hi) return static_cast<double>(a.count);
    const double f = (t_s - a.t_s) / (b.t_s - a.t_s);
    return static_cast<double>(a.count) + f * static_cast<double>(b.count - a.count);
  }

  /// True when a sample describing the interval [t0_s, t1_s] (stamped after t0_s, up to and including
  /// the first sample at or after t1_s) reports reversing (direction -1).
  bool any_reversing(double t0_s, double t1_s) const {
    for (const Entry& e : entries_) {
      if (e.t_s <= t0_s) continue;
      if (e.direction < 0) return true;
      if (e.t_s >= t1_s) break;
    }
    return false;
  }

  /// Drops samples no longer needed for times >= t_s (keeps the last sample at or before t_s).
  void drop_before(double t_s) {
    while (entries_.size() >= 2 && entries_[1].t_s <= t_s) entries_.pop_front();
  }

  const std::deque<Entry>& entries() const { return entries_; }
  std::optional<double> last_time_s() const { return last_t_s_; }
  double max_bracket_s() const { return max_bracket_s_; }

 private:
  BracketState bracket(double t_s, double watermark_s, std::size_t& lo, std::size_t& hi) const {
    if (entries_.empty() || t_s < entries_.front().t_s) {
      // Before the first buffered sample: only pending if nothing has arrived yet.
      if (entries_.empty() && watermark_s < t_s + max_bracket_s_) return BracketState::kPending;
      return BracketState::kMissing;
    }
    if (entries_.back().t_s < t_s) {
      return watermark_s < t_s + max_bracket_s_ ? BracketState::kPending : BracketState::kMissing;
    }
    std::size_t i = 0;
    while (entries_[i].t_s < t_s) ++i;  // first entry at or after t_s
    if (entries_[i].t_s == t_s) {
      lo = hi = i;
      return BracketState::kReady;
    }
    lo = i - 1;
    hi = i;
    return entries_[hi].t_s - entries_[lo].t_s <= max_bracket_s_ ? BracketState::kReady : BracketState::kMissing;
  }

  double max_bracket_s_;
  std::deque<Entry> entries_;
  std::optional<uint32_t> last_raw_;
  int64_t last_count_ = 0;
  std::optional<double> last_t_s_;
};

/// The INS attitude stream; attitude at a time by interpolate_attitude (frames.hpp).
class AttitudeBuffer {
 public:
  /// max_bracket_s: the longest gap between two samples across which attitude is interpolated (s, > 0).
  explicit AttitudeBuffer(double max_bracket_s = 1.0) : max_bracket_s_(max_bracket_s) {}

  /// Adds one sample; time must be finite and increase, angles finite, pitch in [-pi/2, pi/2].
  /// Throws StreamInputError otherwise.
  void add(const InsSample& s) {
    detail::check_stream_time("ins", s.t_s, last_t_s_);
    const Attitude& a = s.attitude;
    if (!std::isfinite(a.heading_rad) || !std::isfinite(a.pitch_rad) || !std::isfinite(a.roll_rad) ||
        std::abs(a.pitch_rad) > kPi / 2.0) {
      std::ostringstream m;
      m << "ins: at t=" << s.t_s << " s, attitude is not finite or pitch is outside [-90, 90] deg";
      throw StreamInputError(m.str());
    }
    last_t_s_ = s.t_s;
    entries_.push_back({s.t_s, a});
  }

  /// See OdometerBuffer::state_at.
  BracketState state_at(double t_s, double watermark_s) const {
    std::size_t lo = 0, hi = 0;
    return bracket(t_s, watermark_s, lo, hi);
  }

  /// Attitude at t_s (interpolated between the bracketing samples); nullopt unless kReady.
  std::optional<Attitude> attitude_at(double t_s, double watermark_s) const {
    std::size_t lo = 0, hi = 0;
    if (bracket(t_s, watermark_s, lo, hi) != BracketState::kReady) return std::nullopt;
    if (lo == hi) return entries_[lo].attitude;
    const double f = (t_s - entries_[lo].t_s) / (entries_[hi].t_s - entries_[lo].t_s);
    return interpolate_attitude(entries_[lo].attitude, entries_[hi].attitude, f);
  }

  /// Drops samples no longer needed for times >= t_s (keeps the last sample at or before t_s).
  void drop_before(double t_s) {
    while (entries_.size() >= 2 && entries_[1].t_s <= t_s) entries_.pop_front();
  }

  std::size_t size() const { return entries_.size(); }
  std::optional<double> last_time_s() const { return last_t_s_; }

 private:
  struct Entry {
    double t_s;
    Attitude attitude;
  };
  BracketState bracket(double t_s, double watermark_s, std::size_t& lo, std::size_t& hi) const {
    if (entries_.empty() || t_s < entries_.front().t_s) {
      if (entries_.empty() && watermark_s < t_s + max_bracket_s_) return BracketState::kPending;
      return BracketState::kMissing;
    }
    if (entries_.back().t_s < t_s)
      return watermark_s < t_s + max_bracket_s_ ? BracketState::kPending : BracketState::kMissing;
    std::size_t i = 0;
    while (entries_[i].t_s < t_s) ++i;
    if (entries_[i].t_s == t_s) {
      lo = hi = i;
      return BracketState::kReady;
    }
    lo = i - 1;
    hi = i;
    return entries_[hi].t_s - entries_[lo].t_s <= max_bracket_s_ ? BracketState::kReady : BracketState::kMissing;
  }

  double max_bracket_s_;
  std::deque<Entry> entries_;
  std::optional<double> last_t_s_;
};

/// A piecewise-constant value stream (misalignment, scale factor): the value in force at a time is
/// the latest one stamped at or before it (or strictly before it). Stamps must increase.
template <typename Value>
class StepHistory {
 public:
  /// name: the stream name used in error messages.
  explicit StepHistory(std::string name) : name_(std::move(name)) {}

  /// Adds a value stamped t_s (finite, increasing); throws StreamInputError otherwise.
  void add(double t_s, const Value& v) {
    detail::check_stream_time(name_.c_str(), t_s, last_t_s_);
    last_t_s_ = t_s;
    entries_.push_back({t_s, v});
  }
  /// Latest value stamped <= t_s, if any.
  /// Scans forward from the oldest kept value: after drop_before() the answer is near the front, so
  /// a core that prunes as it goes pays O(1) per query even with a whole recording buffered.
  std::optional<Value> at_or_before(double t_s) const {
    std::optional<Value> found;
    for (const auto& e : entries_) {
      if (e.first > t_s) break;
      found = e.second;
    }
    return found;
  }
  /// Latest value stamped < t_s, if any.
  std::optional<Value> before(double t_s) const {
    std::optional<Value> found;
    for (const auto& e : entries_) {
      if (!(e.first < t_s)) break;
      found = e.second;
    }
    return found;
  }
  /// Drops values that can no longer be the answer for any time >= t_s (keeps the latest one
  /// stamped strictly before t_s, which still answers before(t_s)).
  void drop_before(double t_s) {
    while (entries_.size() >= 2 && entries_[1].first < t_s) entries_.pop_front();
  }
  std::size_t size() const { return entries_.size(); }

 private:
  std::string name_;
  std::deque<std::pair<double, Value>> entries_;
  std::optional<double> last_t_s_;
};

/// GNSS course over ground (rad, clockwise from north, [0, 2 pi)) of an ENU
/// velocity (m/s). Meaningless at low speed: callers gate on speed first.
inline double gnss_course_rad(const Eigen::Vector3d& v_enu_mps) {
  return wrap_two_pi(std::atan2(v_enu_mps.x(), v_enu_mps.y()));
}

/// Validates a GNSS sample (finite time, position, velocity); throws StreamInputError naming the
/// offending field. stream: name used in the message.
inline void check_gnss_sample(const char* stream, const GnssSample& g) {
  const bool ok = std::isfinite(g.position.lat_rad) && std::isfinite(g.position.lon_rad) &&
                  std::isfinite(g.position.height_m) && std::abs(g.position.lat_rad) <= kPi / 2.0 &&
                  g.vel_enu_mps.allFinite();
  if (!ok) {
    std::ostringstream m;
    m << stream << ": at t=" << g.t_s << " s, position or velocity is not finite (or latitude out of range)";
    throw StreamInputError(m.str());
  }
}

}  // namespace odonav
