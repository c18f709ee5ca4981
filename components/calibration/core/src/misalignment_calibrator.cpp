#include "odonav/calibration/misalignment_calibrator.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "odonav/checkpoint_state.hpp"

namespace odonav::calibration {

PublishedMisalignment published_misalignment(const MisalignmentOutput& out) {
  PublishedMisalignment m;
  m.t_s = out.t_s;
  m.heading_rad = out.misalignment.heading_rad;
  m.pitch_rad = out.misalignment.pitch_rad;
  m.heading_std_rad = std::isfinite(out.sigma_heading_rad) ? out.sigma_heading_rad : -1.0;
  m.pitch_std_rad = std::isfinite(out.sigma_pitch_rad) ? out.sigma_pitch_rad : -1.0;
  m.converged = out.converged;
  m.samples_used = out.samples_used;
  return m;
}

results::MisalignmentRow output_row(const MisalignmentOutput& m) {
  results::MisalignmentRow r;
  r.t_s = m.t_s;
  r.heading_rad = m.misalignment.heading_rad;
  r.pitch_rad = m.misalignment.pitch_rad;
  r.heading_std_rad = m.sigma_heading_rad;
  r.pitch_std_rad = m.sigma_pitch_rad;
  r.converged = m.converged;
  r.state = to_string(m.state);
  r.samples_used = m.samples_used;
  return r;
}

std::vector<ComponentInput> calibration_inputs(const MisalignmentCalibratorParams& p) {
  std::vector<ComponentInput> in{{"gnss", true, "", 0.0}};
  if (p.use_ins) in.push_back({"ins", true, "", 0.0});
  return in;
}

const char* to_string(CalibrationState state) {
  switch (state) {
    case CalibrationState::kWaiting: return "waiting";
    case CalibrationState::kCalibrating: return "calibrating";
    case CalibrationState::kConverged: return "converged";
    case CalibrationState::kFrozen: return "frozen";
  }
  return "unknown";
}

const char* to_string(CalibrationEpochStatus status) {
  switch (status) {
    case CalibrationEpochStatus::kUsed: return "used";
    case CalibrationEpochStatus::kNoIns: return "no_ins";
    case CalibrationEpochStatus::kInvalidFix: return "invalid_fix";
    case CalibrationEpochStatus::kNoAttitude: return "no_attitude";
    case CalibrationEpochStatus::kReversing: return "reversing";
    case CalibrationEpochStatus::kLowSpeed: return "low_speed";
    case CalibrationEpochStatus::kTurning: return "turning";
    case CalibrationEpochStatus::kFrozen: return "frozen";
    case CalibrationEpochStatus::kOutlier: return "outlier";
  }
  return "unknown";
}

double MisalignmentCalibrator::Regression::residual_sum_squares() const {
  if (!(sum_phi2 > 0.0)) return 0.0;
  // sum (y - theta phi)^2 at the least-squares theta; clamp the rounding of the difference.
  return std::max(0.0, sum_y2 - sum_phi_y * sum_phi_y / sum_phi2);
}

MisalignmentCalibrator::MisalignmentCalibrator(const MisalignmentCalibratorParams& p)
    : params_(p), attitude_(p.max_bracket_s), motion_(p.braking_stop) {
  auto require = [](bool ok, const char* what) {
    if (!ok) throw std::invalid_argument(std::string("MisalignmentCalibratorParams: ") + what);
  };
  require(p.min_speed_mps > 0.0, "min_speed_mps must be > 0");
  require(p.max_yaw_rate_rad_s > 0.0, "max_yaw_rate_rad_s must be > 0");
  require(p.yaw_rate_half_window_s > 0.0, "yaw_rate_half_window_s must be > 0");
  require(p.converged_sigma_rad > 0.0, "converged_sigma_rad must be > 0");
  require(p.residual_std_floor_mps > 0.0, "residual_std_floor_mps must be > 0");
  require(p.max_bracket_s > 0.0, "max_bracket_s must be > 0");
  require(!p.lever_arm_body_m || p.lever_arm_body_m->allFinite(), "lever_arm_body_m must be finite");
  require(p.max_speed_mps > 0.0, "max_speed_mps must be > 0");
  require(p.max_acceleration_mps2 > 0.0, "max_acceleration_mps2 must be > 0");
  require(p.speed_jump_margin_mps >= 0.0, "speed_jump_margin_mps must be >= 0");
  require(p.speed_jump_reference_max_age_s > 0.0, "speed_jump_reference_max_age_s must be > 0");
  require(p.innovation_min_samples >= 2, "innovation_min_samples must be >= 2");
  require(p.innovation_n_sigma > 0.0, "innovation_n_sigma must be > 0");
  require(p.gnss_velocity_sigma_mps > 0.0, "gnss_velocity_sigma_mps must be > 0");
  require(p.innovation_angle_margin_rad >= 0.0 && p.innovation_angle_margin_rad < 1.5,
          "innovation_angle_margin_rad must be in [0, 1.5)");
  require(p.innovation_max_consecutive_rejections >= 1, "innovation_max_consecutive_rejections must be >= 1");
}

void MisalignmentCalibrator::add_gnss(const GnssSample& sample) {
  queue_gnss_sample(sample, last_gnss_t_s_, pending_gnss_);
}

void MisalignmentCalibrator::add_ins(const InsSample& sample) {
  if (params_.use_ins) attitude_.add(sample);
}

std::vector<MisalignmentOutput> MisalignmentCalibrator::process_until(double watermark_s) {
  if (std::isnan(watermark_s)) throw std::invalid_argument("MisalignmentCalibrator::process_until: watermark is NaN");
  if (watermark_s > watermark_s_) watermark_s_ = watermark_s;
  std::vector<MisalignmentOutput> out;
  const double h = params_.yaw_rate_half_window_s;
  while (!pending_gnss_.empty() && pending_gnss_.front().t_s <= watermark_s_) {
    const double t = pending_gnss_.front().t_s;
    if (params_.use_ins && attitude_.state_at(t, watermark_s_) == BracketState::kPending) break;
    // Only where the INS record starts (no INS h before the epoch) the window looks forwards.
    if (params_.use_ins && attitude_.state_at(t - h, watermark_s_) == BracketState::kMissing &&
        attitude_.state_at(t + h, watermark_s_) == BracketState::kPending)
      break;
    out.push_back(process_epoch(pending_gnss_.front()));
    pending_gnss_.pop_front();
    // The next epoch is later; its yaw window starts no earlier than t_next - 2h > t - 2h.
    attitude_.drop_before(t - 2.0 * h);
  }
  return out;
}

std::vector<MisalignmentOutput> MisalignmentCalibrator::finish() {
  return process_until(std::numeric_limits<double>::infinity());
}

void MisalignmentCalibrator::freeze() { frozen_ = true; }
void MisalignmentCalibrator::unfreeze() { frozen_ = false; }
void MisalignmentCalibrator::reset() {
  heading_ = Regression{};
  pitch_ = Regression{};
  heading_correlation_.reset();
  pitch_correlation_.reset();
  samples_used_ = 0;
  last_used_forward_.reset();
  consecutive_innovation_rejections_ = 0;
  braking_snapshot_.reset();
}

void MisalignmentCalibrator::track_braking_stop(double t_s, double speed_mps) {
  const MotionPhase phase = motion_.add(t_s, speed_mps);
  auto take = [&] {
    return std::optional<BrakingSnapshot>(
        BrakingSnapshot{heading_, pitch_, samples_used_, last_used_forward_, consecutive_innovation_rejections_, 0});
  };
  auto restore = [&](const BrakingSnapshot& snap) {
    heading_ = snap.heading;
    pitch_ = snap.pitch;
    samples_used_ = snap.samples_used;
    last_used_forward_ = snap.last_used_forward;
    consecutive_innovation_rejections_ = snap.consecutive_innovation_rejections;
  };
  const uint64_t withdrawn =
      apply_braking_stop(braking_snapshot_, phase, params_.braking_stop.enabled && !frozen_, take, restore);
  if (withdrawn == 0) return;
  ++counters_.braking_stops;
  counters_.braking_withdrawn += withdrawn;
}

MisalignmentCalibrator::RegressionSpread MisalignmentCalibrator::spread(const Regression& r) const {
  const double dof = static_cast<double>(samples_used_ - 1);
  const double s = std::max(params_.residual_std_floor_mps, std::sqrt(r.residual_sum_squares() / dof));
  return {s, s / std::sqrt(r.sum_phi2)};
}

double MisalignmentCalibrator::published_sigma_theta(const Regression& r,
                                                     const ResidualCorrelationTracker& correlation) const {
  const double dof = static_cast<double>(samples_used_ - 1);
  const double sigma_v = params_.gnss_velocity_sigma_mps;
  const double s = std::max(
      params_.residual_std_floor_mps,
      std::sqrt((r.residual_sum_squares() + kPriorResidualEpochs * sigma_v * sigma_v) / (dof + kPriorResidualEpochs)));
  return s / std::sqrt(r.sum_phi2) * correlation.sigma_factor();
}

bool MisalignmentCalibrator::is_outlier(const GnssSample& g, const Eigen::Vector3d& v_b) {
  innovation_suspended_now_ = false;
  if (!params_.outlier_gate_enabled) return false;
  const double phi = v_b.x();
  // 2. Speed jump against the last used epoch.
  if (last_used_forward_) {
    const double dt = g.t_s - last_used_forward_->first;
    if (dt <= params_.speed_jump_reference_max_age_s &&
        std::abs(phi - last_used_forward_->second) > params_.max_acceleration_mps2 * dt + params_.speed_jump_margin_mps)
      return true;
  }
  // 3. Innovation against the current estimate.
  if (samples_used_ < params_.innovation_min_samples) return false;
  const double sigma_v = g.vel_std_mps && *g.vel_std_mps > 0.0 ? *g.vel_std_mps : params_.gnss_velocity_sigma_mps;
  const double margin = std::tan(params_.innovation_angle_margin_rad) * phi;
  auto fails = [&](const Regression& r, double y) {
    const RegressionSpread sp = spread(r);
    const double s = std::max(sp.residual_std_mps, sigma_v);
    const double sigma_gate = std::sqrt(s * s + (sp.sigma_theta * phi) * (sp.sigma_theta * phi));
    return std::abs(y - r.theta() * phi) > params_.innovation_n_sigma * sigma_gate + margin;
  };
  if (!fails(heading_, v_b.y()) && !fails(pitch_, v_b.z())) {
    consecutive_innovation_rejections_ = 0;
    return false;
  }
  if (consecutive_innovation_rejections_ < params_.innovation_max_consecutive_rejections) {
    ++consecutive_innovation_rejections_;
    return true;
  }
  innovation_suspended_now_ = true;
  return false;
}

MisalignmentOutput MisalignmentCalibrator::current() const {
  MisalignmentOutput o;
  o.t_s = last_t_s_;
  o.samples_used = samples_used_;
  if (samples_used_ > 0) {
    const double theta_h = heading_.theta(), theta_p = pitch_.theta();
    const double a_h = std::atan(theta_h);
    const double a_p = std::atan(theta_p * std::cos(a_h));
    o.misalignment = Misalignment{a_h, a_p};
    if (samples_used_ >= 2) {
      const double sigma_theta_h = published_sigma_theta(heading_, heading_correlation_);
      const double sigma_theta_p = published_sigma_theta(pitch_, pitch_correlation_);
      // d atan(x)/dx = 1 / (1 + x^2); a_p depends on theta_p through x = theta_p cos a_h.
      const double x_p = theta_p * std::cos(a_h);
      o.sigma_heading_rad = sigma_theta_h / (1.0 + theta_h * theta_h);
      o.sigma_pitch_rad = sigma_theta_p * std::cos(a_h) / (1.0 + x_p * x_p);
    }
  }
  o.converged = samples_used_ >= params_.min_samples && o.sigma_heading_rad < params_.converged_sigma_rad &&
                o.sigma_pitch_rad < params_.converged_sigma_rad;
  if (!params_.use_ins) {
    o.state = CalibrationState::kWaiting;
    o.reason = "no INS: the misalignment needs the INS attitude";
  } else if (frozen_) {
    o.state = CalibrationState::kFrozen;
    o.reason = "frozen by command";
  } else if (samples_used_ == 0) {
    o.state = CalibrationState::kWaiting;
    o.reason = "waiting for a straight drive above the minimum speed with valid GNSS";
  } else if (o.converged) {
    o.state = CalibrationState::kConverged;
    o.reason = "both sigmas below the threshold";
  } else {
    o.state = CalibrationState::kCalibrating;
    // Name what is missing with its numbers: a short drive must say it, not just "calibrating".
    auto deg = [](double rad) {
      std::ostringstream t;
      t.precision(3);
      t << rad * 180.0 / kPi;
      return t.str();
    };
    if (samples_used_ < params_.min_samples) {
      std::ostringstream t;
      t.precision(3);
      t << params_.min_speed_mps;
      o.reason = "collecting samples: " + std::to_string(samples_used_) + " GNSS epochs used (straight, above " +
                 t.str() + " m/s), " + std::to_string(params_.min_samples) + " needed";
    } else {
      o.reason = "sigma above the threshold: " + deg(std::max(o.sigma_heading_rad, o.sigma_pitch_rad)) + " deg, " +
                 deg(params_.converged_sigma_rad) + " deg needed";
    }
  }
  return o;
}

MisalignmentOutput MisalignmentCalibrator::process_epoch(const GnssSample& g) {
  ++counters_.epochs;
  last_t_s_ = g.t_s;
  auto finish_epoch = [&](CalibrationEpochStatus s, uint64_t& counter) {
    ++counter;
    MisalignmentOutput o = current();
    o.epoch_status = s;
    return o;
  };
  if (!params_.use_ins) return finish_epoch(CalibrationEpochStatus::kNoIns, counters_.no_ins);
  if (frozen_) {
    braking_snapshot_.reset();
    return finish_epoch(CalibrationEpochStatus::kFrozen, counters_.frozen);
  }
  if (!g.valid()) return finish_epoch(CalibrationEpochStatus::kInvalidFix, counters_.invalid_fix);

  const double h = params_.yaw_rate_half_window_s;
  const std::optional<Attitude> att = attitude_.attitude_at(g.t_s, watermark_s_);
  if (!att) return finish_epoch(CalibrationEpochStatus::kNoAttitude, counters_.no_attitude);
  // The rate window [t - 2h, t], backwards (the epoch's own INS is the last one needed); [t - h, t]
  // where the INS record starts less than 2h before the epoch, [t, t + h] where it starts less
  // than h before it (the first epochs only).
  std::optional<Attitude> after = att;
  std::optional<Attitude> before = attitude_.attitude_at(g.t_s - 2.0 * h, watermark_s_);
  std::optional<Attitude> mid = attitude_.attitude_at(g.t_s - h, watermark_s_);
  double window_s = 2.0 * h;
  if (!before && mid) {
    before = mid;
    mid = attitude_.attitude_at(g.t_s - 0.5 * h, watermark_s_);
    window_s = h;
  } else if (!mid) {
    before = att;
    after = attitude_.attitude_at(g.t_s + h, watermark_s_);
    mid = attitude_.attitude_at(g.t_s + 0.5 * h, watermark_s_);
    window_s = h;
  }
  if (!before || !mid || !after) return finish_epoch(CalibrationEpochStatus::kNoAttitude, counters_.no_attitude);
  // The rate at the window's middle, applied at t: the lever-arm term lags by h (it is small: a
  // straight-line gate follows).
  const Eigen::Vector3d omega_b = body_rate_rad_s(*before, *mid, *after, window_s);
  // The yaw rate about the navigation vertical (heading is clockwise, so the sign flips; only |.| matters).
  const double yaw_rate = wrap_pi(after->heading_rad - before->heading_rad) / window_s;

  Eigen::Vector3d v_b = enu_to_body(*att) * g.vel_enu_mps;
  if (params_.lever_arm_body_m) v_b -= omega_b.cross(*params_.lever_arm_body_m);
  track_braking_stop(g.t_s, std::isfinite(v_b.x()) ? v_b.x() : std::nan(""));

  // 1. Physical limit, before the sign and speed tests so a spike is not counted as reversing (also
  // catches 1e308 and its overflow to inf in the rotation).
  if (!v_b.allFinite() || (params_.outlier_gate_enabled && g.vel_enu_mps.head<2>().norm() > params_.max_speed_mps))
    return finish_epoch(CalibrationEpochStatus::kOutlier, counters_.outlier);
  if (v_b.x() < 0.0) return finish_epoch(CalibrationEpochStatus::kReversing, counters_.reversing);
  if (v_b.x() < params_.min_speed_mps) return finish_epoch(CalibrationEpochStatus::kLowSpeed, counters_.low_speed);
  if (std::abs(yaw_rate) > params_.max_yaw_rate_rad_s)
    return finish_epoch(CalibrationEpochStatus::kTurning, counters_.turning);
  if (is_outlier(g, v_b)) return finish_epoch(CalibrationEpochStatus::kOutlier, counters_.outlier);
  if (innovation_suspended_now_) ++counters_.innovation_suspended;

  const double phi = v_b.x();
  if (samples_used_ >= 2) {
    // A-priori residuals against the estimate so far, normalised as for RLS (E[r^2] = s^2).
    const double norm = std::sqrt(1.0 + phi * phi / heading_.sum_phi2);
    heading_correlation_.add((v_b.y() - heading_.theta() * phi) / norm, 3.0 * spread(heading_).residual_std_mps);
    pitch_correlation_.add((v_b.z() - pitch_.theta() * phi) / norm, 3.0 * spread(pitch_).residual_std_mps);
  }
  last_used_forward_ = std::make_pair(g.t_s, phi);
  heading_.sum_phi2 += phi * phi;
  heading_.sum_phi_y += phi * v_b.y();
  heading_.sum_y2 += v_b.y() * v_b.y();
  pitch_.sum_phi2 += phi * phi;
  pitch_.sum_phi_y += phi * v_b.z();
  pitch_.sum_y2 += v_b.z() * v_b.z();
  ++samples_used_;
  if (braking_snapshot_) ++braking_snapshot_->used_since;
  return finish_epoch(CalibrationEpochStatus::kUsed, counters_.used);
}

ODONAV_STATE_FIELDS(MisalignmentCounters) {
  a("epochs", s.epochs)("used", s.used)("no_ins", s.no_ins)("invalid_fix", s.invalid_fix)("no_attitude", s.no_attitude)(
      "reversing", s.reversing)("low_speed", s.low_speed)("turning", s.turning)("frozen", s.frozen)(
      "outlier", s.outlier)("innovation_suspended", s.innovation_suspended)("braking_stops", s.braking_stops)(
      "braking_withdrawn", s.braking_withdrawn);
}

template <class Archive, class Self>
void MisalignmentCalibrator::state_fields(Archive& a, Self& c) {
  a("heading", c.heading_)("pitch", c.pitch_)("samples_used", c.samples_used_)(
      "last_used_forward", c.last_used_forward_)("consecutive_innovation_rejections",
                                                 c.consecutive_innovation_rejections_)("frozen", c.frozen_)(
      "last_t_s", c.last_t_s_)("counters", c.counters_)
      .via(
          "motion_epochs", [&] { return c.motion_.state(); }, [&](const auto& epochs) { c.motion_.restore(epochs); })(
          "braking_snapshot", c.braking_snapshot_);
  a.via("heading_correlation", c.heading_correlation_).via("pitch_correlation", c.pitch_correlation_);
  a.check("consecutive_innovation_rejections",
          c.consecutive_innovation_rejections_ >= 0 &&
              c.consecutive_innovation_rejections_ <= c.params_.innovation_max_consecutive_rejections,
          "is negative or above the configured limit");
  a.check("last_t_s", std::isfinite(c.last_t_s_), "is not finite");
  a.check("samples_used", c.samples_used_ <= c.counters_.used, "exceeds the used-epoch counter");
}

StateJson MisalignmentCalibrator::save_state() const { return save_fields(*this); }

void MisalignmentCalibrator::restore_state(const StateJson& state) {
  // Restored into a copy: this one changes only when everything was read.
  MisalignmentCalibrator c = restored_copy(*this, state, "calibrator");
  // The epochs up to the restored one were processed: one stamped at or before it is refused.
  if (c.counters_.epochs > 0) c.last_gnss_t_s_ = c.last_t_s_;
  *this = std::move(c);
}

}  // namespace odonav::calibration
