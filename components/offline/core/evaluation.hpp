#pragma once
// Evaluation of odonav's outputs against a reference: scale-factor error against the true K, and dead
// reckoning error against a reference track (truth, or GNSS when there is no truth). Middleware-free,
// used by odonav-offline and by the pipeline's summary alike, so both report the same figures.
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "odonav/geodesy.hpp"

namespace odonav::offline {

/// A value at a time (t_s on the dataset's time base).
struct TimedValue {
  double t_s = 0.0;
  double value = 0.0;
};

/// A step of the true K at t_s (from the simulator's meta.json).
struct KStep {
  double t_s = 0.0;
  double k_before_m_per_pulse = 0.0;
  double k_after_m_per_pulse = 0.0;
};

/// Scale-factor accuracy figures. Times in seconds, errors relative (0.001 = 0.1 %).
struct KEvaluation {
  std::size_t epochs = 0;                 ///< estimates compared (after convergence, outside settle windows).
  double rms_rel_error = std::numeric_limits<double>::quiet_NaN();
  double max_rel_error = std::numeric_limits<double>::quiet_NaN();
  double final_rel_error = std::numeric_limits<double>::quiet_NaN();
  /// Time from the first valid motion until K stays within the tolerance (until the first K step or
  /// the end); NaN when it never does.
  double time_to_converge_s = std::numeric_limits<double>::quiet_NaN();
  /// Per K step: time from the step until K stays within the tolerance of the new K (until the next
  /// step or the end); NaN when it never does.
  std::vector<double> settle_times_s;
};

struct KEvaluationParams {
  double tolerance_rel = 0.005;       ///< "within 0.5 %".
  double settle_window_s = 10.0;      ///< excluded from the RMS after each step (the allowed settle time).
};

/// Compares an estimate series with the reference K (a step function: the latest reference value at
/// or before each estimate's time). first_motion_t_s: time of the first accepted regression sample.
/// The RMS covers estimates after convergence (time_to_converge), outside [step, step + settle_window).
KEvaluation evaluate_scale_factor(const std::vector<TimedValue>& estimate_m_per_pulse,
                                  const std::vector<TimedValue>& reference_m_per_pulse,
                                  const std::vector<KStep>& steps, double first_motion_t_s,
                                  const KEvaluationParams& params = {});

/// A position at a time.
struct TimedPosition {
  double t_s = 0.0;
  Geodetic position;
};

/// A span of time without GNSS.
struct Outage {
  double start_s = 0.0;
  double end_s = 0.0;
};

/// Dead-reckoning accuracy figures: horizontal error in metres and in % of distance travelled (%D).
struct DrEvaluation {
  std::size_t epochs = 0;
  double distance_m = 0.0;                  ///< distance travelled at the last compared epoch.
  double final_error_m = std::numeric_limits<double>::quiet_NaN();
  double final_error_percent = std::numeric_limits<double>::quiet_NaN();
  double max_error_m = std::numeric_limits<double>::quiet_NaN();
  double max_error_percent = std::numeric_limits<double>::quiet_NaN();  ///< over distance >= min_distance_m.
  /// Per outage: the error DR accumulates across the outage alone (as if re-initialised on the
  /// reference at the last reference epoch before it): |(DR_end - DR_start) - (ref_end - ref_start)|
  /// horizontally, in metres and in % of the distance travelled over the outage.
  std::vector<double> outage_error_m;
  std::vector<double> outage_error_percent;
};

/// Compares a DR track with a reference track (interpolated linearly in time; epochs outside the
/// reference's span are skipped). distance_m: distance travelled at each DR epoch (same length as dr).
/// min_distance_m: %D maxima ignore the first metres, where %D is meaningless.
DrEvaluation evaluate_dead_reckoning(const std::vector<TimedPosition>& dr, const std::vector<double>& distance_m,
                                     const std::vector<TimedPosition>& reference,
                                     const std::vector<Outage>& outages, double min_distance_m = 100.0);

}  // namespace odonav::offline
