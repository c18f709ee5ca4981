#include "odonav/calibration/calibration_health.hpp"

namespace odonav::calibration {

ComponentHealth calibration_health(const CalibrationHealthFacts& f) {
  using State = ComponentHealth::State;
  using Level = ComponentHealth::Level;
  ComponentHealth h{State::kRunning, Level::kOk, ""};
  if (!f.use_ins) {
    h = {State::kDegraded, Level::kWarn, "no INS: the misalignment cannot be calibrated"};
  } else if (!f.current) {
    h = {State::kStarting, Level::kOk, "waiting for the first GNSS epoch to process"};
  } else {
    switch (f.current->state) {
      case CalibrationState::kConverged: break;
      case CalibrationState::kFrozen: h.reason = "frozen by command"; break;
      case CalibrationState::kWaiting:
      case CalibrationState::kCalibrating: h.reason = "not converged yet: " + f.current->reason; break;
    }
  }
  bool warn = h.level != Level::kOk;
  apply_restart_notes(f, f.now_s, h.reason, warn);
  if (warn) h.level = Level::kWarn;
  return h;
}

}  // namespace odonav::calibration
