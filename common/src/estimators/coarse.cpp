// Coarse S/N calibration: the traditional baseline (drive straight, K = S / N), with GNSS positions
// standing in for the surveyed line. See CoarseEstimator in estimators.hpp for the run rules.
#include <cmath>
#include <stdexcept>

#include "estimator_internal.hpp"
#include "odonav/estimators.hpp"

namespace odonav {

using namespace estimators_internal;

CoarseEstimator::CoarseEstimator(const ScaleFactorEstimatorParams& params) : params_(params) { params_.validate(); }

void CoarseEstimator::close_run() {
  if (!run_open_) return;
  run_open_ = false;
  const double length_m = (run_end_m_ - run_start_m_).norm();
  if (length_m >= params_.coarse_min_length_m && run_pulses_ > 0.0) {
    total_length_m_ += length_m;
    total_pulses_ += run_pulses_;
    ++runs_counted_;
  }
}

void CoarseEstimator::update(const ScaleFactorSample& sample) {
  if (!sample_is_valid(sample)) check_sample(name(), sample);  // throws, naming the field
  // Contiguous: this interval starts where the previous accepted sample ended, so no pulses were
  // lost in between. dt_s = 0 means "not given": then contiguity is assumed (documented).
  const double tolerance_s = 1e-6 + 1e-3 * sample.dt_s;
  const bool contiguous = have_previous_ && sample.t_s > previous_t_s_ &&
                          (sample.dt_s == 0.0 || std::abs(sample.t_s - sample.dt_s - previous_t_s_) <= tolerance_s);
  if (!sample.straight || !contiguous) close_run();
  if (sample.straight) {
    if (!run_open_) {
      run_open_ = true;
      if (contiguous) {
        run_start_m_ = previous_position_m_;
        run_pulses_ = sample.phi_pulses;
      } else {
        run_start_m_ = sample.gnss_position_enu_m;
        run_pulses_ = 0.0;
      }
    } else {
      run_pulses_ += sample.phi_pulses;
    }
    run_end_m_ = sample.gnss_position_enu_m;
  }
  have_previous_ = true;
  previous_t_s_ = sample.t_s;
  previous_position_m_ = sample.gnss_position_enu_m;
  ++samples_used_;
}

ScaleFactorEstimate CoarseEstimator::estimate() const {
  ScaleFactorEstimate e = invalid_estimate(samples_used_, 1.0, 1.0);  // whole straight runs: no forgetting
  // The run still open counts as soon as it is long enough: a drive that ends on its straight (the
  // calibration run itself) never sees a sample that closes it.
  double length_m = total_length_m_, pulses = total_pulses_;
  std::size_t runs = runs_counted_;
  const double open_length_m = run_open_ ? (run_end_m_ - run_start_m_).norm() : 0.0;
  if (run_open_ && open_length_m >= params_.coarse_min_length_m && run_pulses_ > 0.0) {
    length_m += open_length_m;
    pulses += run_pulses_;
    ++runs;
  }
  if (runs == 0) return e;
  // Each run has two independent end-point position errors.
  set_valid_estimate(e, params_, length_m / pulses,
                     std::sqrt(2.0 * static_cast<double>(runs)) * params_.coarse_position_sigma_m / pulses);
  return e;
}

void CoarseEstimator::reset() {
  have_previous_ = false;
  previous_t_s_ = 0.0;
  previous_position_m_.setZero();
  run_open_ = false;
  run_start_m_.setZero();
  run_end_m_.setZero();
  run_pulses_ = 0.0;
  runs_counted_ = 0;
  total_length_m_ = 0.0;
  total_pulses_ = 0.0;
  samples_used_ = 0;
}

template <class Archive, class Self>
void CoarseEstimator::state_fields(Archive& a, Self& self) {
  a("have_previous", self.have_previous_)("previous_t_s", self.previous_t_s_)(
      "previous_position_m", self.previous_position_m_)("run_open", self.run_open_)("run_start_m", self.run_start_m_)(
      "run_end_m", self.run_end_m_)("run_pulses", self.run_pulses_)("runs_counted", self.runs_counted_)(
      "total_length_m", self.total_length_m_)("total_pulses", self.total_pulses_)("samples_used", self.samples_used_);
  a.check("run_pulses", self.run_pulses_ >= 0.0, "is out of range");
  a.check("total_length_m", self.total_length_m_ >= 0.0, "is out of range");
  a.check("total_pulses", self.total_pulses_ >= 0.0 && (self.runs_counted_ == 0 || self.total_pulses_ > 0.0),
          "is out of range");
}

StateJson CoarseEstimator::save_state() const { return save_estimator_fields(*this, name(), params_); }

void CoarseEstimator::restore_state(const StateJson& state) {
  // Restored into a copy: this one changes only when everything was read.
  *this = restored_estimator_copy(*this, state, name(), params_);
}

}  // namespace odonav
