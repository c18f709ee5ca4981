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
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <deque>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

#include "odonav/defaults.hpp"
#include "odonav/sensor_samples.hpp"
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
  kReady,    ///< a valid bracket exists: the value is available.
  kPending,  ///< no sample at or after t yet, and the watermark does not exclude one: wait.
  kMissing,  ///< no valid bracket can exist (gap, or t before the first sample): the value is absent.
};

namespace detail {
/// The index of the first entry of a time-sorted, non-empty buffer stamped at or after t_s (that of
/// std::lower_bound). Sensor streams are nearly evenly spaced, so the search starts where even
/// spacing puts t_s and steps from there; a few steps off (a gap, a burst), a binary search of the
/// side it is on. A query costs a few comparisons instead of log2(n) steps of a deque iterator.
template <class Entries>
std::size_t first_at_or_after(const Entries& entries, double t_s) {
  const auto before = [](const auto& e, double t) { return e.t_s < t; };
  const std::size_t n = entries.size();
  const double first_s = entries.front().t_s, last_s = entries.back().t_s;
  if (!(t_s > first_s && t_s <= last_s && last_s > first_s))  // ends, NaN, a single time
    return static_cast<std::size_t>(std::lower_bound(entries.begin(), entries.end(), t_s, before) - entries.begin());
  constexpr std::size_t kSteps = 4;
  std::size_t i = std::min(n - 1, static_cast<std::size_t>((t_s - first_s) / (last_s - first_s) * double(n - 1)));
  if (entries[i].t_s < t_s) {  // the answer is after i (entries.back() is at or after t_s)
    for (std::size_t k = 0; k < kSteps; ++k)
      if (!(entries[++i].t_s < t_s)) return i;
    return static_cast<std::size_t>(std::lower_bound(entries.begin() + i, entries.end(), t_s, before) -
                                    entries.begin());
  }
  // entries[i] is at or after t_s, entries.front() before it: the answer is in (0, i].
  for (std::size_t k = 0; k < kSteps; ++k, --i)
    if (entries[i - 1].t_s < t_s) return i;
  return static_cast<std::size_t>(std::lower_bound(entries.begin(), entries.begin() + i, t_s, before) -
                                  entries.begin());
}

/// The samples of a time-sorted buffer (entries with a t_s, s) that bracket t_s: lo == hi when one is
/// stamped exactly t_s. kPending while the buffer cannot know yet (t_s after its last sample, or
/// nothing buffered, and watermark_s < t_s + max_bracket_s), kMissing when it never will (before the
/// first sample, or a gap longer than max_bracket_s around t_s). first_at_or_after: O(1) on an evenly
/// spaced stream, O(log n) at worst.
template <class Entries>
BracketState bracket(const Entries& entries, double t_s, double watermark_s, double max_bracket_s, std::size_t& lo,
                     std::size_t& hi) {
  if (entries.empty() || t_s < entries.front().t_s) {
    // Before the first buffered sample: only pending if nothing has arrived yet.
    if (entries.empty() && watermark_s < t_s + max_bracket_s) return BracketState::kPending;
    return BracketState::kMissing;
  }
  if (entries.back().t_s < t_s)
    return watermark_s < t_s + max_bracket_s ? BracketState::kPending : BracketState::kMissing;
  // The first entry at or after t_s.
  const std::size_t i = first_at_or_after(entries, t_s);
  if (entries[i].t_s == t_s) {
    lo = hi = i;
    return BracketState::kReady;
  }
  lo = i - 1;
  hi = i;
  return entries[hi].t_s - entries[lo].t_s <= max_bracket_s ? BracketState::kReady : BracketState::kMissing;
}

/// What the interpolated sensor buffers (OdometerBuffer, AttitudeBuffer) share: their samples in
/// increasing time (Entry has t_s, s), the bracket of a time and the pruning of what no later time
/// needs.
template <class Entry>
class BracketedStream {
 public:
  /// Whether the value at t_s (s) can be known, given that every sample with stamp <= watermark_s
  /// has been added.
  BracketState state_at(double t_s, double watermark_s) const {
    std::size_t lo = 0, hi = 0;
    return bracket(t_s, watermark_s, lo, hi);
  }
  /// Drops samples no longer needed for times >= t_s (keeps the last sample at or before t_s).
  void drop_before(double t_s) {
    while (entries_.size() >= 2 && entries_[1].t_s <= t_s) entries_.pop_front();
  }
  std::optional<double> last_time_s() const { return last_t_s_; }
  double max_bracket_s() const { return max_bracket_s_; }

