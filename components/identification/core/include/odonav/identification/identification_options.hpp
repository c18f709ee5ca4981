#pragma once
// The identification parameters as command-line / config-file options, shared by odonav-offline and
// odonav-identification so both take the same flags with the same defaults (the cores' defaults).
#include <optional>

#include <Eigen/Dense>

#include "odonav/defaults.hpp"
#include "odonav/config.hpp"
#include "odonav/identification/identification_core.hpp"

namespace odonav::identification {

/// Declares --estimator, --window, --lambda-min, --vff-kappa, --vff-c, --vff-change-threshold, --ff-lambda,
/// --converged-rel-sigma, --id-min-speed, --id-max-yaw-rate-deg-s, --innovation-n-sigma,
/// --gnss-velocity-sigma, --max-interval-s, --min-pulses, --[no-]reversing-samples, --gnss-latency-s.
void add_identification_options(Options& options);

/// --gnss-latency-s: "auto" (estimate = true, nothing fixed), "off" (estimate = false, nothing
/// fixed: latency 0) or seconds within +-10 (fixed). Throws ConfigError naming the option otherwise.
std::optional<double> parse_gnss_latency_option(const std::string& text, bool& estimate);

/// Reads them back (after Options::parse). Throws ConfigError naming the option when the
/// combination is invalid (e.g. an unknown estimator).
IdentificationParams identification_params_from(const Options& options);

/// What the identification must know of the vehicle besides its options. odonav-identification
/// takes these from its command line (--use-ins, --lever-arm, --nominal-k); odonav-offline from
/// the dataset (ins.csv present, meta.json's lever arm and nominal K, unless given as options).
struct IdentificationVehicleFacts {
  /// The vehicle has an INS; false = degraded mode (forward speed = |GNSS velocity|).
  bool use_ins = true;
  /// GNSS antenna in the INS body frame (forward-left-up, m) from the reference point; none = 0.
  std::optional<Eigen::Vector3d> lever_arm_body_m;
  /// The vehicle's nominal K (m/pulse, finite, > 0): the pulse-jump gate converts its maximum
  /// speed to pulses with it, so a fine encoder (small K) does not see real motion as a jump.
  double nominal_k_m_per_pulse = kDefaultNominalK_m_per_pulse;
  /// Also run every other estimator side by side (odonav-offline compares them; the node publishes
  /// the main one only).
  bool run_all_estimators = false;
};

/// The one place the identification parameters are built, for the node and odonav-offline alike
/// (so they cannot disagree on the same data): identification_params_from(options) plus the
/// vehicle facts. Throws ConfigError naming the option when the options are invalid, or
/// "nominal K" when facts.nominal_k_m_per_pulse is not finite and > 0.
IdentificationParams identification_params_for(const Options& options, const IdentificationVehicleFacts& facts);

}  // namespace odonav::identification
