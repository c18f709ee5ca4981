#include "odonav/sample_builder.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace odonav {

int fix_quality_rank(int fix) {
  switch (fix) {
    case 0:
    case 6:
      return 0;
    case 2:
    case 3:
    case 9:
      return 2;
    case 5:
      return 3;
    case 4:
      return 4;
    default:
      return 1;
  }
}

const char* to_string(EpochStatus status) {
  switch (status) {
    case EpochStatus::kAccepted: return "accepted";
    case EpochStatus::kChainStart: return "chain_start";
    case EpochStatus::kInvalidFix: return "invalid_fix";
    case EpochStatus::kLowFixQuality: return "low_fix_quality";
    case EpochStatus::kNoOdometer: return "no_odometer";
    case EpochStatus::kNoAttitude: return "no_attitude";
    case EpochStatus::kNegativeSpeed: return "negative_speed";
    case EpochStatus::kSpeedJump: return "speed_jump";
    case EpochStatus::kGap: return "gap";
    case EpochStatus::kMinSpeed: return "min_speed";
    case EpochStatus::kReversing: return "reversing";
    case EpochStatus::kYawRate: return "yaw_rate";
    case EpochStatus::kNoPulses: return "no_pulses";
    case EpochStatus::kInnovation: return "innovation";
  }
  return "unknown";
}

uint64_t SampleBuilderCounters::count(EpochStatus status) const {
  switch (status) {
    case EpochStatus::kAccepted: return accepted;
    case EpochStatus::kChainStart: return chain_starts;
    case EpochStatus::kInvalidFix: return invalid_fix;
    case EpochStatus::kLowFixQuality: return low_fix_quality;
    case EpochStatus::kNoOdometer: return no_odometer;
    case EpochStatus::kNoAttitude: return no_attitude;
    case EpochStatus::kNegativeSpeed: return negative_speed;
    case EpochStatus::kSpeedJump: return speed_jump;
    case EpochStatus::kGap: return gap;
    case EpochStatus::kMinSpeed: return min_speed;
    case EpochStatus::kReversing: return reversing;
    case EpochStatus::kYawRate: return yaw_rate;
    case EpochStatus::kNoPulses: return no_pulses;
    case EpochStatus::kInnovation: return innovation;
  }
  return 0;
}

namespace {
void require(bool ok, const char* what) {
  if (!ok) throw std::invalid_argument(std::string("SampleBuilderParams: ") + what);
}
}  // namespace

SampleBuilder::SampleBuilder(const SampleBuilderParams& p)
    : params_(p), odometer_(p.max_bracket_s, p.odometer_jump_gate), attitude_(p.max_bracket_s) {
  require(p.min_speed_mps >= 0.0, "min_speed_mps must be >= 0");
  require(p.min_fix_rank >= 1 && p.min_fix_rank <= 4, "min_fix_rank must be in 1..4");
  require(p.max_interval_s > 0.0, "max_interval_s must be > 0");
  require(p.max_yaw_rate_rad_s > 0.0, "max_yaw_rate_rad_s must be > 0");
  require(p.straight_yaw_rate_rad_s >= 0.0, "straight_yaw_rate_rad_s must be >= 0");
  require(p.max_acceleration_mps2 > 0.0 && p.speed_jump_margin_mps >= 0.0,
          "max_acceleration_mps2 must be > 0 and speed_jump_margin_mps >= 0");
  require(p.speed_jump_reference_max_age_s > 0.0, "speed_jump_reference_max_age_s must be > 0");
  require(p.innovation_n_sigma > 0.0, "innovation_n_sigma must be > 0");
  require(p.gnss_velocity_sigma_mps > 0.0, "gnss_velocity_sigma_mps must be > 0");
  require(p.innovation_k_change_fraction >= 0.0, "innovation_k_change_fraction must be >= 0");
  require(p.innovation_max_consecutive_rejections >= 1, "innovation_max_consecutive_rejections must be >= 1");
  require(p.max_bracket_s > 0.0, "max_bracket_s must be > 0");
  require(!p.lever_arm_body_m || p.lever_arm_body_m->allFinite(), "lever_arm_body_m must be finite");
  require(p.lever_arm_rate_half_window_s > 0.0, "lever_arm_rate_half_window_s must be > 0");
}