 protected:
  /// max_bracket_s: the longest gap between two samples across which the value is interpolated (s, > 0).
  explicit BracketedStream(double max_bracket_s) : max_bracket_s_(max_bracket_s) {}
  /// detail::bracket over the buffered samples.
  BracketState bracket(double t_s, double watermark_s, std::size_t& lo, std::size_t& hi) const {
    return detail::bracket(entries_, t_s, watermark_s, max_bracket_s_, lo, hi);
  }

  double max_bracket_s_;
  std::deque<Entry> entries_;
  std::optional<double> last_t_s_;
};
}  // namespace detail

/// A sample of the odometer stream as OdometerBuffer keeps it.
struct OdometerEntry {
  double t_s = 0.0;
  int64_t count = 0;  ///< unwrapped accumulated pulses since the first sample.
  uint32_t raw_pulses = 0;
  int direction = 1;
};

/// A sample of the INS attitude stream as AttitudeBuffer keeps it.
struct AttitudeEntry {
  double t_s;
  Attitude attitude;
};

/// The pulse-jump gate of the odometer stream: the largest count increment a real vehicle can make
/// in dt_s. A counter glitch (a bit flip, a reset to a random value, a bus error) shows up as an
/// increment millions of times the normal one; taken as distance it would move dead reckoning by
/// kilometres and give the scale-factor regression a sample with an absurd phi.
///   max_increment(dt) = max_speed_mps / k_m_per_pulse * dt + margin_pulses      [pulses]
/// Defaults: 100 m/s (360 km/h, several times any ground vehicle's top speed, so real motion never
/// reaches it even with K off by a factor of 3) at K = 0.0125 m/pulse gives 8000 pulses/s, i.e. 80
/// pulses over a 100 Hz interval where 10 m/s makes 8; the 2-pulse margin covers quantisation and
/// time-stamp jitter on very short intervals. A counter running backwards (a huge increment modulo
/// 2^32) is rejected the same way.
struct OdometerJumpGate {
  /// Fastest physically possible speed (m/s, > 0).
  double max_speed_mps = 100.0;
  /// Scale factor the speed is converted to pulses with: the nominal K (m/pulse, > 0).
  double k_m_per_pulse = kDefaultNominalK_m_per_pulse;
  /// Allowance for pulse quantisation and time-stamp jitter (pulses, >= 0).
  double margin_pulses = 2.0;
  /// The largest plausible increment over dt_s (s, >= 0), in pulses.
  double max_increment_pulses(double dt_s) const { return max_speed_mps / k_m_per_pulse * dt_s + margin_pulses; }
};

/// The direction an odometer reports over an interval (OdometerBuffer::direction_over).
enum class OdometerDirection {
  kForward,    ///< no sample says reversing (direction +1 or 0, unknown).
  kReversing,  ///< every sample says reversing (-1).
  kMixed,      ///< the direction changes within the interval.
};

/// What OdometerBuffer::add did with a sample.
enum class OdometerAddResult {
  kAccepted,      ///< buffered.
  kJumpRejected,  ///< implausible increment: not buffered, counted (jumps_rejected()).
};

/// The odometer stream. Holds the accumulated count unwrapped: each increment is taken modulo 2^32
/// (pulse_increment), so a counter wrap is not a jump. The unwrapped count starts at 0 at the first
/// sample ever added (independent of pruning, so answers never depend on when pruning happened).
///
/// Pulse jumps (OdometerJumpGate): a sample whose increment from the last accepted sample exceeds
/// the gate is rejected (not buffered) and counted. The next sample tells which glitch it was:
///  - a spike (one bad value, then the counter goes on as before): its increment from the last
///    accepted sample is plausible again, so it is accepted and no pulse is lost;
///  - a step (the counter jumped and keeps counting from the new value): its increment from the
///    rejected value is plausible, so the buffer re-bases on it. The pulses over the interval that
///    held the jump are unknown: they are estimated as the last accepted pulse rate times that
///    interval (exact at constant speed), counted in rebases().
/// The counts of later samples are then their true increments added to that, so the distance after
/// a jump stays correct (up to the one estimated interval).
class OdometerBuffer : public detail::BracketedStream<OdometerEntry> {
 public:
  using Entry = OdometerEntry;

