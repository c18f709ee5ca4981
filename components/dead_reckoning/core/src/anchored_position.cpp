#include "odonav/dead_reckoning/anchored_position.hpp"

#include <algorithm>
#include <sstream>
#include <stdexcept>
#include <string>

#include "odonav/dead_reckoning/dead_reckoner.hpp"
#include "odonav/frames.hpp"
#include "odonav/stream_buffers.hpp"

namespace odonav::dead_reckoning {

results::NavigationPositionRow output_row(const AnchoredPosition& p) {
  results::NavigationPositionRow r;
  r.t_s = p.t_s;
  const Geodetic position = normalized(p.position);  // lat [-90, 90], lon [-180, 180)
  r.lat_rad = position.lat_rad;
  r.lon_rad = position.lon_rad;
  r.height_m = position.height_m;
  r.east_m = p.enu_m.x();
  r.north_m = p.enu_m.y();
  r.up_m = p.enu_m.z();
  r.var_east_m2 = p.covariance_enu_m2(0, 0);
  r.var_north_m2 = p.covariance_enu_m2(1, 1);
  r.var_up_m2 = p.covariance_enu_m2(2, 2);
  r.status = to_string(p.status);
  r.last_fix_t_s = p.last_fix_t_s;
  r.distance_since_fix_m = p.distance_since_fix_m;
  return r;
}

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
  auto non_negative = [](double v) { return std::isfinite(v) && v >= 0.0; };
  require(non_negative(p.hold_off_s), "hold_off_s must be finite and >= 0");
  require(positive(p.drift_percent_distance), "drift_percent_distance must be finite and > 0");
  require(positive(p.correlation_distance_m), "correlation_distance_m must be finite and > 0");
  require(non_negative(p.scale_sigma_percent), "scale_sigma_percent must be finite and >= 0");
  require(non_negative(p.scale_random_walk_percent_per_sqrt_km),
          "scale_random_walk_percent_per_sqrt_km must be finite and >= 0");
  require(non_negative(p.heading_sigma_deg), "heading_sigma_deg must be finite and >= 0");
  require(non_negative(p.heading_random_walk_deg_per_sqrt_s),
          "heading_random_walk_deg_per_sqrt_s must be finite and >= 0");
  require(positive(p.fix_correlation_time_s), "fix_correlation_time_s must be finite and > 0");
  require(
      std::isfinite(p.fix_correlated_fraction) && p.fix_correlated_fraction >= 0.0 && p.fix_correlated_fraction < 1.0,
      "fix_correlated_fraction must be in [0, 1)");
  require(positive(p.default_fix_sigma_m), "default_fix_sigma_m must be finite and > 0");
  require(positive(p.min_fix_sigma_m), "min_fix_sigma_m must be finite and > 0");
  require(positive(p.vertical_sigma_factor), "vertical_sigma_factor must be finite and > 0");
  require(positive(p.gate_sigma), "gate_sigma must be finite and > 0");
  require(p.gate_restart_after >= 1, "gate_restart_after must be >= 1");
  require(positive(p.anchored_max_age_s), "anchored_max_age_s must be finite and > 0");
  const double rate = p.drift_percent_distance / 100.0;
  q_offset_m2_per_m_ = rate * rate * p.correlation_distance_m;
  const double scale_rw = p.scale_random_walk_percent_per_sqrt_km / 100.0;
  q_scale_per_m_ = scale_rw * scale_rw / 1000.0;
  const double heading_rw = p.heading_random_walk_deg_per_sqrt_s * kDegToRad;
  q_heading_rad2_per_s_ = heading_rw * heading_rw;
}

