#pragma once
// "Never a silent zero": after a run, every main result that is missing or degenerate is named with
// the gate or cause, the threshold and the observed value, so that a user whose recording gives no K
// learns which setting to change instead of reading "accepted 0". Pure function of the run's facts.
#include <cstddef>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "odonav/offline/offline_runner.hpp"

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

/// The median interval between consecutive sample times, one time at a time: a count per distinct
/// interval, so memory grows with the number of distinct intervals (a few for a receiver's fixed
/// rate), not with the drive. Past kMaxDistinct distinct intervals (times with fine random jitter)
/// the intervals are counted to the microsecond.
class MedianPeriod {
 public:
  static constexpr std::size_t kMaxDistinct = std::size_t{1} << 16;
  /// The next sample's time (s), in time order.
  void add(double t_s);
  /// The median interval (s): of n intervals sorted, the one at index n / 2. NaN with fewer than
  /// two samples.
  double median_s() const;
  /// Distinct intervals counted (the memory used).
  std::size_t distinct() const { return count_by_interval_.size(); }

 private:
  std::map<double, std::size_t> count_by_interval_;
  std::size_t intervals_ = 0;
  std::optional<double> last_s_;
  bool rounded_ = false;
};

/// The median interval between consecutive samples' times (s); NaN with fewer than two samples.
double median_period_s(const std::vector<double>& times_s);

/// The facts of a run diagnose_run needs, gathered as the run streams: every input sample's time
/// and each output as it is produced, in constant memory (MedianPeriod aside).
class RunDiagnosisAccumulator {
 public:
  void add_odometer(double t_s);  ///< each odometer sample's time (s)
  void add_gnss(double t_s);      ///< each GNSS epoch's time (s), valid or not
  void add_ins(double t_s);       ///< each INS sample's time (s)
  /// Each identification output: its main estimate, the GNSS latency after it and whether that
  /// latency was decided (IdentificationOutput::latency_decided).
  void add_identification(const ScaleFactorEstimate& main, const GnssLatencyEstimate& latency = {},
                          bool latency_decided = true);
  void add_misalignment(const calibration::MisalignmentOutput& output);  ///< each calibration output
  /// Each online dead-reckoning output's time (s) and position (for the warning near a pole).
  void add_dead_reckoning(double t_s, const Geodetic& position);
  /// The warnings, from the facts gathered and the run's final gate counters.
  /// consistency: the dead reckoning's checks at the end (OfflineRunTotals::consistency; each one
  /// raised during the run is a warning "inconsistent_<check>" with its finding).
  RunDiagnosis finish(const OfflineParams& params, const SampleBuilderCounters& builder,
                      const calibration::MisalignmentCounters& calibration,
                      const dead_reckoning::DeadReckonerCounters& dead_reckoning,
                      const std::vector<dead_reckoning::ConsistencyState>& consistency = {},
                      const dead_reckoning::GnssJumpCounters& gnss_jumps = {}) const;

 private:
  struct Span {  // first and last time (s) of a stream, and its count
    std::size_t n = 0;
    double first_s = 0.0, last_s = 0.0;
    void add(double t_s);
  };
  Span odometer_, gnss_, dead_reckoning_;
  // Outputs within kPolarHeadingRadiusM of a pole: the first one's time, the closest distance.
  struct NearPole {
    std::size_t n = 0;
    double first_s = 0.0, closest_m = 0.0;
    bool north = true;
  } near_pole_;
  MedianPeriod gnss_period_;
  bool has_ins_ = false;
  std::optional<ScaleFactorEstimate> last_main_;
  std::optional<GnssLatencyEstimate> last_latency_;
  bool latency_ever_decided_ = false;
  bool last_latency_decided_ = true;
  std::optional<calibration::MisalignmentOutput> last_misalignment_;
};

/// Warnings of one run of run_offline over `dataset` with `params`: a RunDiagnosisAccumulator fed
/// the dataset and the result.
RunDiagnosis diagnose_run(const Dataset& dataset, const OfflineParams& params, const OfflineResult& result);

}  // namespace odonav::offline
