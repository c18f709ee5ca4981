// Random-walk Kalman filter on K with a CUSUM change detector (see KfRandomWalkEstimator).
// Why: a window or a forgetting factor trades steady-state noise against tracking speed with one
// knob. A random walk with a small q is quiet in steady state; the detector opens the filter only
// when the innovations show a sustained bias (a real change of K), so it re-converges in a few
// samples instead of a window length.
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "estimator_internal.hpp"
#include "odonav/estimators.hpp"

namespace odonav {

using namespace estimators_internal;

KfRandomWalkEstimator::KfRandomWalkEstimator(const ScaleFactorEstimatorParams& params)
    : params_(params),
      residual_scale_(params.sigma_y_floor_m, params.sigma_y_ewma_alpha),
      change_(params.kf_change_threshold, params.kf_change_drift) {
  params_.validate();
}

void KfRandomWalkEstimator::update(const ScaleFactorSample& sample) {
  if (!sample_is_valid(sample)) check_sample(name(), sample);  // throws, naming the field
  const double phi = sample.phi_pulses;
  const double y = sample.y_m;
  const double k_for_model =
      initialised_ ? k_ : (params_.prior_weight_pulses2 > 0.0 ? params_.k_prior_m_per_pulse : y / phi);
  const double r = residual_scale_.count() >= kMinResidualsForOnlineScale
                       ? std::pow(residual_scale_.sigma_m(), 2)
                       : model_sigma_y2_m2(params_, k_for_model, sample.dt_s);
  if (!initialised_ && params_.prior_weight_pulses2 > 0.0) {
    k_ = params_.k_prior_m_per_pulse;
    p_ = r / params_.prior_weight_pulses2;
    initialised_ = true;
  }
  if (!initialised_) {
    k_ = y / phi;
    p_ = r / (phi * phi);
    initialised_ = true;
    ++samples_used_;
    return;
  }
  // Predict: K drifts as a random walk.
  const double dt = sample.dt_s > 0.0 ? sample.dt_s : params_.sample_interval_s;
  const double q = params_.kf_rel_process_noise_per_sqrt_s * k_;
  p_ += q * q * dt;
  // Update.
  const double innovation = y - k_ * phi;
  const double innovation_variance = phi * phi * p_ + r;
  residual_scale_.add(innovation, innovation_variance / r);
  const double gain = p_ * phi / innovation_variance;
  k_ += gain * innovation;
  p_ *= 1.0 - gain * phi;
  // Change detection on the normalised innovation.
  if (change_.add(innovation / std::sqrt(innovation_variance), samples_used_)) {
    const double sigma_change = params_.kf_change_rel_sigma * k_;
    p_ = std::max(p_, sigma_change * sigma_change);
  }
  ++samples_used_;
}

ScaleFactorEstimate KfRandomWalkEstimator::estimate() const {
  ScaleFactorEstimate e;
  e.samples_used = samples_used_;
  e.forgetting_factor = 1.0;
  e.window_fill = 1.0;
  if (!initialised_ || samples_used_ == 0) return e;
  e.valid = true;
  e.k_m_per_pulse = k_;
  e.sigma_m_per_pulse = std::sqrt(p_);
  e.converged = is_converged(params_, k_, e.sigma_m_per_pulse, samples_used_);
  return e;
}

void KfRandomWalkEstimator::reset() {
  initialised_ = false;
  k_ = 0.0;
  p_ = 0.0;
  change_.reset();
  samples_used_ = 0;
  residual_scale_.reset();
}

std::string KfRandomWalkEstimator::save_state() const {
  StateWriter out(name());
  out.put_params(params_);
  out.put_u64("initialised", initialised_ ? 1 : 0);
  out.put("k", k_);
  out.put("p", p_);
  put_change_detector(out, change_);
  out.put_u64("samples_used", samples_used_);
  out.put_u64("residual_count", residual_scale_.count());
  out.put("residual_variance", residual_scale_.variance_m2());
  return out.finish();
}

void KfRandomWalkEstimator::restore_state(const std::string& state) {
  const StateReader in(state, name());
  in.check_params(params_);
  const std::string where = "estimator state for 'kf_rw': ";
  const uint64_t initialised = in.get_u64("initialised");
  const double k = in.get("k");
  const double p = in.get("p");
  const CusumChangeDetector::State change = get_change_detector(in);
  const uint64_t samples_used = in.get_u64("samples_used");
  const uint64_t residual_count = in.get_u64("residual_count");
  const double residual_variance = in.get("residual_variance");
  if (initialised > 1) throw std::runtime_error(where + "initialised must be 0 or 1");
  if (!std::isfinite(k) || !(p >= 0.0) || !std::isfinite(p) || !(residual_variance >= 0.0))
    throw std::runtime_error(where + "K or variance out of range");
  initialised_ = initialised == 1;
  k_ = k;
  p_ = p;
  change_.set_state(change);
  samples_used_ = samples_used;
  residual_scale_.set_state(residual_count, residual_variance);
}

}  // namespace odonav
