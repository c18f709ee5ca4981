#pragma once
// Private helpers shared by the estimator sources: input checks, the noise model, and the
// save_state() / restore_state() fields (checkpoint_state.hpp). Not installed, not part of the API.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "odonav/checkpoint_state.hpp"
#include "odonav/estimators.hpp"
#include "odonav/scale_factor_estimator.hpp"

namespace odonav {

ODONAV_STATE_FIELDS(CusumChangeDetector::State) {
  a("high", s.high)("low", s.low)("high_start", s.high_start)("low_start", s.low_start)("changes", s.changes);
}

}  // namespace odonav

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

/// An estimate that is not valid (yet): what every estimator reports whatever its state, the
/// samples used, the forgetting factor (1: none) and the window fill (1: no window).
inline ScaleFactorEstimate invalid_estimate(uint64_t samples_used, double forgetting_factor, double window_fill) {
  ScaleFactorEstimate e;
  e.samples_used = samples_used;
  e.forgetting_factor = forgetting_factor;
  e.window_fill = window_fill;
  return e;
}

/// Makes e valid with K = k_m_per_pulse and its one-sigma sigma_m_per_pulse (m/pulse), converged
/// per the params and e's samples_used.
inline void set_valid_estimate(ScaleFactorEstimate& e, const ScaleFactorEstimatorParams& params, double k_m_per_pulse,
                               double sigma_m_per_pulse) {
  e.valid = true;
  e.k_m_per_pulse = k_m_per_pulse;
  e.sigma_m_per_pulse = sigma_m_per_pulse;
  e.converged = is_converged(params, e.k_m_per_pulse, e.sigma_m_per_pulse, e.samples_used);
}

/// The estimate of a least-squares estimator with total sums (prior included) s_pp [pulse^2] and
/// s_py [pulse m]: K = s_py / s_pp, sigma = sigma_y / sqrt(s_pp), converged per the params.
/// Invalid when no sample is held (has_samples false) or s_pp is not positive.
inline ScaleFactorEstimate least_squares_estimate(const ScaleFactorEstimatorParams& params, bool has_samples,
                                                  double s_pp, double s_py, double sigma_y_m, uint64_t samples_used,
                                                  double forgetting_factor, double window_fill) {
  ScaleFactorEstimate e = invalid_estimate(samples_used, forgetting_factor, window_fill);
  if (!has_samples || !(s_pp > 0.0)) return e;
  set_valid_estimate(e, params, s_py / s_pp, sigma_y_m / std::sqrt(s_pp));
  return e;
}

/// An estimator's state (save_state): {"estimator": name, "params": {...}, its own fields}. `fields`
/// writes the estimator's fields (its state_fields, which only the estimator can reach).
StateJson save_estimator_state(const std::string& name, const ScaleFactorEstimatorParams& params,
                               const std::function<void(StateOut&)>& fields);
/// Reads such a state: the estimator's name and every parameter must be the same (bitwise: another
/// parameter would not continue identically), then `fields` reads the estimator's fields (into a
/// copy the caller commits). Throws CheckpointError "estimator state for '<name>': <what>".
void restore_estimator_state(const StateJson& state, const std::string& name, const ScaleFactorEstimatorParams& params,
                             const std::function<void(StateIn&)>& fields);

/// save_state() of estimator e: save_estimator_state with e's own state_fields.
template <class Estimator>
StateJson save_estimator_fields(const Estimator& e, const std::string& name, const ScaleFactorEstimatorParams& params) {
  return save_estimator_state(name, params, [&](StateOut& a) { StateAccess::fields(a, e); });
}

/// `copy` (the estimator before the restore) with its state_fields read from state by
/// restore_estimator_state; the caller commits it. Throws CheckpointError as that does.
template <class Estimator>
Estimator restored_estimator_copy(Estimator copy, const StateJson& state, const std::string& name,
                                  const ScaleFactorEstimatorParams& params) {
  restore_estimator_state(state, name, params, [&](StateIn& a) { StateAccess::fields(a, copy); });
  return copy;
}

/// The residual scale tracker's count and variance (saved and restored through its accessors).
template <class Archive, class Tracker>
void residual_scale_fields(Archive& a, Tracker& t) {
  a.via(
      "residual_scale", [&] { return std::make_pair(t.count(), t.variance_m2()); },
      [&](auto v) { t.set_state(v.first, v.second); });
}

/// The change detector's sums, their runs' first sample and the changes counted.
template <class Archive, class Detector>
void change_detector_fields(Archive& a, Detector& d) {
  a.via(
      "change_detector", [&] { return d.state(); }, [&](auto s) { d.set_state(s); });
}

/// Until a few residuals are in, the online scale is too noisy to weight measurements with or to
/// normalise the change detector's residuals by.
constexpr uint64_t kMinResidualsForOnlineScale = 10;

}  // namespace odonav::estimators_internal
