#pragma once
// "Never a silent zero": after a run, every main result that is missing or degenerate is named with
// the gate or cause, the threshold and the observed value, so that a user whose recording gives no K
// learns which setting to change instead of reading "accepted 0". Pure function of the run's facts.
#include <string>
#include <vector>

#include "offline_runner.hpp"

namespace odonav::offline {

struct RunWarning {
  /// Stable identifier, e.g. "no_k", "gnss_gap_gate", "no_misalignment", "no_dead_reckoning",
  /// "dead_reckoning_truncated", "no_time_overlap", "implausible_k".
  std::string code;
  std::string message;  ///< names the gate or cause, the threshold and the observed value.
};

struct RunDiagnosis {
  std::vector<RunWarning> warnings;
  /// False when the run's main result is missing: no identified K, or no (or truncated)
  /// dead-reckoning output.
  /// odonav-offline then exits with kExitNoUsableResult.
  bool usable = true;
};

/// Exit status of odonav-offline when it ran but produced no usable result (README, "Exit status").
inline constexpr int kExitNoUsableResult = 3;

/// The median interval between consecutive samples' times (s); NaN with fewer than two samples.
double median_period_s(const std::vector<double>& times_s);

/// Warnings of one run of run_offline over `dataset` with `params`.
RunDiagnosis diagnose_run(const Dataset& dataset, const OfflineParams& params, const OfflineResult& result);

}  // namespace odonav::offline
