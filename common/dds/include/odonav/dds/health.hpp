#pragma once
// Health publication: every component publishes its Health at 1 Hz on rt/odonav/health, with the
// acknowledgement of the last Command it received.
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "odonav/dds/endpoints.hpp"
#include "odonav/msg/Health.h"
#include "odonav/topics.hpp"

namespace odonav::dds {

/// How often (wall clock, s) a component at most evaluates its Health between publications: the
/// loops that could evaluate it after every sample (hundreds per second) evaluate the counters and
/// the peers' silences at most this often, still well inside the 1 s health period and the peers'
/// silence bounds; state changes are still seen within this period.
constexpr double kHealthEvaluationPeriod_s = 0.05;

/// Named figures of a component (samples accepted, bad rows, queue depth, ...), in order.
using HealthCounters = std::vector<std::pair<std::string, double>>;

/// The acknowledgement of the last command a component received (Health.last_command_*).
struct CommandAck {
  std::uint32_t command_id = 0;
  odonav::msg::CommandResult result = odonav::msg::COMMAND_RESULT_NONE;
  std::string detail;  ///< human readable, e.g. why it was rejected
};

/// Fills a Health message: header stamp = stamp_s (seconds on the dataset time base, see
/// to_time_msg for range and errors), frame_id "", keys vehicle_id and component, and the rest
/// as given.
odonav::msg::Health make_health(const std::string& vehicle_id, const std::string& component, double stamp_s,
                                odonav::msg::HealthState state, odonav::msg::HealthLevel level,
                                const std::string& reason, const HealthCounters& counters,
                                const CommandAck& ack = CommandAck{});

/// Lets an event through at most once per period, on a clock the caller drives (seconds, any
/// time base: steady clock, or dataset time when replaying faster than real time).
class RateLimiter {
 public:
  /// min_period_s: finite, >= 0 (0 lets every call through). Throws std::invalid_argument.
  explicit RateLimiter(double min_period_s);
  /// True, and the period restarts at now_s, on the first call, when now_s - (last pass) >=
  /// min_period_s, or when now_s is earlier than the last pass (the clock was reset, e.g. a replay
  /// restarted). False otherwise, and for a NaN now_s.
  bool due(double now_s);
  /// Forgets the last pass: the next due() is true.
  void reset() { has_last_ = false; }
  double min_period_s() const { return min_period_s_; }

 private:
  double min_period_s_;
  bool has_last_ = false;
  double last_s_ = 0.0;
};

/// Publishes one component's Health at most max_rate_hz times per second of the caller's clock.
class HealthPublisher {
 public:
  /// max_rate_hz: finite, > 0 (1 Hz by contract). Throws std::invalid_argument for a bad rate and
  /// std::runtime_error when the writer cannot be created (see Writer).
  HealthPublisher(const Participant& participant, std::string vehicle_id, std::string component,
                  double max_rate_hz = 1.0, const std::string& qos_profile = topics::kHealthWriterProfile,
                  const std::string& topic_name = topics::kHealth.name);

  /// Records the acknowledgement carried by every following Health.
  void acknowledge(std::uint32_t command_id, odonav::msg::CommandResult result, const std::string& detail);

  /// Writes Health if at least 1/max_rate_hz has passed since the last write (now_s: the caller's
  /// clock, seconds, also used as the header stamp). Returns true if a sample was written.
  bool publish_if_due(double now_s, odonav::msg::HealthState state, odonav::msg::HealthLevel level,
                      const std::string& reason, const HealthCounters& counters = {});

  /// Writes Health now regardless of the rate (a state change worth telling at once, e.g.
  /// stopping), and restarts the rate period. Returns true if the sample was written.
  bool publish_now(double now_s, odonav::msg::HealthState state, odonav::msg::HealthLevel level,
                   const std::string& reason, const HealthCounters& counters = {});

  Writer<odonav::msg::Health>& writer() { return writer_; }

 private:
  static double period_from_rate(double max_rate_hz);

  std::string vehicle_id_;
  std::string component_;
  RateLimiter limiter_;
  CommandAck ack_;
  Writer<odonav::msg::Health> writer_;
};

}  // namespace odonav::dds
