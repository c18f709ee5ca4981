#include "odonav/dead_reckoning/anchored_position.hpp"

#include <algorithm>
#include <sstream>
#include <stdexcept>
#include <string>

#include "odonav/dead_reckoning/dead_reckoner.hpp"
#include "odonav/stream_buffers.hpp"

namespace odonav {

const char* to_string(AnchorStatus status) {
  switch (status) {
    case AnchorStatus::kNotStarted: return "not_started";
    case AnchorStatus::kAnchored: return "anchored";
    case AnchorStatus::kDeadReckoning: return "dead_reckoning";
  }
  return "unknown";
}

AnchoredPositionFilter::AnchoredPositionFilter(const AnchoredPositionParams& p) : params_(p) {
  auto require = [](bool ok, const char* what) {
    if (!ok) throw std::invalid_argument(std::string("AnchoredPositionParams: ") + what);
  };
  auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  require(std::isfinite(p.hold_off_s) && p.hold_off_s >= 0.0, "hold_off_s must be finite and >= 0");
  require(positive(p.drift_percent_distance), "drift_percent_distance must be finite and > 0");
  require(positive(p.correlation_distance_m), "correlation_distance_m must be finite and > 0");
  require(std::isfinite(p.fix_correlation_time_s) && p.fix_correlation_time_s >= 0.0,
          "fix_correlation_time_s must be finite and >= 0");
  require(positive(p.default_fix_sigma_m), "default_fix_sigma_m must be finite and > 0");
  require(positive(p.min_fix_sigma_m), "min_fix_sigma_m must be finite and > 0");
  require(positive(p.vertical_sigma_factor), "vertical_sigma_factor must be finite and > 0");
  require(positive(p.gate_sigma), "gate_sigma must be finite and > 0");
  require(p.gate_restart_after >= 1, "gate_restart_after must be >= 1");
  require(positive(p.anchored_max_age_s), "anchored_max_age_s must be finite and > 0");
  const double rate = p.drift_percent_distance / 100.0;
  q_m2_per_m_ = rate * rate * p.correlation_distance_m;
}

double AnchoredPositionFilter::applies_from_s(double epoch_s) const {
  // 1 us early for a hold-off > 0: GNSS epochs and odometer samples often share a grid (10 and
  // 100 Hz), so epoch + hold-off is an odometer instant up to the last bit, and a stamp that crossed
  // DDS (integer nanoseconds) may come back a few ulps off; 1 us is far above that and far below any
  // sensor period, so odonav-offline and the node put the sample on the same side. The estimates'
  // hold-off rule has the same guard.
  return params_.hold_off_s > 0.0 ? epoch_s + params_.hold_off_s - kAnchorApplicationGuard_s : epoch_s;
}

void AnchoredPositionFilter::add_fix(const AnchorFix& fix) {
  detail::check_stream_time("anchor_fix", fix.t_s, last_added_t_s_);
  if (!fix.fix_enu_m.allFinite() || !fix.dr_enu_m.allFinite() || !std::isfinite(fix.dr_distance_m)) {
    std::ostringstream m;
    m << "anchor_fix: at t=" << fix.t_s << " s, a position or the distance is not finite";
    throw StreamInputError(m.str());
  }
  last_added_t_s_ = fix.t_s;
  ++counters_.fixes_added;
  queued_.push_back(fix);
}

void AnchoredPositionFilter::apply(const AnchorFix& fix) {
  const double sigma_h = std::max(
      params_.min_fix_sigma_m,
      std::isfinite(fix.sigma_m) && fix.sigma_m > 0.0 ? fix.sigma_m : params_.default_fix_sigma_m);
  const double sigma_v = params_.vertical_sigma_factor * sigma_h;
  double correlation = 1.0;
  if (previous_fix_t_s_) correlation = std::max(1.0, params_.fix_correlation_time_s / (fix.t_s - *previous_fix_t_s_));
  previous_fix_t_s_ = fix.t_s;
  const Eigen::Vector3d r = correlation * Eigen::Vector3d(sigma_h * sigma_h, sigma_h * sigma_h, sigma_v * sigma_v);
  const Eigen::Vector3d z = fix.fix_enu_m - fix.dr_enu_m;  // the DR error at the fix epoch
  const bool restart = initialised_ && consecutive_gated_ >= params_.gate_restart_after;
  if (!initialised_ || restart) {
    // No prior (or none worth keeping): the fix sets the offset (the DR starts on a fix, so it is
    // 0 at the first one).
    offset_m_ = z;
    variance_m2_ = r / correlation;  // one fix alone: its own variance
    initialised_ = true;
    consecutive_gated_ = 0;
    if (restart) ++counters_.gate_restarts;
  } else {
    const Eigen::Vector3d innovation = z - offset_m_;
    const Eigen::Vector3d s = variance_m2_ + r;
    const double innovation_h_m = innovation.head<2>().norm();
    // The gate on the innovation's own spread: one fix errs by sigma whatever its correlation with
    // the others (the inflation above only weighs how much it teaches).
    const double gate_m = params_.gate_sigma * std::sqrt(variance_m2_.x() + variance_m2_.y() + 2.0 * sigma_h * sigma_h);
    if (innovation_h_m > gate_m) {
      ++counters_.fixes_rejected_gate;
      ++consecutive_gated_;
      counters_.last_rejected_innovation_m = innovation_h_m;
      counters_.last_rejected_gate_m = gate_m;
      return;
    }
    consecutive_gated_ = 0;
    for (int i = 0; i < 3; ++i) {
      const double gain = variance_m2_[i] / s[i];
      offset_m_[i] += gain * innovation[i];
      variance_m2_[i] *= 1.0 - gain;
    }
  }
  ++counters_.fixes_applied;
  last_fix_t_s_ = fix.t_s;
  last_fix_distance_m_ = fix.dr_distance_m;
}

AnchoredPosition AnchoredPositionFilter::step(const AnchorDrStep& s) {
  detail::check_stream_time("anchor_step", s.t_s, last_step_t_s_);
  if (!s.enu_m.allFinite() || !std::isfinite(s.distance_m)) {
    std::ostringstream m;
    m << "anchor_step: at t=" << s.t_s << " s, the DR position or distance is not finite";
    throw StreamInputError(m.str());
  }
  last_step_t_s_ = s.t_s;
  ++counters_.steps;
  // Process noise of the distance driven since the last step (the odometer, not time: a vehicle
  // standing still does not drift).
  if (initialised_) variance_m2_.array() += q_m2_per_m_ * std::abs(s.distance_m - last_distance_m_);
  last_distance_m_ = s.distance_m;
  while (!queued_.empty() && applies_from_s(queued_.front().t_s) <= s.t_s) {
    apply(queued_.front());
    queued_.pop_front();
  }

  AnchoredPosition out;
  out.t_s = s.t_s;
  if (!initialised_) {
    out.position = s.position;
    out.enu_m = s.enu_m;
    return out;
  }
  out.enu_m = s.enu_m + offset_m_;
  out.position = move_geodetic(s.position, offset_m_);
  out.covariance_enu_m2 = variance_m2_.asDiagonal();
  out.last_fix_t_s = last_fix_t_s_;
  out.distance_since_fix_m = std::max(0.0, s.distance_m - last_fix_distance_m_);
  out.status = s.t_s - last_fix_t_s_ <= params_.anchored_max_age_s ? AnchorStatus::kAnchored
                                                                    : AnchorStatus::kDeadReckoning;
  return out;
}

AnchoredPosition AnchoredPositionFilter::step(const DeadReckoningOutput& dr) {
  for (const AnchorFix& f : dr.gnss_fixes) add_fix(f);
  return step(AnchorDrStep{dr.t_s, dr.position, dr.enu_m, dr.distance_m});
}

}  // namespace odonav