OdometerAddResult SampleBuilder::add_odometer(const OdometerSample& sample) {
  const OdometerAddResult result = odometer_.add(sample);
  counters_.odometer_jumps_rejected = odometer_.jumps_rejected();
  counters_.odometer_rebases = odometer_.rebases();
  return result;
}

void SampleBuilder::add_gnss(const GnssSample& sample) {
  detail::check_stream_time("gnss", sample.t_s, last_gnss_t_s_);
  check_gnss_sample("gnss", sample);
  last_gnss_t_s_ = sample.t_s;
  pending_gnss_.push_back(sample);
}

void SampleBuilder::add_ins(const InsSample& sample) {
  if (params_.use_ins) attitude_.add(sample);
}

void SampleBuilder::add_misalignment(double t_s, const Misalignment& m) {
  if (!std::isfinite(m.heading_rad) || !std::isfinite(m.pitch_rad)) {
    std::ostringstream s;
    s << "misalignment: at t=" << t_s << " s, angles are not finite";
    throw StreamInputError(s.str());
  }
  misalignment_.add(t_s, m);
}

void SampleBuilder::add_scale_factor_estimate(double t_s, double k, double sigma) {
  if (!std::isfinite(k) || !(k > 0.0) || !std::isfinite(sigma) || sigma < 0.0) {
    std::ostringstream s;
    s << "scale_factor_estimate: at t=" << t_s << " s, K=" << k << " m/pulse must be finite and > 0 and sigma="
      << sigma << " finite and >= 0";
    throw StreamInputError(s.str());
  }
  k_estimates_.add(t_s, KEstimate{k, sigma});
}

std::vector<SampleBuilderEpoch> SampleBuilder::process_until(double watermark_s, const EpochCallback& on_epoch) {
  if (std::isnan(watermark_s)) throw std::invalid_argument("SampleBuilder::process_until: watermark is NaN");
  if (watermark_s > watermark_s_) watermark_s_ = watermark_s;
  std::vector<SampleBuilderEpoch> out;
  while (!pending_gnss_.empty() && pending_gnss_.front().t_s <= watermark_s_) {
    const double t = pending_gnss_.front().t_s;
    // Wait until the epoch's odometer count and attitude are final (see stream_buffers.hpp).
    if (odometer_.state_at(t, watermark_s_) == BracketState::kPending) break;
    if (params_.use_ins && attitude_.state_at(t, watermark_s_) == BracketState::kPending) break;
    if (compensates_lever_arm() &&
        attitude_.state_at(t + params_.lever_arm_rate_half_window_s, watermark_s_) == BracketState::kPending)
      break;
    out.push_back(process_epoch(pending_gnss_.front()));
    pending_gnss_.pop_front();
    // Everything before this epoch is no longer needed: the next interval starts here and the
    // chain start keeps its own copy of what it needs.
    odometer_.drop_before(t);
    // Keep the INS window [t - h, ...] for the next epoch's body rate (lever arm).
    attitude_.drop_before(compensates_lever_arm() ? t - params_.lever_arm_rate_half_window_s : t);
    misalignment_.drop_before(t);
    k_estimates_.drop_before(t);
    if (on_epoch) on_epoch(out.back());
  }
  return out;
}

std::vector<SampleBuilderEpoch> SampleBuilder::finish(const EpochCallback& on_epoch) {
  return process_until(std::numeric_limits<double>::infinity(), on_epoch);
}

bool SampleBuilder::compensates_lever_arm() const { return params_.use_ins && params_.lever_arm_body_m.has_value(); }

