#pragma once
// Misalignment-calibration parameters as options, shared by odonav-offline and odonav-calibration.
#include <optional>
#include <string>

#include <Eigen/Dense>

#include "odonav/calibration/misalignment_calibrator.hpp"
#include "odonav/config.hpp"

namespace odonav {

/// Declares --cal-min-speed, --cal-max-yaw-rate-deg-s, --cal-converged-sigma-deg, --cal-min-samples.
void add_calibration_options(Options& options);
MisalignmentCalibratorParams calibration_params_from(const Options& options);

/// Declares --lever-arm "x,y,z" (GNSS antenna in the INS body frame, forward-left-up, metres; empty =
/// none). Shared by calibration and dead reckoning.
void add_lever_arm_option(Options& options);
/// Parses --lever-arm; throws ConfigError naming it when malformed.
std::optional<Eigen::Vector3d> lever_arm_from(const Options& options);

}  // namespace odonav
