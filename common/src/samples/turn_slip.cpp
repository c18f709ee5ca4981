#include "odonav/turn_slip.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "odonav/checkpoint_state.hpp"

namespace odonav {

void TurnSlipParams::validate() const {
  auto require = [](bool ok, const char* what) {
    if (!ok) throw std::invalid_argument(std::string("turn slip: ") + what);
  };
  require(min_samples >= 1, "min_samples must be >= 1");
  require(std::isfinite(min_significance_sigmas) && min_significance_sigmas > 0.0,
          "min_significance_sigmas must be > 0");
  require(std::isfinite(outlier_n_sigma) && outlier_n_sigma > 0.0, "outlier_n_sigma must be > 0");
  require(std::isfinite(max_slip_fraction) && max_slip_fraction > 0.0 && max_slip_fraction < 0.5,
          "max_slip_fraction must be in (0, 0.5)");
}

double turn_slip_fraction(double g_s_per_rad, double threshold_radps, double yaw_rate_radps) {
  const double s = g_s_per_rad * std::max(0.0, std::abs(yaw_rate_radps) - threshold_radps);
  if (!std::isfinite(s)) return 0.0;
  return std::clamp(s, 0.0, 0.5);
}

double turn_slip_gain_to_apply(bool applies, double g) { return applies && std::isfinite(g) && g > 0.0 ? g : 0.0; }

TurnSlipEstimator::TurnSlipEstimator(const TurnSlipParams& params) : params_(params) { params_.validate(); }

void TurnSlipEstimator::update(const TurnSlipSample& s) {
  const bool usable = std::isfinite(s.turn_pulses_radps) && s.turn_pulses_radps > 0.0 &&
                      std::isfinite(s.k_m_per_pulse) && s.k_m_per_pulse > 0.0 && std::isfinite(s.sigma_y_m) &&
                      s.sigma_y_m > 0.0 && std::isfinite(s.y_m) && std::isfinite(s.phi_pulses);
  if (!usable) return;
  const double r = s.y_m - s.k_m_per_pulse * s.phi_pulses;
  // Slip only shortens the GNSS distance against K phi, by at most max_slip_fraction of it: a
  // residual beyond that and the noise is a velocity outlier (the cross-track and speed-jump gates
  // let a glitch along the track through).
  if (std::abs(r) >
      params_.outlier_n_sigma * s.sigma_y_m + params_.max_slip_fraction * std::abs(s.k_m_per_pulse * s.phi_pulses)) {
    ++outliers_;
    return;
  }
  const double h = -s.k_m_per_pulse * s.turn_pulses_radps;
  const double w = 1.0 / (s.sigma_y_m * s.sigma_y_m);
  shh_ += w * h * h;
  shr_ += w * h * r;
  srr_ += w * r * r;
  ++samples_;
}

TurnSlipEstimate TurnSlipEstimator::estimate() const {
  TurnSlipEstimate e;
  e.samples = samples_;
  e.outliers = outliers_;
  if (samples_ == 0 || !(shh_ > 0.0)) {
    e.reason = "no turn samples yet";
    return e;
  }
  e.g_s_per_rad = shr_ / shh_;
  if (samples_ >= 2) {
    // Scaled by the residual scatter (never below the sensor noise alone): K's own error and a
    // slip that does not follow the model widen sigma instead of faking significance.
    const double chi2 = std::max(0.0, srr_ - e.g_s_per_rad * shr_);
    const double reduced = std::max(1.0, chi2 / static_cast<double>(samples_ - 1));
    e.sigma_s_per_rad = std::sqrt(reduced / shh_);
  }
  std::ostringstream why;
  if (samples_ < params_.min_samples) {
    why << samples_ << " turn samples < " << params_.min_samples;
  } else if (!(std::abs(e.g_s_per_rad) >= params_.min_significance_sigmas * e.sigma_s_per_rad)) {
    why << "|g| = " << std::abs(e.g_s_per_rad) << " s/rad < " << params_.min_significance_sigmas << " sigma (sigma "
        << e.sigma_s_per_rad << " s/rad)";
  } else if (e.g_s_per_rad < 0.0) {
    // Fewer pulses per metre in turns than on straights: not skid (a lever arm or a misalignment
    // not compensated would look like this); never applied, so the DR keeps K as identified.
    why << "g = " << e.g_s_per_rad << " s/rad < 0: not track slip";
  }
  e.reason = why.str();
  e.applies = e.reason.empty();
  return e;
}

template <class Archive, class Self>
void TurnSlipEstimator::state_fields(Archive& a, Self& self) {
  a("shh", self.shh_)("shr", self.shr_)("srr", self.srr_)("samples", self.samples_)("outliers", self.outliers_);
  a.check("shh", std::isfinite(self.shh_), "is not finite");
  a.check("shr", std::isfinite(self.shr_), "is not finite");
  a.check("srr", std::isfinite(self.srr_), "is not finite");
}

StateJson TurnSlipEstimator::save_state() const { return save_fields(*this); }

void TurnSlipEstimator::restore_state(const StateJson& state) {
  // Restored into a copy: this one changes only when everything was read.
  *this = restored_copy(*this, state, "turn_slip");
}

}  // namespace odonav
