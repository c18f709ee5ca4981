#pragma once
// The concrete odometer scale-factor estimators of docs/ALGORITHM.md §3, their parameters and a factory.
//
// Regression (docs/ALGORITHM.md §2):  y_k = K * phi_k + e_k, scalar theta = K [m/pulse].
// Every least-squares estimator here keeps the two weighted sums
//   S_pp = w0 + sum_i w_i phi_i^2          [pulse^2]
//   S_py = w0 K0 + sum_i w_i phi_i y_i     [pulse m]
// and reports K = S_py / S_pp: that is the exact scalar RLS recursion written without P and gain, so
// each estimator equals a weighted batch least-squares solution over the same samples and weights
// (the acceptance test). w0, K0 is an optional prior pseudo-sample (k_prior_m_per_pulse,
// prior_weight_pulses2) that is a fixed regularisation: never forgotten, never dropped from a window.
//
//   rls         w_i = 1 for every sample since reset (growing memory; cannot track: data saturation).
//   ff_rls      w_i = lambda^(k-i), constant lambda (fading memory of about 1/(1-lambda) samples).
//   lm_rls      w_i = 1 for the last L accepted samples, 0 before (sliding window).
//   vff_lm_rls  the last L samples, w_i = prod_{j=i+1..k} lambda_j with the Fortescue-type variable
//               forgetting factor lambda_j of docs/ALGORITHM.md §3 (1 while the window is filling).
//   coarse      K = sum S / sum N over straight runs (the traditional baseline), S from GNSS positions.
//   kf_rw       random-walk Kalman filter on K with an innovation-based change detector (the
//               ALGORITHM's "open goal": fast after a jump, quiet in steady state).
//
// Sigma: sigma_K = sigma_y / sqrt(S_pp). sigma_y is estimated online from the a-priori residuals
// eps = y - K_prev * phi, normalised by s = 1 + phi^2 / S_pp (for RLS E[eps^2] = s sigma_y^2 exactly),
// with a clipped (robust) exponentially weighted mean, floored by sigma_y_floor_m. For weighted sums
// (w_i <= 1) sigma_y / sqrt(S_pp) is an upper bound of the true one-sigma, so it errs on the safe side.
//
// Bad samples (non-finite values, phi <= 0) are rejected with std::invalid_argument naming the
// estimator, the sample time and the field; the estimator state is then unchanged.
#include <algorithm>
#include <cstddef>
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "odonav/residual_correlation.hpp"
#include "odonav/scale_factor_estimator.hpp"

namespace odonav {

/// Every parameter of every estimator, with its unit, default and valid range.
/// validate() throws std::invalid_argument naming the first bad parameter and its value.
struct ScaleFactorEstimatorParams {
  // --- prior (rls, ff_rls, lm_rls, vff_lm_rls, kf_rw) ---
  /// Prior K [m/pulse], any finite value; used only when prior_weight_pulses2 > 0.
  double k_prior_m_per_pulse = 0.0;
  /// Weight of the prior as a pseudo-sample with phi^2 = this [pulse^2], >= 0. 0 = no prior: the
  /// first estimate is then y/phi of the first sample. A weak prior is e.g. 1 (one pulse's worth).
  double prior_weight_pulses2 = 0.0;

  // --- accuracy and convergence (all estimators) ---
  /// Lower bound of the online residual scale sigma_y [m], > 0. Keeps sigma_K honest on clean data.
  double sigma_y_floor_m = 1e-3;
  /// Weight of a new residual in the sigma_y^2 running mean, in (0, 1]. 0.02 ~ the last 50 samples.
  double sigma_y_ewma_alpha = 0.02;
  /// Converged when sigma_K / |K| is below this (dimensionless), in (0, 1).
  double converged_rel_sigma = 0.001;
  /// ... and at least this many samples were used since reset, >= 1.
  uint64_t min_samples = 10;

  // --- ff_rls ---
  /// Constant forgetting factor lambda of FF-RLS, in (0, 1]. 0.99 ~ a memory of 100 samples (10 s
  /// at 10 Hz), comparable with the default window.
  double forgetting_factor = 0.99;

  // --- lm_rls, vff_lm_rls ---
  /// Window length L [accepted samples], in [1, 10^8]. 100 = 10 s at 10 Hz.
  std::size_t window_length = 100;
  /// Exact re-summation of the window sums every M samples, M in [1, 10^9]; 0 = M = L.
  /// Why L: the re-summation costs O(L), so every L samples it costs O(1) amortised (it doubles the
  /// per-sample work at most), and the downdating drift between two re-summations is about
  /// L * 1e-16 relative, far below anything measurable. It also re-bases the log-weights.
  std::size_t resum_interval = 0;

