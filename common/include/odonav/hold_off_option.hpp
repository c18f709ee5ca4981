#pragma once
// --estimate-hold-off-s: the hold-off d of the estimate-application rule (consumer_rules.hpp,
// estimate_applies_from_s). Declared by odonav-identification, odonav-dead-reckoning and
// odonav-offline, read by the shared parameter functions (identification_params_for,
// dead_reckoning_facts_from), so the nodes and the offline reference apply the same rule.
#include "odonav/config.hpp"

namespace odonav {

/// Declares --estimate-hold-off-s (default kDefaultEstimateHoldOff_s, 0..10 s), unless declared already.
void add_estimate_hold_off_option(Options& options);
/// Its value (s).
double estimate_hold_off_from(const Options& options);

}  // namespace odonav