double AnchoredPositionFilter::applies_from_s(double epoch_s) const {
  return estimate_applies_from_s(epoch_s, params_.hold_off_s);
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

void AnchoredPositionFilter::start(const Eigen::Vector3d& z, double sigma_h_m) {
  // No prior on the offset: after the fix z = o + b + w it is z, with the fix's variance, and
  // anti-correlated with b (o = z - b - w).
  const double c = params_.fix_correlated_fraction;
  const Eigen::Vector3d var(sigma_h_m * sigma_h_m, sigma_h_m * sigma_h_m,
                            std::pow(params_.vertical_sigma_factor * sigma_h_m, 2));
  x_.setZero();
  x_.head<3>() = z;
  p_.setZero();
  const double scale_sigma = params_.scale_sigma_percent / 100.0, heading_sigma = params_.heading_sigma_deg * kDegToRad;
  for (int i = 0; i < 3; ++i) {
    p_(i, i) = var[i];
    p_(5 + i, 5 + i) = c * var[i];
    p_(i, 5 + i) = p_(5 + i, i) = -c * var[i];
  }
  p_(3, 3) = scale_sigma * scale_sigma;
  p_(4, 4) = heading_sigma * heading_sigma;
  initialised_ = true;
}

void AnchoredPositionFilter::propagate(const Eigen::Vector3d& d, double dd_m, double dt_s) {
  Matrix f = Matrix::Identity();
  f(0, 3) = d.x();
  f(0, 4) = -d.y();
  f(1, 3) = d.y();
  f(1, 4) = d.x();
  f(2, 3) = d.z();
  const double phi = std::exp(-dt_s / params_.fix_correlation_time_s);
  for (int i = 5; i < 8; ++i) f(i, i) = phi;
  x_ = f * x_;
  p_ = f * p_ * f.transpose();
  const double q_o = q_offset_m2_per_m_ * dd_m;
  for (int i = 0; i < 3; ++i) p_(i, i) += q_o;
  p_(3, 3) += q_scale_per_m_ * dd_m;
  p_(4, 4) += q_heading_rad2_per_s_ * dt_s;
  // Gauss-Markov drive: keeps b's variance at its stationary value.
  const double var_b = correlated_sigma_h_m_ * correlated_sigma_h_m_ * (1.0 - phi * phi);
  p_(5, 5) += var_b;
  p_(6, 6) += var_b;
  p_(7, 7) += var_b * params_.vertical_sigma_factor * params_.vertical_sigma_factor;
}

void AnchoredPositionFilter::apply(const AnchorFix& fix, const AnchorDrStep& now) {
  const double sigma_h =
      std::max(params_.min_fix_sigma_m,
               std::isfinite(fix.sigma_m) && fix.sigma_m > 0.0 ? fix.sigma_m : params_.default_fix_sigma_m);
  const double sigma_v = params_.vertical_sigma_factor * sigma_h;
  // The DR where the fix measured (at its epoch minus the GNSS latency: the DeadReckoner's).
  const Eigen::Vector3d& dr_meas = fix.dr_enu_m;
  const Eigen::Vector3d z = fix.fix_enu_m - dr_meas;  // the DR error when the fix measured
  const bool restart = initialised_ && consecutive_gated_ >= params_.gate_restart_after;
  correlated_sigma_h_m_ = std::sqrt(params_.fix_correlated_fraction) * sigma_h;
  if (!initialised_ || restart) {
    // No prior worth keeping: the fix sets the offset (0 at the first, on which the DR starts).
    start(z, sigma_h);
    consecutive_gated_ = 0;
    if (restart) ++counters_.gate_restarts;
  } else {
    const double c = params_.fix_correlated_fraction;
    const Eigen::Vector3d r = (1.0 - c) * Eigen::Vector3d(sigma_h * sigma_h, sigma_h * sigma_h, sigma_v * sigma_v);
    // o(measured) = o(now) - (s, psi) acting on the DR increment since then.
    const Eigen::Vector3d d = now.enu_m - dr_meas;
    Eigen::Matrix<double, 3, kN> h = Eigen::Matrix<double, 3, kN>::Zero();
    h.block<3, 3>(0, 0).setIdentity();
    h.block<3, 3>(0, 5).setIdentity();
    h(0, 3) = -d.x();
    h(0, 4) = d.y();
    h(1, 3) = -d.y();
    h(1, 4) = -d.x();
    h(2, 3) = -d.z();
    const Eigen::Vector3d innovation = z - h * x_;
    const Eigen::Matrix3d s = h * p_ * h.transpose() + Eigen::Matrix3d(r.asDiagonal());
    const double innovation_h_m = innovation.head<2>().norm();
    const double gate_m = params_.gate_sigma * std::sqrt(s(0, 0) + s(1, 1));
    if (innovation_h_m > gate_m) {
      ++counters_.fixes_rejected_gate;
      ++consecutive_gated_;
      counters_.last_rejected_innovation_m = innovation_h_m;
      counters_.last_rejected_gate_m = gate_m;
      return;
    }
    consecutive_gated_ = 0;
    const Eigen::Matrix<double, kN, 3> k = p_ * h.transpose() * s.inverse();
    x_ += k * innovation;
    // Joseph form: stays symmetric and positive over thousands of updates.
    const Matrix ikh = Matrix::Identity() - k * h;
    p_ = ikh * p_ * ikh.transpose() + k * Eigen::Matrix3d(r.asDiagonal()) * k.transpose();
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
  // Propagation over the DR increment of the step (the odometer's distance, not time, drives the
  // offset's and the scale's noise: a vehicle standing still does not drift).
  if (initialised_)
    propagate(s.enu_m - last_enu_m_, std::abs(s.distance_m - last_distance_m_), s.t_s - *last_step_t_s_);
  last_step_t_s_ = s.t_s;
  last_enu_m_ = s.enu_m;
  last_distance_m_ = s.distance_m;
  ++counters_.steps;
  while (!queued_.empty() && applies_from_s(queued_.front().t_s) <= s.t_s) {
    apply(queued_.front(), s);
    queued_.pop_front();
  }

  AnchoredPosition out;
  out.t_s = s.t_s;
  if (!initialised_) {
    out.position = s.position;
    out.enu_m = s.enu_m;
    return out;
  }
  // The filter works in the DR origin's ENU frame; the offset moves the DR position along the
  // same vector in the ENU frame at that position (the two frames differ by the meridian
  // convergence: near a pole by up to 180 deg), and the covariance is turned with it.
  const Eigen::Vector3d offset = x_.head<3>();
  out.enu_m = s.enu_m + offset;
  out.position = move_geodetic(s.position, s.origin_to_local * offset);
  out.covariance_enu_m2 = s.origin_to_local * p_.block<3, 3>(0, 0) * s.origin_to_local.transpose();
  out.scale_error = x_[3];
  out.heading_error_rad = x_[4];
  out.last_fix_t_s = last_fix_t_s_;
  out.distance_since_fix_m = std::max(0.0, s.distance_m - last_fix_distance_m_);
  out.status =
      s.t_s - last_fix_t_s_ <= params_.anchored_max_age_s ? AnchorStatus::kAnchored : AnchorStatus::kDeadReckoning;
  return out;
}

AnchoredPosition AnchoredPositionFilter::step(const DeadReckoningOutput& dr) {
  for (const AnchorFix& f : dr.gnss_fixes) add_fix(f);
  return step(AnchorDrStep{dr.t_s, dr.position, dr.enu_m, dr.distance_m, dr.origin_to_local});
}

}  // namespace odonav::dead_reckoning
