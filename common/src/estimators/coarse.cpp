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
  ScaleFactorEstimate e;
  e.samples_used = samples_used_;
  e.forgetting_factor = 1.0;
  e.window_fill = 1.0;
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
  e.valid = true;
  e.k_m_per_pulse = length_m / pulses;
  // Each run has two independent end-point position errors.
  e.sigma_m_per_pulse = std::sqrt(2.0 * static_cast<double>(runs)) * params_.coarse_position_sigma_m / pulses;
  e.converged = is_converged(params_, e.k_m_per_pulse, e.sigma_m_per_pulse, samples_used_);
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

std::string CoarseEstimator::save_state() const {
  StateWriter out(name());
  out.put_params(params_);
  out.put_u64("have_previous", have_previous_ ? 1 : 0);
  out.put("previous_t_s", previous_t_s_);
  out.put_row("row", {previous_position_m_.x(), previous_position_m_.y(), previous_position_m_.z()});
  out.put_u64("run_open", run_open_ ? 1 : 0);
  out.put_row("row", {run_start_m_.x(), run_start_m_.y(), run_start_m_.z()});
  out.put_row("row", {run_end_m_.x(), run_end_m_.y(), run_end_m_.z()});
  out.put("run_pulses", run_pulses_);
  out.put_u64("runs_counted", runs_counted_);
  out.put("total_length_m", total_length_m_);
  out.put("total_pulses", total_pulses_);
  out.put_u64("samples_used", samples_used_);
  return out.finish();
}

void CoarseEstimator::restore_state(const std::string& state) {
  const StateReader in(state, name());
  in.check_params(params_);
  const auto rows = in.rows("row", 3);
  const std::string where = "estimator state for 'coarse': ";
  if (rows.size() != 3)
    throw std::runtime_error(where + "expected 3 position rows, got " + std::to_string(rows.size()));
  const uint64_t have_previous = in.get_u64("have_previous");
  const uint64_t run_open = in.get_u64("run_open");
  if (have_previous > 1 || run_open > 1) throw std::runtime_error(where + "flags must be 0 or 1");
  const double previous_t_s = in.get("previous_t_s");
  const double run_pulses = in.get("run_pulses");
  const uint64_t runs_counted = in.get_u64("runs_counted");
  const double total_length_m = in.get("total_length_m");
  const double total_pulses = in.get("total_pulses");
  const uint64_t samples_used = in.get_u64("samples_used");
  if (!(run_pulses >= 0.0) || !(total_length_m >= 0.0) || !(total_pulses >= 0.0) ||
      (runs_counted > 0 && !(total_pulses > 0.0)))
    throw std::runtime_error(where + "run totals out of range");
  have_previous_ = have_previous == 1;
  previous_t_s_ = previous_t_s;
  previous_position_m_ = Eigen::Vector3d(rows[0][0], rows[0][1], rows[0][2]);
  run_open_ = run_open == 1;
  run_start_m_ = Eigen::Vector3d(rows[1][0], rows[1][1], rows[1][2]);
  run_end_m_ = Eigen::Vector3d(rows[2][0], rows[2][1], rows[2][2]);
  run_pulses_ = run_pulses;
  runs_counted_ = runs_counted;
  total_length_m_ = total_length_m;
  total_pulses_ = total_pulses;
  samples_used_ = samples_used;
}

}  // namespace odonav
