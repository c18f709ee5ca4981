#pragma once
// odonav-gateway's middleware-free core, part 2: the pacing clock (`--speed 1|N|max`).
//
// Paced modes map event time to wall time: the sample stamped t is due at
//   wall_start + (t - t_first) / speed
// so a replay at speed 1 reproduces the sensors' real timing and speed N compresses it N times.
// "max" has no due times: the gateway publishes as fast as its readers acknowledge (flow control
// in the node), checking acknowledgments every `ack_interval_s` of data.
#include <optional>
#include <string>

namespace odonav::gateway {

/// A publication speed.
struct Speed {
  bool as_fast_as_possible = false;  ///< "max".
  double factor = 1.0;               ///< event seconds per wall second when paced, (0, 1e6].
};

/// Parses "max", or a positive decimal factor ("1", "10", "0.5"), at most 1e6. Throws ConfigError
/// naming --speed and the accepted forms otherwise (zero, negative, NaN, text).
Speed parse_speed(const std::string& text);

/// "max" or the factor, e.g. "x10".
std::string to_string(const Speed& speed);

/// Maps event time (s, dataset time base) to wall time (s, any monotonic clock, e.g. steady_now_s).
class PacingClock {
 public:
  /// first_t_s: event time of the first sample; wall_start_s: when it is due. Both finite.
  /// Throws std::invalid_argument otherwise.
  PacingClock(const Speed& speed, double first_t_s, double wall_start_s);

  /// Wall time (s) at which the sample stamped t_s is due; nullopt in "max" mode (due at once).
  /// Samples before first_t_s are due at wall_start_s (never earlier: the clock does not run back).
  std::optional<double> due_wall_s(double t_s) const;

  /// Event time (s) the clock has reached at wall time wall_s: first_t_s + (wall_s -
  /// wall_start_s) * speed, not before first_t_s; +infinity in "max" mode.
  double event_time_at(double wall_s) const;

  const Speed& speed() const { return speed_; }

 private:
  Speed speed_;
  double first_t_s_;
  double wall_start_s_;
};

/// Flow control in "max" mode: tells when `interval_s` of event time has been published since the
/// last acknowledgment wait. interval_s > 0 (the gateway uses 0.1 s: with 100 Hz streams that is
/// 10 samples per topic, far below the writers' KEEP_LAST 3000, so nothing is overwritten unread).
class AckSchedule {
 public:
  /// Throws std::invalid_argument unless interval_s is finite and > 0.
  explicit AckSchedule(double interval_s);
  /// A sample stamped t_s is about to be published: true when the readers must acknowledge
  /// everything before it first (interval_s of event time since the last wait). The first call is false.
  bool wait_before(double t_s);

 private:
  double interval_s_;
  std::optional<double> last_wait_t_s_;
};

}  // namespace odonav::gateway
