#pragma once
// The calibration's health decision, a pure function over the facts the node supplies (the node
// only publishes what it returns), as identification_health and dead_reckoning_health are for their
// components.
#include <optional>
#include <string>

#include "odonav/calibration/misalignment_calibrator.hpp"
#include "odonav/component_health.hpp"
#include "odonav/restart_policy.hpp"

namespace odonav::calibration {

/// Everything calibration_health() decides on. The restart notes come from the lifecycle
/// (CalibrationLifecycle::restart().health_notes()).
struct CalibrationHealthFacts : RestartHealthNotes {
  /// The vehicle has an INS (--use-ins): without it the misalignment cannot be calibrated.
  bool use_ins = true;
  /// The calibrator's current output, once a GNSS epoch was processed (or a state restored).
  std::optional<MisalignmentOutput> current;
  /// Now, steady clock (s): how long the restart notes stay.
  double now_s = 0.0;
};

/// The health decision. Reasons (operators and tests rely on the exact texts):
///  - no INS: DEGRADED, WARN "no INS: the misalignment cannot be calibrated";
///  - no output yet: STARTING "waiting for the first GNSS epoch to process";
///  - frozen: "frozen by command"; waiting or calibrating: "not converged yet: <the calibrator's
///    reason>" (level OK: converging is normal at the start of a drive);
///  - then the restart notes (restore, checkpoint errors, catch-up: apply_restart_notes), which
///    raise the level to WARN when they say so.
ComponentHealth calibration_health(const CalibrationHealthFacts& facts);

}  // namespace odonav::calibration