  // --- vff_lm_rls ---
  /// Lower clamp of the variable forgetting factor per sample_interval_s of sample interval, in
  /// (0, 1]: a sample spanning n such intervals is clamped at lambda_min^n, and the law's memory L
  /// counts in the same intervals (L / n samples), so VFF forgets per second at every GNSS rate.
  double lambda_min = 0.95;
  /// Residual variance scale C of the VFF law [m^2], >= 0. 0 = automatic: C = vff_kappa * sigma_y^2
  /// with sigma_y^2 = (sigma_v_mps * T)^2 / 2 + K^2 / 6 (GNSS velocity noise plus
  /// pulse quantisation, K the current estimate; regression_noise_variance_m2), never below
  /// sigma_y_floor_m^2.
  double vff_c_m2 = 0.0;
  /// kappa of the automatic C, > 0 (docs/ALGORITHM.md §3: 1..10).
  double vff_kappa = 4.0;
  /// Change detector of vff_lm_rls: threshold of the two-sided CUSUM of the normalised a-priori
  /// residuals (dimensionless), >= 0; 0 = off. When one side passes it (a sustained bias: a change
  /// of K, not one outlier) the window is cut back to the samples since that side's run began, but
  /// never below window_length reference intervals (sample_interval_s each: 10 s by default, all of
  /// the window at 10 Hz). Why: the VFF law stops forgetting once the residuals look like noise,
  /// while the window still holds the samples from before the change (docs/ALGORITHM.md §3). The
  /// same detector and threshold as kf_rw's.
  double vff_change_threshold = 12.0;
  /// Change detector of vff_lm_rls: drift (allowance) subtracted per sample from the CUSUM, >= 0.
  double vff_change_drift = 0.5;
  /// One-sigma GNSS velocity noise [m/s], >= 0 (automatic C, kf_rw measurement noise prior).
  double sigma_v_mps = 0.05;
  /// Sample interval T [s], > 0, for samples that do not carry their own (dt_s 0): every sample of
  /// the sample builder carries its GNSS interval, so the noise model follows the data's rate.
  /// Also the reference interval of the VFF law's lambda_min and memory (see lambda_min).
  double sample_interval_s = 0.1;

  // --- coarse ---
  /// A straight run counts when its straight-line length S is at least this [m], > 0.
  double coarse_min_length_m = 100.0;
  /// One-sigma GNSS position noise [m], >= 0, for sigma_K of the coarse method (each run end).
  double coarse_position_sigma_m = 1.0;

  // --- kf_rw ---
  /// Random-walk spectral density of K relative to K [1/sqrt(s)], >= 0: the K state gains
  /// (q * K)^2 * dt of variance per sample. 1e-5 ~ 0.1 % drift over 10^4 s (wear, temperature).
  double kf_rel_process_noise_per_sqrt_s = 1e-5;
  /// Change detector: threshold of the CUSUM of normalised innovations (dimensionless), > 0.
  double kf_change_threshold = 12.0;
  /// Change detector: drift (allowance) subtracted per sample from the CUSUM, >= 0.
  double kf_change_drift = 0.5;
  /// On a detected change the K variance is set to at least (this * K)^2, > 0 (relative, e.g. 5 %).
  double kf_change_rel_sigma = 0.05;

  /// Throws std::invalid_argument("ScaleFactorEstimatorParams: <name> = <value> is invalid: <range>").
  void validate() const;
};

/// The names make_scale_factor_estimator() accepts, in a stable order.
std::vector<std::string> estimator_names();

/// Builds an estimator by name (see estimator_names()). Validates params first.
/// Throws std::invalid_argument for an unknown name (listing the valid ones) or invalid params.
std::unique_ptr<ScaleFactorEstimator> make_scale_factor_estimator(const std::string& name,
                                                                  const ScaleFactorEstimatorParams& params);

/// Online robust estimate of the residual scale sigma_y [m] from a-priori residuals (see top).
class ResidualScaleTracker {
 public:
  /// floor_m [m] > 0: the smallest sigma reported; alpha in (0, 1]: weight of a new residual.
  ResidualScaleTracker(double floor_m, double alpha) : floor_m_(floor_m), alpha_(alpha) {}
  /// Adds one a-priori residual eps [m] with its variance inflation s = 1 + phi^2/S_pp (>= 1).
  /// The first residuals form a plain mean (weight 1/n until it falls to alpha); from the 6th on a
  /// residual is clipped at 3 sigma so one GNSS outlier cannot blow sigma_y up, while a real change
  /// still raises it by up to a factor (1 + 8 alpha) per sample.
  void add(double eps_m, double s);
  /// max(sqrt(running mean of eps^2/s), floor) [m]; the floor when nothing was added.
  double sigma_m() const;
  void reset() {
    count_ = 0;
    variance_m2_ = 0.0;
  }
  uint64_t count() const { return count_; }
  double variance_m2() const { return variance_m2_; }
  /// For save/restore.
  void set_state(uint64_t count, double variance_m2) {
    count_ = count;
    variance_m2_ = variance_m2;
  }

