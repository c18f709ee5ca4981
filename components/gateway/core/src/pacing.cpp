#include "odonav/gateway/pacing.hpp"

#include <charconv>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "odonav/config.hpp"

namespace odonav::gateway {

Speed parse_speed(const std::string& text) {
  if (text == "max") return Speed{true, 1.0};
  double v = 0.0;
  const auto res = std::from_chars(text.data(), text.data() + text.size(), v);
  if (text.empty() || res.ec != std::errc() || res.ptr != text.data() + text.size() || !std::isfinite(v) ||
      !(v > 0.0) || v > 1e6)
    throw ConfigError("--speed: '" + text + "' is not 'max' or a factor in (0, 1e6] (1 = real time)");
  return Speed{false, v};
}

std::string to_string(const Speed& speed) {
  if (speed.as_fast_as_possible) return "max";
  std::ostringstream s;
  s << "x" << speed.factor;
  return s.str();
}

PacingClock::PacingClock(const Speed& speed, double first_t_s, double wall_start_s)
    : speed_(speed), first_t_s_(first_t_s), wall_start_s_(wall_start_s) {
  if (!std::isfinite(first_t_s) || !std::isfinite(wall_start_s))
    throw std::invalid_argument("PacingClock: first_t_s and wall_start_s must be finite");
  if (!speed.as_fast_as_possible && !(speed.factor > 0.0 && std::isfinite(speed.factor)))
    throw std::invalid_argument("PacingClock: speed factor must be finite and > 0");
}

std::optional<double> PacingClock::due_wall_s(double t_s) const {
  if (speed_.as_fast_as_possible) return std::nullopt;
  if (!(t_s > first_t_s_)) return wall_start_s_;
  return wall_start_s_ + (t_s - first_t_s_) / speed_.factor;
}

double PacingClock::event_time_at(double wall_s) const {
  if (speed_.as_fast_as_possible) return std::numeric_limits<double>::infinity();
  if (!(wall_s > wall_start_s_)) return first_t_s_;
  return first_t_s_ + (wall_s - wall_start_s_) * speed_.factor;
}

AckSchedule::AckSchedule(double interval_s) : interval_s_(interval_s) {
  if (!std::isfinite(interval_s) || !(interval_s > 0.0))
    throw std::invalid_argument("AckSchedule: interval_s must be finite and > 0");
}

bool AckSchedule::wait_before(double t_s) {
  if (!last_wait_t_s_) {
    last_wait_t_s_ = t_s;
    return false;
  }
  if (t_s - *last_wait_t_s_ >= interval_s_) {
    last_wait_t_s_ = t_s;
    return true;
  }
  return false;
}

}  // namespace odonav::gateway
