#pragma once
// The identification parameters as command-line / config-file options, shared by odonav-offline and
// odonav-identification so both take the same flags with the same defaults (the cores' defaults).
#include "odonav/config.hpp"
#include "odonav/identification/identification_core.hpp"

namespace odonav {

/// Declares --estimator, --window, --lambda-min, --vff-kappa, --vff-c, --ff-lambda,
/// --converged-rel-sigma, --min-speed, --max-yaw-rate-deg-s, --innovation-n-sigma,
/// --gnss-velocity-sigma, --max-interval-s.
void add_identification_options(Options& options);

/// Reads them back (after Options::parse). Throws ConfigError naming the option when the
/// combination is invalid (e.g. an unknown estimator).
IdentificationParams identification_params_from(const Options& options);

}  // namespace odonav