 private:
  double floor_m_;
  double alpha_;
  uint64_t count_ = 0;
  double variance_m2_ = 0.0;
};

/// Two-sided CUSUM of normalised residuals z (dimensionless, about N(0, 1) while the model holds):
///   high = max(0, high + z - drift),  low = max(0, low - z - drift).
/// A side over threshold is a sustained bias (a change), not one outlier: add() then reports the
/// change, with the index of the first sample of the run that raised it (the sample after that
/// side was last at 0: where the change began), and both sums restart. Used by kf_rw and vff_lm_rls.
class CusumChangeDetector {
 public:
  /// threshold > 0, drift >= 0 (validated with the estimator parameters).
  CusumChangeDetector(double threshold, double drift) : threshold_(threshold), drift_(drift) {}
  /// Adds the normalised residual z of the sample with index `index` (0, 1, ... in order).
  /// Returns the index of the first sample of the run on a detected change, nullopt otherwise.
  std::optional<uint64_t> add(double z, uint64_t index);
  /// The larger side over the threshold (>= 0; a change fires above 1).
  double statistic() const { return threshold_ > 0.0 ? std::max(high_, low_) / threshold_ : 0.0; }
  uint64_t changes_detected() const { return changes_; }
  void reset() { *this = CusumChangeDetector(threshold_, drift_); }

  /// For save/restore: the two sums, the first index of each side's run, the changes counted.
  struct State {
    double high = 0.0, low = 0.0;
    uint64_t high_start = 0, low_start = 0, changes = 0;
  };
  State state() const { return {high_, low_, high_start_, low_start_, changes_}; }
  /// Throws std::runtime_error when a sum is negative or not finite.
  void set_state(const State& s);

 private:
  double threshold_;
  double drift_;
  double high_ = 0.0;
  double low_ = 0.0;
  uint64_t high_start_ = 0;
  uint64_t low_start_ = 0;
  uint64_t changes_ = 0;
};

/// Growing-memory RLS ("rls") and constant-forgetting RLS ("ff_rls").
class RlsEstimator : public ScaleFactorEstimator {
 public:
  /// Growing memory (lambda = 1), name "rls".
  explicit RlsEstimator(const ScaleFactorEstimatorParams& params);
  std::string name() const override { return name_; }
  void update(const ScaleFactorSample& sample) override;
  ScaleFactorEstimate estimate() const override;
  void reset() override;
  StateJson save_state() const override;
  void restore_state(const StateJson& state) override;

  /// The data sums without the prior: S_pp [pulse^2], S_py [pulse m].
  double data_s_pp() const { return s_pp_; }
  double data_s_py() const { return s_py_; }

 protected:
  /// Constant forgetting factor lambda in (0, 1]; used by FfRlsEstimator.
  RlsEstimator(const ScaleFactorEstimatorParams& params, double lambda, std::string name);

 private:
  // The state's fields, listed once for save_state() and restore_state() (checkpoint_state.hpp).
  friend struct StateAccess;  // the estimators' save_state() / restore_state() reach state_fields
  template <class Archive, class Self>
  static void state_fields(Archive& a, Self& self);
  ScaleFactorEstimatorParams params_;
  double lambda_;
  std::string name_;
  double s_pp_ = 0.0;
  double s_py_ = 0.0;
  uint64_t samples_used_ = 0;
  ResidualScaleTracker residual_scale_;
};

/// FF-RLS: RLS with the constant forgetting factor params.forgetting_factor ("ff_rls").
class FfRlsEstimator : public RlsEstimator {
 public:
  explicit FfRlsEstimator(const ScaleFactorEstimatorParams& params);
};

/// The window sums of a sliding-window estimator, for checks and diagnostics.
struct WindowSums {
  double s_pp = 0.0;     ///< sum of w_i phi_i^2 over the window, prior excluded [pulse^2].
  double s_py = 0.0;     ///< sum of w_i phi_i y_i over the window, prior excluded [pulse m].
  std::size_t held = 0;  ///< samples in the window.
  /// sum of w_i phi_i speed_change_i over the window [pulse m/s] (ScaleFactorSample::speed_change_mps).
  double s_pdv = 0.0;
};

/// Sliding-window RLS: LM-RLS ("lm_rls", lambda = 1) and VFF-LM-RLS ("vff_lm_rls"), exact and O(1)
/// per sample with a ring buffer of (phi, y, Lambda_i), Lambda the running sum of ln(lambda).
/// The sample leaving the window is removed with its current weight exp(Lambda - Lambda_o).
class WindowRlsEstimator : public ScaleFactorEstimator {
 public:
  std::string name() const override { return variable_forgetting_ ? "vff_lm_rls" : "lm_rls"; }
  void update(const ScaleFactorSample& sample) override;
  ScaleFactorEstimate estimate() const override;
  void reset() override;
  StateJson save_state() const override;
  void restore_state(const StateJson& state) override;

