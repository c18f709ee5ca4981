#pragma once
// Private helpers shared by the estimator sources: input checks, the noise model, and the text
// format of save_state() / restore_state(). Not installed, not part of the API.
//
// State text, version 1: one "key value..." line each, first line "odonav-scale-factor-state 1",
// second "estimator <name>", parameters as "param.<name> <value>", doubles in C99 hex-float (%a, so
// the round trip is exact), last line "checksum <FNV-1a 64 of every byte before that line>".
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "odonav/estimators.hpp"
#include "odonav/scale_factor_estimator.hpp"

namespace odonav::estimators_internal {

/// Throws std::invalid_argument naming the estimator, the sample time and the bad field when a
/// value is not finite or phi_pulses <= 0 (accepted samples always move forward).
void check_sample(const std::string& estimator, const ScaleFactorSample& sample);

/// The conditions check_sample() enforces, without building the estimator's name: update() calls
/// check_sample() (which throws with the full message) only when this is false, so a good sample
/// costs a few compares instead of a std::string per update.
inline bool sample_is_valid(const ScaleFactorSample& sample) {
  return std::isfinite(sample.t_s) && std::isfinite(sample.phi_pulses) && sample.phi_pulses > 0.0 &&
         std::isfinite(sample.y_m) && std::isfinite(sample.dt_s) && sample.dt_s >= 0.0 &&
         std::isfinite(sample.gnss_position_enu_m[0]) && std::isfinite(sample.gnss_position_enu_m[1]) &&
         std::isfinite(sample.gnss_position_enu_m[2]);
}

/// Model residual variance [m^2] of the estimators: regression_noise_variance_m2
/// (scale_factor_estimator.hpp, docs/ALGORITHM.md "Estimators") with the params' sigma_v_mps and
/// sample_interval_s, at least sigma_y_floor_m^2.
/// Inline (with the two below): called on every update, a call costs as much as the arithmetic.
/// interval_s: the sample's own GNSS interval when known (> 0), so the model follows the GNSS rate
/// of the data (1 Hz samples carry ten times the velocity noise of 10 Hz ones); else
/// params.sample_interval_s.
inline double model_sigma_y2_m2(const ScaleFactorEstimatorParams& params, double k_m_per_pulse,
                                double interval_s = 0.0) {
  const double t = interval_s > 0.0 ? interval_s : params.sample_interval_s;
  const double model = regression_noise_variance_m2(params.sigma_v_mps, t, k_m_per_pulse);
  return std::max(model, params.sigma_y_floor_m * params.sigma_y_floor_m);
}

/// converged rule shared by every estimator: sigma / |K| < converged_rel_sigma and enough samples.
inline bool is_converged(const ScaleFactorEstimatorParams& params, double k, double sigma, uint64_t samples_used) {
  return samples_used >= params.min_samples && k != 0.0 && sigma / std::abs(k) < params.converged_rel_sigma;
}

/// The estimate of a least-squares estimator with total sums (prior included) s_pp [pulse^2] and
/// s_py [pulse m]: K = s_py / s_pp, sigma = sigma_y / sqrt(s_pp), converged per the params.
/// Invalid when no sample is held (has_samples false) or s_pp is not positive.
inline ScaleFactorEstimate least_squares_estimate(const ScaleFactorEstimatorParams& params, bool has_samples,
                                                  double s_pp, double s_py, double sigma_y_m, uint64_t samples_used,
                                                  double forgetting_factor, double window_fill) {
  ScaleFactorEstimate e;
  e.samples_used = samples_used;
  e.forgetting_factor = forgetting_factor;
  e.window_fill = window_fill;
  if (!has_samples || !(s_pp > 0.0)) return e;
  e.valid = true;
  e.k_m_per_pulse = s_py / s_pp;
  e.sigma_m_per_pulse = sigma_y_m / std::sqrt(s_pp);
  e.converged = is_converged(params, e.k_m_per_pulse, e.sigma_m_per_pulse, samples_used);
  return e;
}

class StateWriter {
 public:
  explicit StateWriter(const std::string& estimator_name);
  void put(const std::string& key, double value);
  void put_u64(const std::string& key, uint64_t value);
  void put_row(const std::string& key, const std::vector<double>& values);
  void put_params(const ScaleFactorEstimatorParams& params);
  std::string finish();

 private:
  std::string text_;
};

class StateReader {
 public:
  /// Parses and checks header, version, checksum and estimator name; throws std::runtime_error.
  StateReader(const std::string& text, const std::string& estimator_name);
  double get(const std::string& key) const;
  /// Whether a single-valued field is present (fields added in a later build are optional).
  bool has(const std::string& key) const { return single_.count(key) > 0; }
  uint64_t get_u64(const std::string& key) const;
  /// All rows stored under key, in order; each must have `width` values.
  std::vector<std::vector<double>> rows(const std::string& key, std::size_t width) const;
  /// Throws std::runtime_error when a parameter differs from the saved one (names it).
  void check_params(const ScaleFactorEstimatorParams& params) const;

 private:
  const std::vector<std::string>& values(const std::string& key) const;
  std::string estimator_;
  std::map<std::string, std::vector<std::string>> single_;
  std::map<std::string, std::vector<std::vector<std::string>>> rows_;
};

/// The change detector's fields in a state text (cusum_high, cusum_low, their runs' first sample,
/// changes_detected).
void put_change_detector(StateWriter& out, const CusumChangeDetector& detector);
/// Reads them back; throws std::runtime_error naming the field when one is missing or out of range.
CusumChangeDetector::State get_change_detector(const StateReader& in);

/// Until a few residuals are in, the online scale is too noisy to weight measurements with or to
/// normalise the change detector's residuals by.
constexpr uint64_t kMinResidualsForOnlineScale = 10;

}  // namespace odonav::estimators_internal