  /// max_bracket_s: the longest gap between two samples across which the count is interpolated (s, > 0).
  /// gate: the pulse-jump gate (see OdometerJumpGate); throws std::invalid_argument when its values
  /// are out of range.
  explicit OdometerBuffer(double max_bracket_s = 1.0, const OdometerJumpGate& gate = {})
      : BracketedStream(max_bracket_s), gate_(gate) {
    if (!(std::isfinite(gate.max_speed_mps) && gate.max_speed_mps > 0.0) ||
        !(std::isfinite(gate.k_m_per_pulse) && gate.k_m_per_pulse > 0.0) ||
        !(std::isfinite(gate.margin_pulses) && gate.margin_pulses >= 0.0))
      throw std::invalid_argument(
          "OdometerJumpGate: max_speed_mps and k_m_per_pulse must be finite and > 0, margin_pulses finite and >= 0");
  }

  /// Adds one sample; its time must be finite and increase (also over rejected samples); direction
  /// must be -1, 0 or +1. Throws StreamInputError otherwise. Returns whether the sample was buffered
  /// or rejected by the pulse-jump gate.
  OdometerAddResult add(const OdometerSample& s) {
    detail::check_stream_time("odometer", s.t_s, last_t_s_);
    if (s.direction < -1 || s.direction > 1) {
      std::ostringstream m;
      m << "odometer: at t=" << s.t_s << " s, direction " << s.direction << " is not -1, 0 or +1";
      throw StreamInputError(m.str());
    }
    last_t_s_ = s.t_s;
    Entry e;
    e.t_s = s.t_s;
    e.raw_pulses = s.pulses;
    e.direction = s.direction;
    if (!last_accepted_) {
      e.count = 0;
    } else {
      const Entry& good = *last_accepted_;
      const uint32_t increment = pulse_increment(good.raw_pulses, s.pulses);
      if (static_cast<double>(increment) <= gate_.max_increment_pulses(s.t_s - good.t_s)) {
        e.count = good.count + static_cast<int64_t>(increment);
      } else if (rejected_ && static_cast<double>(pulse_increment(rejected_->raw_pulses, s.pulses)) <=
                                  gate_.max_increment_pulses(s.t_s - rejected_->t_s)) {
        // Step: re-base on the rejected value; the interval that held the jump at the last rate.
        const double estimated = last_rate_pulses_per_s_ * (rejected_->t_s - good.t_s);
        e.count = good.count + std::llround(estimated) +
                  static_cast<int64_t>(pulse_increment(rejected_->raw_pulses, s.pulses));
        ++rebases_;
      } else {
        rejected_ = e;
        ++jumps_rejected_;
        return OdometerAddResult::kJumpRejected;
      }
      last_rate_pulses_per_s_ = static_cast<double>(e.count - good.count) / (s.t_s - good.t_s);
    }
    rejected_.reset();
    last_accepted_ = e;
    entries_.push_back(e);
    return OdometerAddResult::kAccepted;
  }

  /// Samples rejected by the pulse-jump gate so far.
  uint64_t jumps_rejected() const { return jumps_rejected_; }
  /// Counter steps re-based on (each with one interval of estimated pulses) so far.
  uint64_t rebases() const { return rebases_; }
  const OdometerJumpGate& jump_gate() const { return gate_; }

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

  /// The direction the samples describing the interval [t0_s, t1_s] (stamped after t0_s, up to and
  /// including the first sample at or after t1_s) report: kReversing when every one says -1,
  /// kMixed when some do and some do not (0, unknown, counts as forward), else kForward.
  OdometerDirection direction_over(double t0_s, double t1_s) const {
    bool forward = false, reversing = false;
    // From the first sample stamped after t0_s.
    auto it =
        std::upper_bound(entries_.begin(), entries_.end(), t0_s, [](double t, const Entry& e) { return t < e.t_s; });
    for (; it != entries_.end(); ++it) {
      (it->direction < 0 ? reversing : forward) = true;
      if (it->t_s >= t1_s) break;
    }
    if (!reversing) return OdometerDirection::kForward;
    return forward ? OdometerDirection::kMixed : OdometerDirection::kReversing;
  }
  /// True when a sample describing the interval [t0_s, t1_s] reports reversing (direction -1).
  bool any_reversing(double t0_s, double t1_s) const {
    return direction_over(t0_s, t1_s) != OdometerDirection::kForward;
  }
  /// The direction of the sample describing the instant t_s (the first stamped at or after it).
  OdometerDirection direction_at(double t_s) const {
    const auto it =
        std::lower_bound(entries_.begin(), entries_.end(), t_s, [](const Entry& e, double t) { return e.t_s < t; });
    if (it != entries_.end()) return it->direction < 0 ? OdometerDirection::kReversing : OdometerDirection::kForward;
    return OdometerDirection::kForward;
  }

