#include "odonav/braking_stop.hpp"

#include <cmath>
#include <stdexcept>

namespace odonav {

const char* to_string(MotionPhase phase) {
  switch (phase) {
    case MotionPhase::kUnknown: return "unknown";
    case MotionPhase::kDriving: return "driving";
    case MotionPhase::kBraking: return "braking";
    case MotionPhase::kStandstill: return "standstill";
  }
  return "unknown";
}

MotionPhase classify_motion(double before, double now, double dt_s, const BrakingStopParams& p) {
  if (!std::isfinite(now)) return MotionPhase::kUnknown;
  if (std::abs(now) < p.standstill_speed_mps) return MotionPhase::kStandstill;
  if (!std::isfinite(before) || !(dt_s > 0.0)) return MotionPhase::kUnknown;
  // Speeds along the direction of travel: reversing brakes towards zero from below.
  return (std::abs(before) - std::abs(now)) / dt_s > p.braking_mps2 ? MotionPhase::kBraking : MotionPhase::kDriving;
}

void validate(const BrakingStopParams& p) {
  auto require = [](bool ok, const char* what) {
    if (!ok) throw std::invalid_argument(std::string("BrakingStopParams: ") + what);
  };
  require(p.braking_mps2 > 0.0 && std::isfinite(p.braking_mps2), "braking_mps2 must be > 0");
  require(p.baseline_s > 0.0 && std::isfinite(p.baseline_s), "baseline_s must be > 0");
  require(p.standstill_speed_mps > 0.0 && std::isfinite(p.standstill_speed_mps), "standstill_speed_mps must be > 0");
  require(p.max_reference_age_s >= p.baseline_s && std::isfinite(p.max_reference_age_s),
          "max_reference_age_s must be >= baseline_s");
}

BrakingStopStep braking_stop_step(MotionPhase phase, bool active, std::optional<uint64_t> used_since) {
  if (!active) return BrakingStopStep::kDrop;
  switch (phase) {
    case MotionPhase::kUnknown: return BrakingStopStep::kKeep;  // the braking is neither confirmed nor over
    case MotionPhase::kDriving: return BrakingStopStep::kDrop;  // the braking ended moving: its samples stay
    case MotionPhase::kBraking: return used_since ? BrakingStopStep::kKeep : BrakingStopStep::kSnapshot;
    case MotionPhase::kStandstill:
      return used_since && *used_since > 0 ? BrakingStopStep::kRollBack : BrakingStopStep::kDrop;
  }
  return BrakingStopStep::kKeep;
}

MotionPhaseTracker::MotionPhaseTracker(const BrakingStopParams& params) : params_(params) { validate(params_); }

MotionPhase MotionPhaseTracker::add(double t_s, double speed_mps) {
  // The latest epoch at least baseline_s before this one (1 us of slack for the stamps' rounding).
  const std::pair<double, double>* reference = nullptr;
  for (const auto& e : epochs_)
    if (e.first <= t_s - params_.baseline_s + 1e-6) reference = &e;
  MotionPhase phase = MotionPhase::kUnknown;
  if (reference && t_s - reference->first <= params_.max_reference_age_s)
    phase = classify_motion(reference->second, speed_mps, t_s - reference->first, params_);
  else
    phase = classify_motion(std::nan(""), speed_mps, 0.0, params_);
  if (std::isfinite(speed_mps)) epochs_.emplace_back(t_s, speed_mps);
  // Only what a later epoch can still use as its reference (at most max_reference_age_s before it).
  while (!epochs_.empty() && epochs_.front().first < t_s - params_.max_reference_age_s) epochs_.pop_front();
  return phase;
}

std::vector<double> MotionPhaseTracker::state() const {
  std::vector<double> out;
  for (const auto& e : epochs_) {
    out.push_back(e.first);
    out.push_back(e.second);
  }
  return out;
}

void MotionPhaseTracker::restore(const std::vector<double>& s) {
  if (s.size() % 2 != 0) throw std::invalid_argument("motion phase state: not (t, speed) pairs");
  std::deque<std::pair<double, double>> epochs;
  for (std::size_t i = 0; i < s.size(); i += 2) {
    if (!std::isfinite(s[i]) || !std::isfinite(s[i + 1]) || (!epochs.empty() && !(s[i] > epochs.back().first)))
      throw std::invalid_argument("motion phase state: epochs not finite or not in increasing time");
    epochs.emplace_back(s[i], s[i + 1]);
  }
  epochs_.swap(epochs);
}

}  // namespace odonav
