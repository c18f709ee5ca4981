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

std::string RlsEstimator::save_state() const {
  StateWriter out(name_);
  out.put_params(params_);
  out.put("s_pp", s_pp_);
  out.put("s_py", s_py_);
  out.put_u64("samples_used", samples_used_);
  out.put_u64("residual_count", residual_scale_.count());
  out.put("residual_variance", residual_scale_.variance_m2());
  return out.finish();
}

void RlsEstimator::restore_state(const std::string& state) {
  const StateReader in(state, name_);
  in.check_params(params_);
  const double s_pp = in.get("s_pp");
  const double s_py = in.get("s_py");
  const uint64_t samples_used = in.get_u64("samples_used");
  const uint64_t residual_count = in.get_u64("residual_count");
  const double residual_variance = in.get("residual_variance");
  if (!(s_pp >= 0.0) || !std::isfinite(s_pp) || !std::isfinite(s_py) || !(residual_variance >= 0.0))
    throw std::runtime_error("estimator state for '" + name_ + "': sums or residual variance out of range");
  s_pp_ = s_pp;
  s_py_ = s_py;
  samples_used_ = samples_used;
  residual_scale_.set_state(residual_count, residual_variance);
}

}  // namespace odonav