Eigen::Vector3d SampleBuilder::reference_point_velocity(const GnssSample& g, const Attitude& att) const {
  if (!compensates_lever_arm()) return g.vel_enu_mps;
  const double h = params_.lever_arm_rate_half_window_s;
  std::optional<Attitude> before = attitude_.attitude_at(g.t_s - h, watermark_s_);
  std::optional<Attitude> after = attitude_.attitude_at(g.t_s + h, watermark_s_);
  double window_s = 2.0 * h;
  if (!before && !after) return g.vel_enu_mps;  // no rate: leave uncompensated (isolated INS sample)
  if (!before) {
    before = att;
    window_s = h;
  } else if (!after) {
    after = att;
    window_s = h;
  }
  const Eigen::Vector3d omega_b = body_rate_rad_s(*before, att, *after, window_s);
  return g.vel_enu_mps - body_to_enu(att) * omega_b.cross(*params_.lever_arm_body_m);
}

double SampleBuilder::forward_speed(const Eigen::Vector3d& v, const Attitude& att, const Misalignment& mis) const {
  return params_.use_ins ? forward_speed_along_odometer(v, att, mis) : v.norm();
}

void SampleBuilder::count(EpochStatus status) {
  switch (status) {
    case EpochStatus::kAccepted: ++counters_.accepted; break;
    case EpochStatus::kChainStart: ++counters_.chain_starts; break;
    case EpochStatus::kInvalidFix: ++counters_.invalid_fix; break;
    case EpochStatus::kLowFixQuality: ++counters_.low_fix_quality; break;
    case EpochStatus::kNoOdometer: ++counters_.no_odometer; break;
    case EpochStatus::kNoAttitude: ++counters_.no_attitude; break;
    case EpochStatus::kNegativeSpeed: ++counters_.negative_speed; break;
    case EpochStatus::kSpeedJump: ++counters_.speed_jump; break;
    case EpochStatus::kGap: ++counters_.gap; break;
    case EpochStatus::kMinSpeed: ++counters_.min_speed; break;
    case EpochStatus::kReversing: ++counters_.reversing; break;
    case EpochStatus::kYawRate: ++counters_.yaw_rate; break;
    case EpochStatus::kNoPulses: ++counters_.no_pulses; break;
    case EpochStatus::kInnovation: ++counters_.innovation; break;
  }
}

