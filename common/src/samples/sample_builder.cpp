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

namespace {

// One entry per EpochStatus, in enum order: its counter and its stable name. to_string(),
// SampleBuilderCounters::count() and SampleBuilder::count() all read this one table.
struct EpochStatusEntry {
  EpochStatus status;
  uint64_t SampleBuilderCounters::*counter;
  const char* text;
};

constexpr EpochStatusEntry kEpochStatusTable[] = {
    {EpochStatus::kAccepted, &SampleBuilderCounters::accepted, "accepted"},
    {EpochStatus::kChainStart, &SampleBuilderCounters::chain_starts, "chain_start"},
    {EpochStatus::kInvalidFix, &SampleBuilderCounters::invalid_fix, "invalid_fix"},
    {EpochStatus::kLowFixQuality, &SampleBuilderCounters::low_fix_quality, "low_fix_quality"},
    {EpochStatus::kNoOdometer, &SampleBuilderCounters::no_odometer, "no_odometer"},
    {EpochStatus::kNoAttitude, &SampleBuilderCounters::no_attitude, "no_attitude"},
    {EpochStatus::kNegativeSpeed, &SampleBuilderCounters::negative_speed, "negative_speed"},
    {EpochStatus::kSpeedJump, &SampleBuilderCounters::speed_jump, "speed_jump"},
    {EpochStatus::kGap, &SampleBuilderCounters::gap, "gap"},
    {EpochStatus::kMinSpeed, &SampleBuilderCounters::min_speed, "min_speed"},
    {EpochStatus::kReversing, &SampleBuilderCounters::reversing, "reversing"},
    {EpochStatus::kYawRate, &SampleBuilderCounters::yaw_rate, "yaw_rate"},
    {EpochStatus::kNoPulses, &SampleBuilderCounters::no_pulses, "no_pulses"},
    {EpochStatus::kInnovation, &SampleBuilderCounters::innovation, "innovation"},
};

constexpr std::size_t kEpochStatusCount = static_cast<std::size_t>(kLastEpochStatus) + 1;
static_assert(sizeof kEpochStatusTable / sizeof kEpochStatusTable[0] == kEpochStatusCount,
              "one kEpochStatusTable entry per EpochStatus (up to kLastEpochStatus)");

constexpr bool table_in_enum_order() {
  for (std::size_t i = 0; i < kEpochStatusCount; ++i)
    if (static_cast<std::size_t>(kEpochStatusTable[i].status) != i) return false;
  return true;
}
static_assert(table_in_enum_order(), "kEpochStatusTable entries must follow the order of EpochStatus");

/// The table entry of a status; nullptr for a value outside the enum (a cast integer).
const EpochStatusEntry* entry_of(EpochStatus status) {
  const auto index = static_cast<std::size_t>(status);
  return index < kEpochStatusCount ? &kEpochStatusTable[index] : nullptr;
}

}  // namespace

const char* to_string(EpochStatus status) {
  const EpochStatusEntry* entry = entry_of(status);
  return entry ? entry->text : "unknown";
}

uint64_t SampleBuilderCounters::count(EpochStatus status) const {
  const EpochStatusEntry* entry = entry_of(status);
  return entry ? this->*(entry->counter) : 0;
}

double innovation_bound_m(const SampleBuilderParams& params, double sigma_v_mps, double k_m_per_pulse,
                          double sigma_k_m_per_pulse, double phi_pulses, double interval_s) {
  const double estimate_part_m = sigma_k_m_per_pulse * phi_pulses;
  const double sigma_gate_m = std::sqrt(regression_noise_variance_m2(sigma_v_mps, interval_s, k_m_per_pulse) +
                                        estimate_part_m * estimate_part_m);
  return params.innovation_n_sigma * sigma_gate_m +
         params.innovation_k_change_fraction * std::abs(k_m_per_pulse * phi_pulses);
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
  if (const EpochStatusEntry* entry = entry_of(status)) ++(counters_.*(entry->counter));
}

std::optional<EpochStatus> SampleBuilder::check_epoch_velocity(const GnssSample& g, EpochInputs& in) {
  if (!g.valid()) return EpochStatus::kInvalidFix;
  if (fix_quality_rank(g.fix) < params_.min_fix_rank) return EpochStatus::kLowFixQuality;
  if (!frame_) frame_.emplace(g.position);

  const std::optional<double> count_now = odometer_.count_at(g.t_s, watermark_s_);
  if (!count_now) return EpochStatus::kNoOdometer;
  Attitude att;
  if (params_.use_ins) {
    const std::optional<Attitude> a = attitude_.attitude_at(g.t_s, watermark_s_);
    if (!a) return EpochStatus::kNoAttitude;
    att = *a;
  }
  in.misalignment = misalignment_.at_or_before(g.t_s).value_or(Misalignment{});
  const Eigen::Vector3d vel_enu_mps = reference_point_velocity(g, att);
  const double v = forward_speed(vel_enu_mps, att, in.misalignment);
  in.forward_speed_mps = v;
  if (v < 0.0) return EpochStatus::kNegativeSpeed;

  // Speed jump against the last epoch whose velocity was judged good (if recent enough).
  if (last_good_speed_) {
    const double dt = g.t_s - last_good_speed_->first;
    if (dt <= params_.speed_jump_reference_max_age_s &&
        std::abs(v - last_good_speed_->second) > params_.max_acceleration_mps2 * dt + params_.speed_jump_margin_mps)
      return EpochStatus::kSpeedJump;
  }
  in.epoch = GoodEpoch{g.t_s, vel_enu_mps, att, *count_now};
  return std::nullopt;
}

