// RLS (growing memory) and FF-RLS (constant forgetting factor), scalar, written with the sums
// S_pp = lambda S_pp + phi^2, S_py = lambda S_py + phi y: the exact RLS recursion for theta = K
// (P = 1/S_pp, gain = phi/S_pp), with no matrix to lose symmetry or positivity.
#include <cmath>
#include <stdexcept>

#include "estimator_internal.hpp"
#include "odonav/estimators.hpp"

namespace odonav {

using namespace estimators_internal;

RlsEstimator::RlsEstimator(const ScaleFactorEstimatorParams& params) : RlsEstimator(params, 1.0, "rls") {}

RlsEstimator::RlsEstimator(const ScaleFactorEstimatorParams& params, double lambda, std::string name)
    : params_(params),
      lambda_(lambda),
      name_(std::move(name)),
      residual_scale_(params.sigma_y_floor_m, params.sigma_y_ewma_alpha) {
  params_.validate();
}

FfRlsEstimator::FfRlsEstimator(const ScaleFactorEstimatorParams& params)
    : RlsEstimator(params, params.forgetting_factor, "ff_rls") {}

void RlsEstimator::update(const ScaleFactorSample& sample) {
  check_sample(name_, sample);
  const double phi = sample.phi_pulses;
  const double y = sample.y_m;
  const double w0 = params_.prior_weight_pulses2;
  const double s_pp_total = s_pp_ + w0;
  if (samples_used_ > 0 && s_pp_total > 0.0) {
    const double k_prev = (s_py_ + w0 * params_.k_prior_m_per_pulse) / s_pp_total;
    residual_scale_.add(y - k_prev * phi, 1.0 + phi * phi / s_pp_total);
  }
  // The prior is a fixed regulariser, so only the data sums fade.
  s_pp_ = lambda_ * s_pp_ + phi * phi;
  s_py_ = lambda_ * s_py_ + phi * y;
  ++samples_used_;
}

ScaleFactorEstimate RlsEstimator::estimate() const {
  const double w0 = params_.prior_weight_pulses2;
  return least_squares_estimate(params_, samples_used_ > 0, s_pp_ + w0, s_py_ + w0 * params_.k_prior_m_per_pulse,
                                residual_scale_.sigma_m(), samples_used_, lambda_, 1.0);
}

void RlsEstimator::reset() {
  s_pp_ = 0.0;
  s_py_ = 0.0;
  samples_used_ = 0;
  residual_scale_.reset();
}

template <class Archive, class Self>
void RlsEstimator::state_fields(Archive& a, Self& self) {
  a("s_pp", self.s_pp_)("s_py", self.s_py_)("samples_used", self.samples_used_);
  residual_scale_fields(a, self.residual_scale_);
  a.check("s_pp", self.s_pp_ >= 0.0 && std::isfinite(self.s_pp_), "is out of range");
  a.check("s_py", std::isfinite(self.s_py_), "is not finite");
  a.check("residual_scale", self.residual_scale_.variance_m2() >= 0.0, "has a negative variance");
}

StateJson RlsEstimator::save_state() const { return save_estimator_fields(*this, name_, params_); }

void RlsEstimator::restore_state(const StateJson& state) {
  // Restored into a copy: this one changes only when everything was read.
  *this = restored_estimator_copy(*this, state, name_, params_);
}

}  // namespace odonav
