#pragma once
// Dead-reckoning parameters as options, shared by odonav-offline and odonav-dead-reckoning.
#include "odonav/config.hpp"
#include "odonav/dead_reckoning/dead_reckoner.hpp"

namespace odonav {

/// Declares --nominal-k (m/pulse; 0 = from the dataset's meta.json or 0.0125) and --dr-mode 3d|2d.
/// The lever arm is --lever-arm (calibration_options.hpp), declared once by the program.
void add_dead_reckoning_options(Options& options);
/// Reads them; nominal_k_m_per_pulse is 0 when --nominal-k was 0 (the caller fills it in).
DeadReckonerParams dead_reckoning_params_from(const Options& options);

}  // namespace odonav
