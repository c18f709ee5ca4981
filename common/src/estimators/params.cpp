// Parameter validation, the factory, and the shared input checks and noise model.
#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "estimator_internal.hpp"
#include "odonav/estimators.hpp"

namespace odonav {

namespace {

std::string format_value(double value) {
  std::ostringstream out;
  out.precision(17);
  out << value;
  return out.str();
}

[[noreturn]] void bad_param(const char* name, double value, const char* range) {
  throw std::invalid_argument(std::string("ScaleFactorEstimatorParams: ") + name + " = " + format_value(value) +
                              " is invalid: must be " + range);
}

// Checks lo (<|<=) value (<|<=) hi; NaN fails every comparison so it is always rejected.
void check_range(const char* name, double value, double lo, bool lo_open, double hi, bool hi_open, const char* range) {
  const bool lo_ok = lo_open ? value > lo : value >= lo;
  const bool hi_ok = hi_open ? value < hi : value <= hi;
  if (!(lo_ok && hi_ok)) bad_param(name, value, range);
}

constexpr double kInf = HUGE_VAL;

}  // namespace

void ScaleFactorEstimatorParams::validate() const {
  if (!std::isfinite(k_prior_m_per_pulse)) bad_param("k_prior_m_per_pulse", k_prior_m_per_pulse, "finite");
  check_range("prior_weight_pulses2", prior_weight_pulses2, 0.0, false, kInf, true, "finite and >= 0");
  check_range("sigma_y_floor_m", sigma_y_floor_m, 0.0, true, kInf, true, "finite and > 0");
  check_range("sigma_y_ewma_alpha", sigma_y_ewma_alpha, 0.0, true, 1.0, false, "in (0, 1]");
  check_range("converged_rel_sigma", converged_rel_sigma, 0.0, true, 1.0, true, "in (0, 1)");
  if (min_samples < 1) bad_param("min_samples", static_cast<double>(min_samples), ">= 1");
  check_range("forgetting_factor", forgetting_factor, 0.0, true, 1.0, false, "in (0, 1]");
  if (window_length < 1 || window_length > 100000000u)
    bad_param("window_length", static_cast<double>(window_length), "in [1, 10^8]");
  if (resum_interval > 1000000000u)
    bad_param("resum_interval", static_cast<double>(resum_interval), "in [0, 10^9] (0 = window_length)");
  check_range("lambda_min", lambda_min, 0.0, true, 1.0, false, "in (0, 1]");
  check_range("vff_c_m2", vff_c_m2, 0.0, false, kInf, true, "finite and >= 0 (0 = automatic)");
  check_range("vff_kappa", vff_kappa, 0.0, true, kInf, true, "finite and > 0");
  check_range("vff_change_threshold", vff_change_threshold, 0.0, false, kInf, true, "finite and >= 0 (0 = off)");
  check_range("vff_change_drift", vff_change_drift, 0.0, false, kInf, true, "finite and >= 0");
  check_range("sigma_v_mps", sigma_v_mps, 0.0, false, kInf, true, "finite and >= 0");
  check_range("sample_interval_s", sample_interval_s, 0.0, true, kInf, true, "finite and > 0");
  check_range("coarse_min_length_m", coarse_min_length_m, 0.0, true, kInf, true, "finite and > 0");
  check_range("coarse_position_sigma_m", coarse_position_sigma_m, 0.0, false, kInf, true, "finite and >= 0");
  check_range("kf_rel_process_noise_per_sqrt_s", kf_rel_process_noise_per_sqrt_s, 0.0, false, kInf, true,
              "finite and >= 0");
  check_range("kf_change_threshold", kf_change_threshold, 0.0, true, kInf, true, "finite and > 0");
  check_range("kf_change_drift", kf_change_drift, 0.0, false, kInf, true, "finite and >= 0");
  check_range("kf_change_rel_sigma", kf_change_rel_sigma, 0.0, true, kInf, true, "finite and > 0");
}

std::vector<std::string> estimator_names() { return {"rls", "ff_rls", "lm_rls", "vff_lm_rls", "coarse", "kf_rw"}; }

std::unique_ptr<ScaleFactorEstimator> make_scale_factor_estimator(const std::string& name,
                                                                  const ScaleFactorEstimatorParams& params) {
  params.validate();
  if (name == "rls") return std::make_unique<RlsEstimator>(params);
  if (name == "ff_rls") return std::make_unique<FfRlsEstimator>(params);
  if (name == "lm_rls") return std::make_unique<LmRlsEstimator>(params);
  if (name == "vff_lm_rls") return std::make_unique<VffLmRlsEstimator>(params);
  if (name == "coarse") return std::make_unique<CoarseEstimator>(params);
  if (name == "kf_rw") return std::make_unique<KfRandomWalkEstimator>(params);
  std::string valid;
  for (const std::string& n : estimator_names()) valid += (valid.empty() ? "" : ", ") + n;
  throw std::invalid_argument("unknown scale-factor estimator '" + name + "'; valid names: " + valid);
}

namespace estimators_internal {

void check_sample(const std::string& estimator, const ScaleFactorSample& sample) {
  auto fail = [&](const char* field, double value, const char* rule) {
    throw std::invalid_argument(estimator + ": rejected sample at t_s = " + format_value(sample.t_s) + ": " + field +
                                " = " + format_value(value) + " " + rule);
  };
  if (!std::isfinite(sample.t_s)) fail("t_s", sample.t_s, "is not finite");
  if (!std::isfinite(sample.phi_pulses) || !(sample.phi_pulses > 0.0))
    fail("phi_pulses", sample.phi_pulses, "must be finite and > 0 (accepted samples move forward)");
  if (!std::isfinite(sample.y_m)) fail("y_m", sample.y_m, "is not finite");
  if (!std::isfinite(sample.dt_s) || sample.dt_s < 0.0) fail("dt_s", sample.dt_s, "must be finite and >= 0");
  for (int i = 0; i < 3; ++i)
    if (!std::isfinite(sample.gnss_position_enu_m[i]))
      fail(i == 0   ? "gnss_position_enu_m.east"
           : i == 1 ? "gnss_position_enu_m.north"
                    : "gnss_position_enu_m.up",
           sample.gnss_position_enu_m[i], "is not finite");
}

}  // namespace estimators_internal

void ResidualScaleTracker::add(double eps_m, double s) {
  double z = eps_m * eps_m / s;
  ++count_;
  if (count_ > 5) z = std::min(z, 9.0 * std::max(variance_m2_, floor_m_ * floor_m_));
  const double weight = std::max(alpha_, 1.0 / static_cast<double>(count_));
  variance_m2_ += weight * (z - variance_m2_);
}

double ResidualScaleTracker::sigma_m() const {
  if (count_ == 0) return floor_m_;
  return std::max(std::sqrt(variance_m2_), floor_m_);
}

}  // namespace odonav
