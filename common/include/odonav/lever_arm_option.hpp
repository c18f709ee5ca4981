#pragma once
// --lever-arm "x,y,z": the GNSS antenna position in the INS body frame (forward-left-up, metres, from
// the INS reference point). Shared by calibration, identification and dead reckoning, and by
// odonav-offline, so every program reads it the same way.
#include <optional>

#include <Eigen/Dense>

#include "odonav/config.hpp"

namespace odonav {

/// Declares --lever-arm (default empty = no lever arm).
void add_lever_arm_option(Options& options);
/// Parses --lever-arm; throws ConfigError naming it when it is not three finite numbers.
std::optional<Eigen::Vector3d> lever_arm_from(const Options& options);

}  // namespace odonav
