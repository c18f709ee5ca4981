#pragma once
// The odometer scale-factor estimators of docs/ALGORITHM.md §3, behind one interface so they can be
// compared side by side on the same samples.
//
// Regression (docs/ALGORITHM.md §2):  y_k = K * phi_k + e_k
//   phi_k: pulses counted over the sample interval [pulses] (>0 for accepted samples)
//   y_k:   distance along the odometer axis over the interval from GNSS velocity [m]
//   K:     odometer scale factor [m/pulse]
#include <cstdint>
#include <memory>
#include <string>

#include <Eigen/Dense>

#include "odonav/state_json.hpp"

namespace odonav {

/// One regression sample, built by the sample builder (sample_builder.hpp).
struct ScaleFactorSample {
  double t_s = 0.0;         ///< end of the interval (a GNSS epoch), seconds.
  double phi_pulses = 0.0;  ///< pulse increment over the interval.
  double y_m = 0.0;         ///< distance from GNSS velocity over the interval, metres.
  double dt_s = 0.0;        ///< interval length, seconds.
  /// GNSS position at t_s in a local ENU frame (metres); used by the coarse S/N calibration only.
  Eigen::Vector3d gnss_position_enu_m = Eigen::Vector3d::Zero();
  bool straight = true;  ///< the yaw-rate gate says this interval was on a straight line.
  /// GNSS speed along the direction of travel at t_s minus at t_s - dt_s (m/s). An error d of the
  /// GNSS latency in force (true minus applied, s) shifts the odometer's interval against the
  /// GNSS's and puts -d * speed_change_mps into y_m - K phi_pulses: what the estimators report as
  /// the sensitivity of K to the latency (ScaleFactorEstimate::dk_dlatency_m_per_pulse_per_s).
  double speed_change_mps = 0.0;
};

/// The sensor noise model of the regression (docs/ALGORITHM.md, "Estimators": sigma_y^2): the
/// variance [m^2] of the residual e_k = y_k - K phi_k that GNSS velocity noise and pulse
/// quantisation alone give over one sample interval,
///   sigma_y^2 = (sigma_v T)^2 / 2 + K^2 / 6.
/// Why these two terms: y = (v_start + v_end) / 2 * T carries two independent velocity errors of
/// sigma_v each, hence (sigma_v T)^2 / 2; phi is the difference of two counts each off by a uniform
/// fraction of a pulse, whose difference has a variance of 1/6 pulse^2, i.e. K^2 / 6 in metres.
/// sigma_v_mps: one-sigma GNSS velocity noise [m/s], >= 0; interval_s: T [s], >= 0; k_m_per_pulse:
/// K [m/pulse] (the current estimate). No floor and no estimate uncertainty: the estimators floor
/// it with sigma_y_floor_m (estimators.hpp), the sample builder's innovation gate adds
/// (sigma_K phi)^2 (sample_builder.hpp). Both use this one function.
inline double regression_noise_variance_m2(double sigma_v_mps, double interval_s, double k_m_per_pulse) {
  const double velocity_part_m = sigma_v_mps * interval_s;
  return 0.5 * velocity_part_m * velocity_part_m + k_m_per_pulse * k_m_per_pulse / 6.0;
}

/// What every estimator reports.
struct ScaleFactorEstimate {
  bool valid = false;              ///< false until the estimator has a value.
  double k_m_per_pulse = 0.0;      ///< K estimate.
  double sigma_m_per_pulse = 0.0;  ///< one-sigma of K (0 when unknown).
  double forgetting_factor = 1.0;  ///< lambda applied at the last update (1 for RLS / windows).
  double window_fill = 0.0;        ///< held samples / window capacity, 0..1 (1 for growing memory).
  bool converged = false;          ///< sigma below the convergence threshold.
  uint64_t samples_used = 0;       ///< samples given to update() since reset.
  /// dK/dd: how K moves with an error d of the GNSS latency in force (true minus applied, s),
  /// -sum w phi speed_change / sum w phi^2 over the samples behind K (m/pulse per s); 0 when the
  /// estimator does not report it (only lm_rls and vff_lm_rls do). docs/ALGORITHM.md "Honest sigma".
  double dk_dlatency_m_per_pulse_per_s = 0.0;
  /// After a detected change of K whose earlier samples are still in the window (vff_lm_rls): the
  /// one-sigma of K including the lag, sqrt(sigma_since^2 + (K - K_since)^2), K_since and
  /// sigma_since the least-squares K and its sigma over the samples since the change began
  /// (m/pulse); 0 otherwise. docs/ALGORITHM.md "Honest sigma".
  double lag_sigma_m_per_pulse = 0.0;
  /// sqrt(long-run variance / variance) of the residuals behind K (>= 1): the factor by which their
  /// serial correlation widens sigma_m_per_pulse (ResidualCorrelationTracker); 1 when the estimator
  /// does not report it (only lm_rls and vff_lm_rls do). docs/ALGORITHM.md "Honest sigma".
  double correlation_factor = 1.0;
};

class ScaleFactorEstimator {
 public:
  virtual ~ScaleFactorEstimator() = default;
  /// Short stable name: "rls", "ff_rls", "lm_rls", "vff_lm_rls", "coarse".
  virtual std::string name() const = 0;
  /// Feeds one accepted sample.
  virtual void update(const ScaleFactorSample& sample) = 0;
  /// Current estimate.
  virtual ScaleFactorEstimate estimate() const = 0;
  /// Forgets everything; the next estimate is invalid until new samples arrive.
  virtual void reset() = 0;

  // A restarted service resumes from the last state instead of re-converging for L samples; DDS
  // persistence keeps samples only, not estimator internals (docs/DDS.md §5).
  /// The complete internal state (checkpoint_state.hpp: every double exact, so a restored estimator
  /// continues bit-identically), with the estimator name and its parameters.
  virtual StateJson save_state() const = 0;
  /// Restores a save_state() state. Throws std::runtime_error (CheckpointError) naming the reason
  /// when it is malformed, of another estimator, or saved with different parameters; the estimator
  /// is then unchanged.
  virtual void restore_state(const StateJson& state) = 0;
};

}  // namespace odonav
