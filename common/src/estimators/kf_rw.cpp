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
  ScaleFactorEstimate e = invalid_estimate(samples_used_, 1.0, 1.0);  // no forgetting, no window
  if (!initialised_ || samples_used_ == 0) return e;
  set_valid_estimate(e, params_, k_, std::sqrt(p_));
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

template <class Archive, class Self>
void KfRandomWalkEstimator::state_fields(Archive& a, Self& self) {
  a("initialised", self.initialised_)("k", self.k_)("p", self.p_)("samples_used", self.samples_used_);
  change_detector_fields(a, self.change_);
  residual_scale_fields(a, self.residual_scale_);
  a.check("k", std::isfinite(self.k_), "is not finite");
  a.check("p", self.p_ >= 0.0 && std::isfinite(self.p_), "is out of range");
  a.check("residual_scale", self.residual_scale_.variance_m2() >= 0.0, "has a negative variance");
}

StateJson KfRandomWalkEstimator::save_state() const { return save_estimator_fields(*this, name(), params_); }

void KfRandomWalkEstimator::restore_state(const StateJson& state) {
  // Restored into a copy: this one changes only when everything was read.
  *this = restored_estimator_copy(*this, state, name(), params_);
}

}  // namespace odonav