EpochStatus SampleBuilder::check_interval(const GnssSample& g, const EpochInputs& in, ScaleFactorSample& sample) const {
  const GoodEpoch& s = *chain_start_;
  const double dt = g.t_s - s.t_s;
  const double v = in.forward_speed_mps;
  // Both ends with the same (latest) misalignment, so the sample is one consistent projection.
  const double v_start = forward_speed(s.vel_enu_mps, s.attitude, in.misalignment);
  double yaw_rate = 0.0;
  if (params_.use_ins) {
    yaw_rate = wrap_pi(in.epoch.attitude.heading_rad - s.attitude.heading_rad) / dt;
  } else {
    yaw_rate = wrap_pi(gnss_course_rad(g.vel_enu_mps) - gnss_course_rad(s.vel_enu_mps)) / dt;
  }
  const double phi = in.epoch.count_pulses - s.count_pulses;
  if (dt > params_.max_interval_s) return EpochStatus::kGap;
  if (v_start < params_.min_speed_mps || v < params_.min_speed_mps) return EpochStatus::kMinSpeed;
  if (odometer_.any_reversing(s.t_s, g.t_s)) return EpochStatus::kReversing;
  if (params_.yaw_rate_gate_enabled && std::abs(yaw_rate) > params_.max_yaw_rate_rad_s) return EpochStatus::kYawRate;
  if (!(phi > 0.0)) return EpochStatus::kNoPulses;
  sample.t_s = g.t_s;
  sample.phi_pulses = phi;
  sample.dt_s = dt;
  sample.y_m = 0.5 * (v_start + v) * dt;
  sample.gnss_position_enu_m = frame_->to_enu(g.position);
  sample.straight = std::abs(yaw_rate) < params_.straight_yaw_rate_rad_s;
  return EpochStatus::kAccepted;
}

SampleBuilder::InnovationVerdict SampleBuilder::innovation_gate(const GnssSample& g, const ScaleFactorSample& sample) {
  if (!params_.innovation_gate_enabled) return InnovationVerdict::kPassed;
  const std::optional<KEstimate> k = k_estimates_.before(g.t_s);
  if (!k) return InnovationVerdict::kPassed;
  const double sigma_v = g.vel_std_mps && *g.vel_std_mps > 0.0 ? *g.vel_std_mps : params_.gnss_velocity_sigma_mps;
  const double predicted_m = k->k_m_per_pulse * sample.phi_pulses;
  const double bound_m =
      innovation_bound_m(params_, sigma_v, k->k_m_per_pulse, k->sigma_m_per_pulse, sample.phi_pulses, sample.dt_s);
  if (!(std::abs(sample.y_m - predicted_m) > bound_m)) {
    consecutive_innovation_rejections_ = 0;
    return InnovationVerdict::kPassed;
  }
  if (consecutive_innovation_rejections_ < params_.innovation_max_consecutive_rejections) {
    ++consecutive_innovation_rejections_;
    return InnovationVerdict::kOutlier;
  }
  return InnovationVerdict::kSuspended;
}

SampleBuilderEpoch SampleBuilder::process_epoch(const GnssSample& g) {
  ++counters_.epochs;
  SampleBuilderEpoch r;
  r.t_s = g.t_s;
  EpochInputs in;
  const std::optional<EpochStatus> bad_velocity = check_epoch_velocity(g, in);
  r.forward_speed_mps = in.forward_speed_mps;
  if (bad_velocity) {
    // An epoch whose own velocity is unusable breaks the chain (see the header).
    r.status = *bad_velocity;
    chain_start_.reset();
    count(r.status);
    return r;
  }

  bool velocity_good = true;
  if (!chain_start_) {
    r.status = EpochStatus::kChainStart;
  } else {
    ScaleFactorSample sample;
    r.status = check_interval(g, in, sample);
    if (r.status == EpochStatus::kAccepted) {
      switch (innovation_gate(g, sample)) {
        case InnovationVerdict::kPassed:
          r.sample = sample;
          break;
        case InnovationVerdict::kSuspended:
          ++counters_.innovation_suspended;
          r.sample = sample;
          break;
        case InnovationVerdict::kOutlier:
          r.status = EpochStatus::kInnovation;
          velocity_good = false;  // blame this epoch: the previous one already passed as an end
          break;
      }
    }
  }
  count(r.status);
  if (velocity_good) {
    chain_start_ = in.epoch;
    last_good_speed_ = std::make_pair(g.t_s, in.forward_speed_mps);
  } else {
    chain_start_.reset();
  }
  return r;
}

}  // namespace odonav