  /// The O(1)-updated window sums.
  WindowSums window_sums() const;
  /// The same sums re-computed from the buffer, exactly (no state change): for drift checks.
  WindowSums exact_window_sums() const;
  /// Running sum of ln(lambda) since the last re-basing; stays within M * |ln lambda_min|.
  double log_weight() const { return log_weight_; }
  /// The residual variance scale C [m^2] the VFF law would use with the estimate K [m/pulse] for a
  /// sample spanning interval_s [s] (0: params' sample_interval_s).
  double vff_c_m2(double k_m_per_pulse, double interval_s = 0.0) const;
  /// vff_lm_rls: changes of K its detector found since reset (each cut the window back).
  uint64_t changes_detected() const { return change_.changes_detected(); }
  /// vff_lm_rls: index (0 = the first sample since reset) of the first sample of the last detected
  /// change, nothing before any; the estimate's lag_sigma_m_per_pulse while samples from before it
  /// are still in the window.
  std::optional<uint64_t> last_change_began() const { return change_began_; }

 protected:
  WindowRlsEstimator(const ScaleFactorEstimatorParams& params, bool variable_forgetting);

 private:
  struct Entry {
    double phi = 0.0;
    double y = 0.0;
    double log_weight = 0.0;  // Lambda when the sample entered (after its own lambda)
    double dv = 0.0;          // speed_change_mps
  };
  // sqrt(sigma_since^2 + (K - K_since)^2) over the samples since change_began_ (see
  // ScaleFactorEstimate::lag_sigma_m_per_pulse), 0 when every held sample is from after it.
  double lag_sigma(double k_m_per_pulse, double sigma_y_m) const;
  // The state's fields, listed once for save_state() and restore_state() (checkpoint_state.hpp).
  friend struct StateAccess;  // the estimators' save_state() / restore_state() reach state_fields
  template <class Archive, class Self>
  static void state_fields(Archive& a, Self& self);
  // The window rows (phi, y, Lambda, speed change) restored into e; the const overload is the
  // save side's, where state_fields never calls it (it exists so both sides compile).
  static void restore_window(WindowRlsEstimator& e, const std::vector<std::array<double, 4>>& rows);
  static void restore_window(const WindowRlsEstimator&, const std::vector<std::array<double, 4>>&) {}
  void resum();
  // Drops the samples before index first_kept (samples_used_ counting), keeping at least
  // window_length reference intervals at the newest sample's interval_s, and re-sums. Returns
  // whether it dropped any.
  bool cut_window(uint64_t first_kept, double interval_s);
  const Entry& entry(std::size_t age_index) const;  // 0 = oldest

