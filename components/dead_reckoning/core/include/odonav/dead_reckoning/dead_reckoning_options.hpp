#pragma once
// Dead-reckoning parameters as options, and the one function that makes DeadReckonerParams out of
// what a program knows, shared by odonav-offline and odonav-dead-reckoning so they cannot disagree.
#include <optional>

#include <Eigen/Dense>

#include "odonav/defaults.hpp"
#include "odonav/config.hpp"
#include "odonav/dead_reckoning/anchored_position.hpp"
#include "odonav/dead_reckoning/dead_reckoner.hpp"

namespace odonav::dead_reckoning {

/// Offset random walk (%D) of the navigation position at least, without INS: the DR heading is then
/// the GNSS course held through stops and turns.
inline constexpr double kDegradedAnchorDriftPercent = 1.0;

/// Declares --nominal-k (m/pulse; 0 = from the dataset's meta.json or 0.0125), --nominal-k-sigma-percent
/// (%; 0 = from meta.json or 3), --dr-mode 3d|2d and
/// the navigation position's --anchor-* flags.
/// The lever arm is --lever-arm (lever_arm_option.hpp), declared once by the program.
void add_dead_reckoning_options(Options& options);
/// Reads them; nominal_k_m_per_pulse is 0 when --nominal-k was 0 (the caller fills it in).
DeadReckonerParams dead_reckoning_params_from(const Options& options);

/// What a dead-reckoning configuration is made of, whoever runs it.
struct DeadReckoningFacts {
  DeadReckoningMode mode = DeadReckoningMode::k3D;  ///< --dr-mode
  /// The vehicle has an INS: --use-ins (odonav-dead-reckoning), the dataset has ins.csv (odonav-offline).
  bool use_ins = true;
  /// GNSS antenna in the body frame (forward-left-up, m) from the INS reference point: --lever-arm,
  /// else (odonav-offline) meta.json's; unset = the antenna is the reference point.
  std::optional<Eigen::Vector3d> lever_arm_body_m;
  /// --nominal-k (m/pulse); <= 0 = not given.
  double nominal_k_option_m_per_pulse = 0.0;
  /// The dataset's meta.json nominal K (m/pulse), if any (odonav-offline; none on a vehicle).
  std::optional<double> dataset_nominal_k_m_per_pulse;
  /// --nominal-k-sigma-percent (%); <= 0 = not given.
  double nominal_k_sigma_option_percent = 0.0;
  /// The dataset's meta.json odometer.k_nominal_sigma_percent (%), if any.
  std::optional<double> dataset_nominal_k_sigma_percent;
  /// --estimate-hold-off-s (s): hold_off_option.hpp.
  double estimate_hold_off_s = kDefaultEstimateHoldOff_s;
  /// The navigation position's --anchor-* flags (hold_off_s is set from estimate_hold_off_s by
  /// anchored_position_params).
  AnchoredPositionParams anchored;
};

/// --dr-mode, --nominal-k and --lever-arm (throws ConfigError naming --lever-arm when it is not
/// three finite numbers); use_ins true and no dataset K: the caller sets those it knows.
DeadReckoningFacts dead_reckoning_facts_from(const Options& options);

/// The one DeadReckonerParams of dead reckoning (defaults of DeadReckonerParams for the rest):
/// nominal K = --nominal-k when > 0, else the dataset's, else kDefaultNominalK_m_per_pulse; its
/// relative sigma likewise from --nominal-k-sigma-percent, meta.json, kDefaultNominalKRelSigma. That
/// nominal K is also the K of the pulse-jump gate (DeadReckonerParams::max_speed_mps / nominal K:
/// DeadReckoner derives the gate from it) and the reference of the commanded-K range
/// (consumer_rules.hpp commanded_k_problem), so both programs gate and accept alike.
DeadReckonerParams dead_reckoner_params(const DeadReckoningFacts& facts);

/// The one AnchoredPositionParams of the navigation position (odonav-offline and
/// odonav-dead-reckoning): facts.anchored (the --anchor-* flags), the hold-off the DR's
/// (--estimate-hold-off-s), and without INS (degraded mode) at least kDegradedAnchorDriftPercent.
AnchoredPositionParams anchored_position_params(const DeadReckoningFacts& facts);

}  // namespace odonav::dead_reckoning
