#include "odonav/dds/health.hpp"

#include <cmath>
#include <stdexcept>

#include "odonav/dds/time.hpp"

namespace odonav::dds {

odonav::msg::Health make_health(const std::string& vehicle_id, const std::string& component, double stamp_s,
                                odonav::msg::HealthState state, odonav::msg::HealthLevel level,
                                const std::string& reason, const HealthCounters& counters, const CommandAck& ack) {
  odonav::msg::Health health;
  health.header(make_header(stamp_s, ""));
  health.vehicle_id(vehicle_id);
  health.component(component);
  health.state(state);
  health.level(level);
  health.reason(reason);
  health.counters().reserve(counters.size());
  for (const auto& [name, value] : counters) {
    odonav::msg::Counter counter;
    counter.name(name);
    counter.value(value);
    health.counters().push_back(std::move(counter));
  }
  health.last_command_id(ack.command_id);
  health.last_command_result(ack.result);
  health.last_command_detail(ack.detail);
  return health;
}

RateLimiter::RateLimiter(double min_period_s) : min_period_s_(min_period_s) {
  if (!std::isfinite(min_period_s) || min_period_s < 0.0) {
    throw std::invalid_argument("odonav::dds::RateLimiter: min_period_s must be finite and >= 0, got " +
                                std::to_string(min_period_s));
  }
}

bool RateLimiter::due(double now_s) {
  if (std::isnan(now_s)) return false;
  if (has_last_ && now_s >= last_s_ && now_s - last_s_ < min_period_s_) return false;
  has_last_ = true;
  last_s_ = now_s;
  return true;
}

double HealthPublisher::period_from_rate(double max_rate_hz) {
  if (!std::isfinite(max_rate_hz) || max_rate_hz <= 0.0) {
    throw std::invalid_argument("odonav::dds::HealthPublisher: max_rate_hz must be finite and > 0, got " +
                                std::to_string(max_rate_hz));
  }
  return 1.0 / max_rate_hz;
}

HealthPublisher::HealthPublisher(const Participant& participant, std::string vehicle_id, std::string component,
                                 double max_rate_hz, const std::string& qos_profile, const std::string& topic_name)
    : vehicle_id_(std::move(vehicle_id)),
      component_(std::move(component)),
      limiter_(period_from_rate(max_rate_hz)),
      writer_(participant, topic_name, qos_profile) {}

void HealthPublisher::acknowledge(std::uint32_t command_id, odonav::msg::CommandResult result,
                                  const std::string& detail) {
  ack_ = CommandAck{command_id, result, detail};
}

bool HealthPublisher::publish_if_due(double now_s, odonav::msg::HealthState state, odonav::msg::HealthLevel level,
                                     const std::string& reason, const HealthCounters& counters) {
  if (!limiter_.due(now_s)) return false;
  return writer_.write(make_health(vehicle_id_, component_, now_s, state, level, reason, counters, ack_));
}

bool HealthPublisher::publish_now(double now_s, odonav::msg::HealthState state, odonav::msg::HealthLevel level,
                                  const std::string& reason, const HealthCounters& counters) {
  limiter_.reset();
  limiter_.due(now_s);
  return writer_.write(make_health(vehicle_id_, component_, now_s, state, level, reason, counters, ack_));
}

}  // namespace odonav::dds