SampleBuilderEpoch SampleBuilder::process_epoch(const GnssSample& g) {
  ++counters_.epochs;
  SampleBuilderEpoch r;
  r.t_s = g.t_s;
  r.forward_speed_mps = std::numeric_limits<double>::quiet_NaN();
  // An epoch whose own velocity is unusable breaks the chain (see the header).
  auto bad_epoch = [&](EpochStatus s) {
    r.status = s;
    chain_start_.reset();
    count(s);
    return r;
  };

  if (!g.valid()) return bad_epoch(EpochStatus::kInvalidFix);
  if (fix_quality_rank(g.fix) < params_.min_fix_rank) return bad_epoch(EpochStatus::kLowFixQuality);
  if (!frame_) frame_.emplace(g.position);

  const std::optional<double> count_now = odometer_.count_at(g.t_s, watermark_s_);
  if (!count_now) return bad_epoch(EpochStatus::kNoOdometer);
  Attitude att;
  if (params_.use_ins) {
    const std::optional<Attitude> a = attitude_.attitude_at(g.t_s, watermark_s_);
    if (!a) return bad_epoch(EpochStatus::kNoAttitude);
    att = *a;
  }
  const Misalignment mis = misalignment_.at_or_before(g.t_s).value_or(Misalignment{});
  const Eigen::Vector3d vel_enu_mps = reference_point_velocity(g, att);
  const double v = forward_speed(vel_enu_mps, att, mis);
  r.forward_speed_mps = v;
  if (v < 0.0) return bad_epoch(EpochStatus::kNegativeSpeed);

  // Speed jump against the last epoch whose velocity was judged good (if recent enough).
  if (last_good_speed_) {
    const double dt = g.t_s - last_good_speed_->first;
    if (dt <= params_.speed_jump_reference_max_age_s &&
        std::abs(v - last_good_speed_->second) > params_.max_acceleration_mps2 * dt + params_.speed_jump_margin_mps)
      return bad_epoch(EpochStatus::kSpeedJump);
  }

  const GoodEpoch here{g.t_s, vel_enu_mps, att, *count_now};
  EpochStatus status = EpochStatus::kAccepted;
  bool velocity_good = true;
  if (!chain_start_) {
    status = EpochStatus::kChainStart;
  } else {
    const GoodEpoch& s = *chain_start_;
    const double dt = g.t_s - s.t_s;
    // Both ends with the same (latest) misalignment, so the sample is one consistent projection.
    const double v_start = forward_speed(s.vel_enu_mps, s.attitude, mis);
    double yaw_rate = 0.0;
    if (params_.use_ins) {
      yaw_rate = wrap_pi(att.heading_rad - s.attitude.heading_rad) / dt;
    } else {
      yaw_rate = wrap_pi(gnss_course_rad(g.vel_enu_mps) - gnss_course_rad(s.vel_enu_mps)) / dt;
    }
    const double phi = *count_now - s.count_pulses;
    if (dt > params_.max_interval_s) {
      status = EpochStatus::kGap;
    } else if (v_start < params_.min_speed_mps || v < params_.min_speed_mps) {
      status = EpochStatus::kMinSpeed;
    } else if (odometer_.any_reversing(s.t_s, g.t_s)) {
      status = EpochStatus::kReversing;
    } else if (params_.yaw_rate_gate_enabled && std::abs(yaw_rate) > params_.max_yaw_rate_rad_s) {
      status = EpochStatus::kYawRate;
    } else if (!(phi > 0.0)) {
      status = EpochStatus::kNoPulses;
    } else {
      ScaleFactorSample sample;
      sample.t_s = g.t_s;
      sample.phi_pulses = phi;
      sample.dt_s = dt;
      sample.y_m = 0.5 * (v_start + v) * dt;
      sample.gnss_position_enu_m = frame_->to_enu(g.position);
      sample.straight = std::abs(yaw_rate) < params_.straight_yaw_rate_rad_s;
      const std::optional<KEstimate> k = k_estimates_.before(g.t_s);
      bool suspended = false;
      if (params_.innovation_gate_enabled && k) {
        const double sigma_v = g.vel_std_mps && *g.vel_std_mps > 0.0 ? *g.vel_std_mps : params_.gnss_velocity_sigma_mps;
        const double predicted = k->k_m_per_pulse * phi;
        const double sigma_gate = std::sqrt(0.5 * (sigma_v * dt) * (sigma_v * dt) +
                                            k->k_m_per_pulse * k->k_m_per_pulse / 6.0 +
                                            (k->sigma_m_per_pulse * phi) * (k->sigma_m_per_pulse * phi));
        const double bound =
            params_.innovation_n_sigma * sigma_gate + params_.innovation_k_change_fraction * std::abs(predicted);
        if (std::abs(sample.y_m - predicted) > bound) {
          if (consecutive_innovation_rejections_ < params_.innovation_max_consecutive_rejections) {
            ++consecutive_innovation_rejections_;
            status = EpochStatus::kInnovation;
            velocity_good = false;  // blame this epoch: the previous one already passed as an end
          } else {
            suspended = true;
          }
        } else {
          consecutive_innovation_rejections_ = 0;
        }
      }
      if (status == EpochStatus::kAccepted) {
        if (suspended) ++counters_.innovation_suspended;
        r.sample = sample;
      }
    }
  }
  r.status = status;
  count(status);
  if (velocity_good) {
    chain_start_ = here;
    last_good_speed_ = std::make_pair(g.t_s, v);
  } else {
    chain_start_.reset();
  }
  return r;
}

}  // namespace odonav
