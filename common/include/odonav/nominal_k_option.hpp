#pragma once
// --nominal-k: the vehicle's nominal odometer scale factor (m/pulse), one flag with one meaning in
// every program that declares it (odonav-identification, odonav-dead-reckoning, odonav-offline):
// the K dead reckoning uses until an identified K is accepted, the K of the pulse-jump gates and
// the reference of the commanded-K range (consumer_rules.hpp commanded_k_problem).
#include <optional>

#include "odonav/config.hpp"

namespace odonav {

/// Declares --nominal-k (m/pulse, 0..10; default 0 = not given: the dataset's meta.json
/// k_nominal_m_per_pulse when a dataset is read, else kDefaultNominalK_m_per_pulse), unless
/// declared already.
void add_nominal_k_option(Options& options);
/// The value given (m/pulse); 0 when not given.
double nominal_k_option_from(const Options& options);
/// The one resolution of the nominal K (m/pulse): option_m_per_pulse when > 0, else the dataset's
/// (meta.json, odonav-offline; none on a vehicle), else kDefaultNominalK_m_per_pulse.
double resolve_nominal_k(double option_m_per_pulse, std::optional<double> dataset_m_per_pulse = std::nullopt);

}  // namespace odonav