  const std::deque<Entry>& entries() const { return entries_; }

  /// Everything the buffer holds besides its parameters, for a component checkpoint: restoring it
  /// into a buffer made with the same parameters continues exactly as the saved one would.
  struct State {
    std::deque<Entry> entries;
    std::optional<Entry> last_accepted;
    std::optional<Entry> rejected;
    double last_rate_pulses_per_s = 0.0;
    uint64_t jumps_rejected = 0;
    uint64_t rebases = 0;
    std::optional<double> last_t_s;
  };
  State state() const {
    return {entries_, last_accepted_, rejected_, last_rate_pulses_per_s_, jumps_rejected_, rebases_, last_t_s_};
  }
  void restore_state(State s) {
    entries_ = std::move(s.entries);
    last_accepted_ = s.last_accepted;
    rejected_ = s.rejected;
    last_rate_pulses_per_s_ = s.last_rate_pulses_per_s;
    jumps_rejected_ = s.jumps_rejected;
    rebases_ = s.rebases;
    last_t_s_ = s.last_t_s;
  }

 private:
  OdometerJumpGate gate_;
  std::optional<Entry> last_accepted_;   ///< the gate's reference (survives pruning).
  std::optional<Entry> rejected_;        ///< the last rejected sample, while no sample was accepted after it.
  double last_rate_pulses_per_s_ = 0.0;  ///< pulse rate over the last accepted interval.
  uint64_t jumps_rejected_ = 0;
  uint64_t rebases_ = 0;
};

/// The INS attitude stream; attitude at a time by interpolate_attitude (frames.hpp).
class AttitudeBuffer : public detail::BracketedStream<AttitudeEntry> {
 public:
  using Entry = AttitudeEntry;

  /// max_bracket_s: the longest gap between two samples across which attitude is interpolated (s, > 0).
  explicit AttitudeBuffer(double max_bracket_s = 1.0) : BracketedStream(max_bracket_s) {}

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

  /// Attitude at t_s (interpolated between the bracketing samples); nullopt unless kReady.
  std::optional<Attitude> attitude_at(double t_s, double watermark_s) const {
    std::size_t lo = 0, hi = 0;
    if (bracket(t_s, watermark_s, lo, hi) != BracketState::kReady) return std::nullopt;
    if (lo == hi) return entries_[lo].attitude;
    const double f = (t_s - entries_[lo].t_s) / (entries_[hi].t_s - entries_[lo].t_s);
    return interpolate_attitude(entries_[lo].attitude, entries_[hi].attitude, f);
  }

  std::size_t size() const { return entries_.size(); }

  /// Everything the buffer holds besides its parameters (see OdometerBuffer::State).
  struct State {
    std::deque<Entry> entries;
    std::optional<double> last_t_s;
  };
  State state() const { return {entries_, last_t_s_}; }
  void restore_state(State s) {
    entries_ = std::move(s.entries);
    last_t_s_ = s.last_t_s;
  }
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

  /// Everything the history holds besides its name (see OdometerBuffer::State).
  struct State {
    std::deque<std::pair<double, Value>> entries;
    std::optional<double> last_t_s;
  };
  State state() const { return {entries_, last_t_s_}; }
  void restore_state(State s) {
    entries_ = std::move(s.entries);
    last_t_s_ = s.last_t_s;
  }

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

/// Queues a GNSS epoch for processing after checking it (time finite and after last_t_s,
/// check_gnss_sample); last_t_s becomes its time. Throws StreamInputError naming the gnss stream.
inline void queue_gnss_sample(const GnssSample& s, std::optional<double>& last_t_s, std::deque<GnssSample>& pending) {
  detail::check_stream_time("gnss", s.t_s, last_t_s);
  check_gnss_sample("gnss", s);
  last_t_s = s.t_s;
  pending.push_back(s);
}

/// Adds the misalignment estimate m (rad) of epoch t_s (s) to its history. Throws StreamInputError
/// when an angle is not finite (nothing is added then), or as StepHistory::add.
inline void add_misalignment_estimate(StepHistory<Misalignment>& history, double t_s, const Misalignment& m) {
  if (!std::isfinite(m.heading_rad) || !std::isfinite(m.pitch_rad)) {
    std::ostringstream s;
    s << "misalignment: at t=" << t_s << " s, angles are not finite";
    throw StreamInputError(s.str());
  }
  history.add(t_s, m);
}

}  // namespace odonav