  ScaleFactorEstimatorParams params_;
  bool variable_forgetting_;
  std::size_t capacity_;
  std::size_t resum_interval_;
  std::vector<Entry> buffer_;
  std::size_t oldest_ = 0;
  std::size_t held_ = 0;
  double s_pp_ = 0.0;
  double s_py_ = 0.0;
  double s_pdv_ = 0.0;
  double log_weight_ = 0.0;
  double last_lambda_ = 1.0;
  std::size_t since_resum_ = 0;
  uint64_t samples_used_ = 0;
  ResidualScaleTracker residual_scale_;
  ResidualCorrelationTracker residual_correlation_;
  CusumChangeDetector change_;
  std::optional<uint64_t> change_began_;  // first sample of the last detected change (samples_used_ index)
};

/// LM-RLS: the last window_length samples with equal weights ("lm_rls").
class LmRlsEstimator : public WindowRlsEstimator {
 public:
  explicit LmRlsEstimator(const ScaleFactorEstimatorParams& params) : WindowRlsEstimator(params, false) {}
};

/// VFF-LM-RLS, the paper's method ("vff_lm_rls"): the window weighted by the variable forgetting
/// factor lambda = clamp(1 - eps^2 / (s L C), lambda_min, 1) once the window is full, 1 before;
/// with odonav's change detector (vff_change_threshold) that cuts the window back after a change.
class VffLmRlsEstimator : public WindowRlsEstimator {
 public:
  explicit VffLmRlsEstimator(const ScaleFactorEstimatorParams& params) : WindowRlsEstimator(params, true) {}
};

/// Coarse S/N ("coarse"): over each run of consecutive straight samples, S = straight-line (3-D)
/// distance between the GNSS positions at the start and the end of the run, N = sum of phi over
/// the run; a run counts when S >= coarse_min_length_m; K = sum S / sum N over counted runs.
/// A run starts at the position of the previous sample when that one is contiguous in time (its t_s
/// equals this sample's t_s - dt_s), because that is where this sample's pulses began; otherwise
/// (first sample, or a time gap from gated-out samples) the first straight sample only marks the
/// start point and its pulses are not counted. A time gap or a non-straight sample ends the run,
/// so N always counts exactly the pulses between the two positions. Invalid until a run counted.
/// sigma_K = sqrt(2 * runs) * coarse_position_sigma_m / sum N.
class CoarseEstimator : public ScaleFactorEstimator {
 public:
  explicit CoarseEstimator(const ScaleFactorEstimatorParams& params);
  std::string name() const override { return "coarse"; }
  void update(const ScaleFactorSample& sample) override;
  ScaleFactorEstimate estimate() const override;
  void reset() override;
  StateJson save_state() const override;
  void restore_state(const StateJson& state) override;

  /// Counted runs so far, and their totals: sum S [m], sum N [pulses].
  uint64_t runs_counted() const { return runs_counted_; }
  double total_length_m() const { return total_length_m_; }
  double total_pulses() const { return total_pulses_; }

 private:
  // The state's fields, listed once for save_state() and restore_state() (checkpoint_state.hpp).
  friend struct StateAccess;  // the estimators' save_state() / restore_state() reach state_fields
  template <class Archive, class Self>
  static void state_fields(Archive& a, Self& self);
  void close_run();

  ScaleFactorEstimatorParams params_;
  bool have_previous_ = false;
  double previous_t_s_ = 0.0;
  Eigen::Vector3d previous_position_m_ = Eigen::Vector3d::Zero();
  bool run_open_ = false;
  Eigen::Vector3d run_start_m_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d run_end_m_ = Eigen::Vector3d::Zero();
  double run_pulses_ = 0.0;
  uint64_t runs_counted_ = 0;
  double total_length_m_ = 0.0;
  double total_pulses_ = 0.0;
  uint64_t samples_used_ = 0;
};

/// Random-walk Kalman filter on K ("kf_rw"): state K, variance P [m^2/pulse^2].
///   predict: P += (q K)^2 dt        (q = kf_rel_process_noise_per_sqrt_s, dt = sample dt_s or T)
///   update:  r = sigma_y^2, innovation nu = y - K phi, S = phi^2 P + r, K += P phi nu / S.
/// Change detector: two-sided CUSUM of nu / sqrt(S) with drift kf_change_drift; when one side passes
/// kf_change_threshold (a sustained bias, not one outlier) P is raised to (kf_change_rel_sigma K)^2
/// so the filter re-converges in a few samples, and both sums restart. forgetting_factor and
/// window_fill report 1 (no window; memory is set by q).
/// Without a prior the first sample initialises K = y/phi, P = sigma_y^2 / phi^2.
class KfRandomWalkEstimator : public ScaleFactorEstimator {
 public:
  explicit KfRandomWalkEstimator(const ScaleFactorEstimatorParams& params);
  std::string name() const override { return "kf_rw"; }
  void update(const ScaleFactorSample& sample) override;
  ScaleFactorEstimate estimate() const override;
  void reset() override;
  StateJson save_state() const override;
  void restore_state(const StateJson& state) override;

  /// Changes detected since reset.
  uint64_t changes_detected() const { return change_.changes_detected(); }
  /// The larger CUSUM side over its threshold (dimensionless, >= 0; a change fires above 1).
  double change_statistic() const { return change_.statistic(); }

 private:
  // The state's fields, listed once for save_state() and restore_state() (checkpoint_state.hpp).
  friend struct StateAccess;  // the estimators' save_state() / restore_state() reach state_fields
  template <class Archive, class Self>
  static void state_fields(Archive& a, Self& self);
  ScaleFactorEstimatorParams params_;
  bool initialised_ = false;
  double k_ = 0.0;
  double p_ = 0.0;
  uint64_t samples_used_ = 0;
  ResidualScaleTracker residual_scale_;
  CusumChangeDetector change_;
};

}  // namespace odonav
