// LM-RLS and VFF-LM-RLS: a sliding window of the last L accepted samples, exact and O(1) per sample
// (docs/ALGORITHM.md §3). The window sums are scaled by lambda on every update, so a sample that entered
// when the running log-weight was Lambda_i has weight exp(Lambda - Lambda_i) now: the product of the
// lambdas applied since, not lambda^L. That is the weight it must be removed with.
#include <algorithm>
#include <array>
#include <cmath>
#include <optional>
#include <stdexcept>

#include "estimator_internal.hpp"
#include "odonav/estimators.hpp"

namespace odonav {

using namespace estimators_internal;

namespace {
// (oldest + age) mod capacity for oldest < capacity and age < capacity, without an integer division
// (a division costs tens of cycles, as much as the rest of the index arithmetic of an update).
inline std::size_t ring_index(std::size_t oldest, std::size_t age, std::size_t capacity) {
  const std::size_t index = oldest + age;
  return index >= capacity ? index - capacity : index;
}

// How many reference intervals (sample_interval_s, 0.1 s) a sample spans; exactly 1 within 1e-6 of
// the reference (10 Hz stamps with their rounding) and for samples without an interval.
// The VFF law and its clamp count in reference intervals, not in samples: lambda_min per 0.1 s
// (lambda_min^n per sample) and the law's memory L x 0.1 s (L / n samples), so tracking after a K
// step takes the same time at every GNSS rate. Per sample, a 1 Hz K step settled in 50 s instead
// of 8 (the law forgot ten times less per second).
double reference_intervals(const ScaleFactorEstimatorParams& p, double interval_s) {
  if (!(interval_s > 0.0) || !(p.sample_interval_s > 0.0)) return 1.0;
  const double n = interval_s / p.sample_interval_s;
  return std::abs(n - 1.0) < 1e-6 ? 1.0 : n;
}
}  // namespace

WindowRlsEstimator::WindowRlsEstimator(const ScaleFactorEstimatorParams& params, bool variable_forgetting)
    : params_(params),
      variable_forgetting_(variable_forgetting),
      capacity_(params.window_length),
      resum_interval_(params.resum_interval == 0 ? params.window_length : params.resum_interval),
      residual_scale_(params.sigma_y_floor_m, params.sigma_y_ewma_alpha),
      residual_correlation_(params.sigma_y_ewma_alpha),
      change_(params.vff_change_threshold, params.vff_change_drift) {
  params_.validate();
  buffer_.resize(capacity_);
}

const WindowRlsEstimator::Entry& WindowRlsEstimator::entry(std::size_t age_index) const {
  return buffer_[ring_index(oldest_, age_index, capacity_)];
}

double WindowRlsEstimator::vff_c_m2(double k_m_per_pulse, double interval_s) const {
  if (params_.vff_c_m2 > 0.0) return params_.vff_c_m2;
  return params_.vff_kappa * model_sigma_y2_m2(params_, k_m_per_pulse, interval_s);
}

void WindowRlsEstimator::update(const ScaleFactorSample& sample) {
  if (!sample_is_valid(sample)) check_sample(name(), sample);  // throws, naming the field
  const double phi = sample.phi_pulses;
  const double y = sample.y_m;
  const double dv = std::isfinite(sample.speed_change_mps) ? sample.speed_change_mps : 0.0;
  const double w0 = params_.prior_weight_pulses2;
  const double s_pp_total = s_pp_ + w0;

  double lambda = 1.0;
  std::optional<uint64_t> change_began;
  if (held_ > 0 && s_pp_total > 0.0) {
    const double k_prev = (s_py_ + w0 * params_.k_prior_m_per_pulse) / s_pp_total;
    const double eps = y - k_prev * phi;  // a-priori error: follows the identification result
    const double s = 1.0 + phi * phi / s_pp_total;
    // The detector normalises by the residual scale observed so far (not the model's): it then
    // holds whatever the samples' real noise is, e.g. the trapezoid correction's at low rates.
    const double sqrt_s = std::sqrt(s);
    const double scale_m = residual_scale_.sigma_m();  // before this sample's own residual is added
    if (variable_forgetting_ && params_.vff_change_threshold > 0.0 &&
        residual_scale_.count() >= kMinResidualsForOnlineScale)
      change_began = change_.add(eps / (sqrt_s * scale_m), samples_used_);
    residual_correlation_.add(eps / sqrt_s, 3.0 * scale_m);
    residual_scale_.add(eps, s);
    // Ordinary RLS while the window fills (fewer than L held), the VFF law afterwards.
    if (variable_forgetting_ && held_ == capacity_) {
      const double c = vff_c_m2(k_prev, sample.dt_s);
      const double n = reference_intervals(params_, sample.dt_s);
      // The law's memory L in reference intervals: L / n samples of n intervals each (see above).
      const double memory_samples = static_cast<double>(capacity_) / n;
      lambda = std::clamp(1.0 - eps * eps / (s * memory_samples * c), std::pow(params_.lambda_min, n), 1.0);
    }
  }

  if (lambda != 1.0) {
    log_weight_ += std::log(lambda);
    s_pp_ *= lambda;
    s_py_ *= lambda;
    s_pdv_ *= lambda;
  }
  s_pp_ += phi * phi;
  s_py_ += phi * y;
  s_pdv_ += phi * dv;

  const Entry newest{phi, y, log_weight_, dv};
  if (held_ == capacity_) {
    const Entry& old = buffer_[oldest_];
    const double beta = variable_forgetting_ ? std::exp(log_weight_ - old.log_weight) : 1.0;
    s_pp_ -= beta * old.phi * old.phi;
    s_py_ -= beta * old.phi * old.y;
    s_pdv_ -= beta * old.phi * old.dv;
    buffer_[oldest_] = newest;
    if (++oldest_ == capacity_) oldest_ = 0;
  } else {
    buffer_[ring_index(oldest_, held_, capacity_)] = newest;
    ++held_;
  }
  last_lambda_ = lambda;
  ++samples_used_;
  if (change_began) change_began_ = *change_began;
  const bool cut = change_began && cut_window(*change_began, sample.dt_s);
  if (!cut && ++since_resum_ >= resum_interval_) resum();
}

bool WindowRlsEstimator::cut_window(uint64_t first_kept, double interval_s) {
  // Never shorter than L reference intervals (10 s): the memory the window has at 10 Hz, where a
  // K step settles within it anyway. Below it, a run of residuals from an unmodelled effect that
  // comes and goes (an uncompensated GNSS latency during an acceleration) would leave K resting
  // on a few seconds of data (measured at 10 Hz with 100-200 ms latency: K RMS 0.13-1.2 %).
  const double n = reference_intervals(params_, interval_s);
  const auto floor_samples = static_cast<std::size_t>(std::ceil(static_cast<double>(capacity_) / n - 1e-9));
  const std::size_t keep = std::max<std::size_t>(
      floor_samples, static_cast<std::size_t>(std::min<uint64_t>(samples_used_ - first_kept, capacity_)));
  if (keep >= held_) return false;
  oldest_ = ring_index(oldest_, held_ - keep, capacity_);
  held_ = keep;
  resum();  // exact sums over what is left (and since_resum_ restarts)
  return true;
}

void WindowRlsEstimator::resum() {
  // Re-base the log-weights on the current Lambda: each stored Lambda_i becomes Lambda_i - Lambda
  // (>= 0, since ln(lambda) <= 0) and Lambda becomes 0; weights exp(0 - Lambda_i) are unchanged.
  // Lambda therefore stays within resum_interval * |ln lambda_min| and exp() never under/overflows.
  const double base = log_weight_;
  double s_pp = 0.0;
  double s_py = 0.0;
  double s_pdv = 0.0;
  for (std::size_t i = 0, index = oldest_; i < held_; ++i) {
    Entry& e = buffer_[index];
    if (++index == capacity_) index = 0;
    e.log_weight -= base;
    const double w = variable_forgetting_ ? std::exp(-e.log_weight) : 1.0;
    s_pp += w * e.phi * e.phi;
    s_py += w * e.phi * e.y;
    s_pdv += w * e.phi * e.dv;
  }
  log_weight_ = 0.0;
  s_pp_ = s_pp;
  s_py_ = s_py;
  s_pdv_ = s_pdv;
  since_resum_ = 0;
}

WindowSums WindowRlsEstimator::window_sums() const { return WindowSums{s_pp_, s_py_, held_, s_pdv_}; }

WindowSums WindowRlsEstimator::exact_window_sums() const {
  WindowSums sums;
  sums.held = held_;
  for (std::size_t i = 0; i < held_; ++i) {
    const Entry& e = entry(i);
    const double w = variable_forgetting_ ? std::exp(log_weight_ - e.log_weight) : 1.0;
    sums.s_pp += w * e.phi * e.phi;
    sums.s_py += w * e.phi * e.y;
    sums.s_pdv += w * e.phi * e.dv;
  }
  return sums;
}

double WindowRlsEstimator::lag_sigma(double k_m_per_pulse, double sigma_y_m) const {
  // The samples since the change began are the index range [change_began_, samples_used_); the
  // window holds [samples_used_ - held_, samples_used_). Nothing to say unless the change began
  // inside the window (older samples from before it still weigh on K).
  if (!change_began_ || held_ == 0) return 0.0;
  const uint64_t first_held = samples_used_ - held_;
  if (*change_began_ <= first_held || *change_began_ >= samples_used_) return 0.0;
  const auto since = static_cast<std::size_t>(samples_used_ - *change_began_);
  double s_pp = 0.0;
  double s_py = 0.0;
  for (std::size_t i = held_ - since; i < held_; ++i) {
    const Entry& e = entry(i);
    const double w = variable_forgetting_ ? std::exp(log_weight_ - e.log_weight) : 1.0;
    s_pp += w * e.phi * e.phi;
    s_py += w * e.phi * e.y;
  }
  if (!(s_pp > 0.0)) return 0.0;
  const double k_since = s_py / s_pp;
  const double sigma_since = sigma_y_m / std::sqrt(s_pp);
  return std::hypot(sigma_since, k_m_per_pulse - k_since);
}

ScaleFactorEstimate WindowRlsEstimator::estimate() const {
  const double w0 = params_.prior_weight_pulses2;
  ScaleFactorEstimate e = least_squares_estimate(
      params_, held_ > 0, s_pp_ + w0, s_py_ + w0 * params_.k_prior_m_per_pulse, residual_scale_.sigma_m(),
      samples_used_, last_lambda_, static_cast<double>(held_) / static_cast<double>(capacity_));
  if (!e.valid) return e;
  // y - K phi = -d speed_change for a latency error d (scale_factor_estimator.hpp), so the
  // least-squares K moves by -d sum w phi dv / sum w phi^2 (the prior does not move).
  e.dk_dlatency_m_per_pulse_per_s = -s_pdv_ / (s_pp_ + w0);
  e.lag_sigma_m_per_pulse = lag_sigma(e.k_m_per_pulse, residual_scale_.sigma_m());
  e.correlation_factor = residual_correlation_.sigma_factor();
  return e;
}

void WindowRlsEstimator::reset() {
  oldest_ = 0;
  held_ = 0;
  s_pp_ = 0.0;
  s_py_ = 0.0;
  s_pdv_ = 0.0;
  log_weight_ = 0.0;
  last_lambda_ = 1.0;
  since_resum_ = 0;
  samples_used_ = 0;
  residual_scale_.reset();
  residual_correlation_.reset();
  change_.reset();
  change_began_.reset();
}

template <class Archive, class Self>
void WindowRlsEstimator::state_fields(Archive& a, Self& self) {
  a("s_pp", self.s_pp_)("s_py", self.s_py_)("s_pdv", self.s_pdv_)("log_weight", self.log_weight_)(
      "last_lambda", self.last_lambda_)("since_resum", self.since_resum_)("samples_used", self.samples_used_);
  residual_scale_fields(a, self.residual_scale_);
  a.via("residual_correlation", self.residual_correlation_);
  change_detector_fields(a, self.change_);
  a("change_began", self.change_began_);  // null before any detected change
  // The window, oldest first, as (phi, y, Lambda, speed change) rows; restored from the start of the ring.
  using Rows = std::vector<std::array<double, 4>>;
  a.via(
      "window",
      [&] {
        Rows rows;
        for (std::size_t i = 0; i < self.held_; ++i)
          rows.push_back({self.entry(i).phi, self.entry(i).y, self.entry(i).log_weight, self.entry(i).dv});
        return rows;
      },
      [&](const Rows& rows) { restore_window(self, rows); });
  a.check("since_resum", self.since_resum_ < self.resum_interval_, "is out of range");
  a.check("change_began", !self.change_began_ || *self.change_began_ <= self.samples_used_, "is out of range");
  a.check("residual_scale", self.residual_scale_.variance_m2() >= 0.0, "has a negative variance");
}

void WindowRlsEstimator::restore_window(WindowRlsEstimator& e, const std::vector<std::array<double, 4>>& rows) {
  if (rows.size() > e.capacity_) throw CheckpointError("field 'window' is longer than the window length");
  for (const auto& r : rows)
    if (!std::isfinite(r[0]) || !std::isfinite(r[1]) || !std::isfinite(r[2]) || !std::isfinite(r[3]))
      throw CheckpointError("field 'window' holds a value that is not finite");
  e.oldest_ = 0;
  e.held_ = rows.size();
  for (std::size_t i = 0; i < rows.size(); ++i) e.buffer_[i] = Entry{rows[i][0], rows[i][1], rows[i][2], rows[i][3]};
}

StateJson WindowRlsEstimator::save_state() const { return save_estimator_fields(*this, name(), params_); }

void WindowRlsEstimator::restore_state(const StateJson& state) {
  // Restored into a copy: this one changes only when everything was read.
  *this = restored_estimator_copy(*this, state, name(), params_);
}

}  // namespace odonav
