#pragma once
// Misalignment-calibration parameters as options, shared by odonav-offline and odonav-calibration.
#include <optional>
#include <string>

#include <Eigen/Dense>

#include "odonav/calibration/misalignment_calibrator.hpp"
#include "odonav/config.hpp"
#include "odonav/lever_arm_option.hpp"

namespace odonav::calibration {

/// Declares --cal-min-speed, --cal-max-yaw-rate-deg-s, --cal-converged-sigma-deg, --cal-min-samples,
/// --cal-braking-stop.
void add_calibration_options(Options& options);
MisalignmentCalibratorParams calibration_params_from(const Options& options);

}  // namespace odonav::calibration
