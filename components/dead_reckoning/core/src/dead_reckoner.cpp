#include "odonav/dead_reckoning/dead_reckoner.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "odonav/consumer_rules.hpp"

namespace odonav::dead_reckoning {

std::optional<double> polar_heading_distance_m(const Geodetic& p) {
  // |lat| below 89 deg is more than 100 km from a pole: no geodesic needed to know.
  if (!(std::abs(p.lat_rad) >= 89.0 * kDegToRad)) return std::nullopt;
  const double d = distance_to_pole_m(p);
  if (!(d <= kPolarHeadingRadiusM)) return std::nullopt;
  return d;
}

std::string polar_heading_text(double distance_m, bool north) {
  std::ostringstream m;
  const long long d = static_cast<long long>(std::ceil(distance_m));
  m << "within " << d << " m of the " << (north ? "North" : "South") << " Pole: true north turns by 1/" << d
    << " rad per metre across the meridian there, so each metre of position error is that much heading error "
       "(the heading is ill-defined inside "
    << static_cast<long long>(kPolarHeadingRadiusM) << " m)";
  return m.str();
}

std::optional<double> DeadReckoner::pole_distance_m() const {
  if (!frame_) return std::nullopt;
  return polar_heading_distance_m(position_);
}

results::DeadReckoningRow output_row(const DeadReckoningOutput& o) {
  results::DeadReckoningRow r;
  r.t_s = o.t_s;
  // Written and published in range (lat [-90, 90], lon [-180, 180)): a start fix at longitude 180
  // is the same place as -180.
  const Geodetic position = normalized(o.position);
  r.lat_rad = position.lat_rad;
  r.lon_rad = position.lon_rad;
  r.height_m = position.height_m;
  r.distance_m = o.distance_m;
  r.k_m_per_pulse = o.k_m_per_pulse;
  r.k_source = to_string(o.k_source);
  r.east_m = o.enu_m.x();
  r.north_m = o.enu_m.y();
  r.up_m = o.enu_m.z();
  r.heading_rad = o.heading_rad;
  r.horizontal_error_m = o.horizontal_error_m;
  r.error_percent = o.error_percent_distance;
  r.error_t_s = o.error_t_s;
  return r;
}

const char* to_string(ScaleFactorSource source) {
  switch (source) {
    case ScaleFactorSource::kNominal: return "nominal";
    case ScaleFactorSource::kIdentified: return "identified";
    case ScaleFactorSource::kCommanded: return "commanded";
  }
  return "unknown";
}

const char* to_string(HeldEstimate estimate) { return estimate == HeldEstimate::kScaleFactor ? "K" : "misalignment"; }

namespace {
// The pulse-jump gate from the DR's own nominal K and maximum speed. Invalid values keep the gate's
// defaults here so that the constructor body, not the buffer, names the bad parameter.
OdometerJumpGate jump_gate_of(const DeadReckonerParams& p) {
  OdometerJumpGate gate;
  if (std::isfinite(p.max_speed_mps) && p.max_speed_mps > 0.0) gate.max_speed_mps = p.max_speed_mps;
  if (std::isfinite(p.nominal_k_m_per_pulse) && p.nominal_k_m_per_pulse > 0.0)
    gate.k_m_per_pulse = p.nominal_k_m_per_pulse;
  return gate;
}
}  // namespace

DeadReckoner::DeadReckoner(const DeadReckonerParams& p)
    : params_(p), odometer_(p.max_bracket_s, jump_gate_of(p)), attitude_(p.max_bracket_s) {
  auto require = [](bool ok, const char* what) {
    if (!ok) throw std::invalid_argument(std::string("DeadReckonerParams: ") + what);
  };
  require(std::isfinite(p.nominal_k_m_per_pulse) && p.nominal_k_m_per_pulse > 0.0,
          "nominal_k_m_per_pulse must be finite and > 0");
  require(std::isfinite(p.max_speed_mps) && p.max_speed_mps > 0.0, "max_speed_mps must be finite and > 0");
  require(p.max_bracket_s > 0.0, "max_bracket_s must be > 0");
  require(std::isfinite(p.gnss_max_gap_s) && p.gnss_max_gap_s >= 0.0, "gnss_max_gap_s must be >= 0 (0: derived)");
  require(std::isfinite(p.gnss_max_gap_floor_s) && p.gnss_max_gap_floor_s > 0.0, "gnss_max_gap_floor_s must be > 0");
  require(std::isfinite(p.gnss_max_gap_periods) && p.gnss_max_gap_periods > 0.0, "gnss_max_gap_periods must be > 0");
  require(p.gnss_period_window >= 1, "gnss_period_window must be >= 1");
  require(p.course_min_speed_mps >= 0.0, "course_min_speed_mps must be >= 0");
  require(p.course_min_speed_floor_mps > 0.0, "course_min_speed_floor_mps must be > 0");
  require(p.course_min_speed_sigmas > 0.0, "course_min_speed_sigmas must be > 0");
  require(p.percent_min_distance_m >= 0.0, "percent_min_distance_m must be >= 0");
  require(std::isfinite(p.estimate_hold_off_s) && p.estimate_hold_off_s >= 0.0,
          "estimate_hold_off_s must be finite and >= 0");
  require(!p.lever_arm_body_m || p.lever_arm_body_m->allFinite(), "lever_arm_body_m must be finite");
}

OdometerAddResult DeadReckoner::add_odometer(const OdometerSample& sample) {
  const OdometerAddResult result = odometer_.add(sample);
  counters_.pulse_jumps_rejected = odometer_.jumps_rejected();
  counters_.pulse_rebases = odometer_.rebases();
  if (result == OdometerAddResult::kAccepted) pending_odometer_t_s_.push_back(sample.t_s);
  return result;
}

void DeadReckoner::add_ins(const InsSample& sample) {
  if (params_.use_ins) attitude_.add(sample);
}

void DeadReckoner::add_gnss(const GnssSample& sample) {
  detail::check_stream_time("gnss", sample.t_s, last_gnss_t_s_);
  check_gnss_sample("gnss", sample);
  // The period observed up to this row (median of the last intervals, robust to a missed fix or an
  // outage), so the gap in force is a function of the data before the row, whatever the arrival.
  if (last_gnss_t_s_) {
    gnss_intervals_s_.push_back(sample.t_s - *last_gnss_t_s_);
    if (gnss_intervals_s_.size() > static_cast<std::size_t>(params_.gnss_period_window)) gnss_intervals_s_.pop_front();
  }
  double period_s = std::numeric_limits<double>::quiet_NaN();
  if (!gnss_intervals_s_.empty()) {
    std::vector<double> sorted(gnss_intervals_s_.begin(), gnss_intervals_s_.end());
    std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2), sorted.end());
    period_s = sorted[sorted.size() / 2];
  }
  last_gnss_gap_s_ = dead_reckoning_gnss_max_gap_s(params_, period_s);
  last_gnss_t_s_ = sample.t_s;
  gnss_.push_back(sample);
  gnss_gap_s_.push_back(last_gnss_gap_s_);
  epochs_to_apply_s_.push_back(sample.t_s);
  error_epochs_.emplace_back(sample, last_gnss_gap_s_);
}

void DeadReckoner::add_scale_factor(double t_s, double k, ScaleFactorSource source) {
  if (!std::isfinite(k) || !(k > 0.0)) {
    std::ostringstream m;
    m << "scale_factor: at t=" << t_s << " s, K=" << k << " m/pulse must be finite and > 0";
    throw StreamInputError(m.str());
  }
  k_history_.add(t_s, KInForce{k, source});
}

void DeadReckoner::add_gnss_latency(double t_s, double latency_s) {
  if (!std::isfinite(t_s) || !std::isfinite(latency_s) || !(std::abs(latency_s) < 10.0)) {
    std::ostringstream m;
    m << "gnss_latency: at t=" << t_s << " s, latency=" << latency_s << " s must be finite and within +-10 s";
    throw StreamInputError(m.str());
  }
  if (last_gnss_latency_ && !(t_s > last_gnss_latency_->first)) {
    ++counters_.gnss_latency_stale;
    return;
  }
  const bool changed = !last_gnss_latency_ ? latency_s != 0.0 : latency_s != last_gnss_latency_->second;
  last_gnss_latency_ = std::make_pair(t_s, latency_s);
  if (changed) gnss_latency_.add(t_s, latency_s);
}

void DeadReckoner::add_turn_slip(double t_s, double g_s_per_rad, double threshold_radps) {
  if (!std::isfinite(t_s) || !std::isfinite(g_s_per_rad) || g_s_per_rad < 0.0 || !std::isfinite(threshold_radps) ||
      threshold_radps < 0.0) {
    std::ostringstream m;
    m << "turn_slip: at t=" << t_s << " s, g=" << g_s_per_rad << " s/rad and threshold=" << threshold_radps
      << " rad/s must be finite and >= 0";
    throw StreamInputError(m.str());
  }
  if (last_turn_slip_ && !(t_s > last_turn_slip_->first)) {
    ++counters_.turn_slip_stale;
    return;
  }
  const TurnSlipInForce value{g_s_per_rad, threshold_radps};
  const bool changed = !last_turn_slip_ ? g_s_per_rad != 0.0
                                        : g_s_per_rad != last_turn_slip_->second.g_s_per_rad ||
                                              threshold_radps != last_turn_slip_->second.threshold_radps;
  last_turn_slip_ = std::make_pair(t_s, value);
  if (changed) turn_slip_.add(t_s, value);
}

double DeadReckoner::turn_slip_fraction_at(double t_s, double mid_s) const {
  if (!params_.use_ins) return 0.0;
  const std::optional<TurnSlipInForce> slip = turn_slip_.at_or_before(t_s);
  if (!slip || slip->g_s_per_rad == 0.0) return 0.0;
  // The window ends at mid-interval, whose attitude the step needs anyway: the slip makes no output
  // wait for more INS than before.
  const double w = params_.turn_slip_yaw_rate_window_s;
  const std::optional<Attitude> a0 = attitude_.attitude_at(mid_s - w, watermark_s_);
  const std::optional<Attitude> a1 = attitude_.attitude_at(mid_s, watermark_s_);
  if (!a0 || !a1) return 0.0;  // no INS around: the distance as counted (as on a straight)
  return turn_slip_fraction(slip->g_s_per_rad, slip->threshold_radps, wrap_pi(a1->heading_rad - a0->heading_rad) / w);
}

void DeadReckoner::add_estimate_received(HeldEstimate estimate, double epoch_s) {
  if (std::isfinite(epoch_s)) held_[static_cast<int>(estimate)].receive(epoch_s);
}

void DeadReckoner::HeldTracker::receive(double epoch_s) {
  // In order as a rule (one producer, event time); a repeat (heartbeat) or an epoch already
  // applicable changes nothing.
  if (last_applicable_s && epoch_s <= *last_applicable_s) return;
  const auto at = std::lower_bound(received_s.begin(), received_s.end(), epoch_s);
  if (at == received_s.end() || *at != epoch_s) received_s.insert(at, epoch_s);
}

bool DeadReckoner::HeldTracker::decide(double t_s, const std::optional<double>& epoch_s, bool exempt) {
  // A stamp that crossed DDS may be a few ulps off the GNSS row's: the guard of the hold-off rule.
  if (epoch_s) {
    while (!received_s.empty() && received_s.front() <= *epoch_s + kEstimateApplicationGuard_s) {
      last_applicable_s = received_s.front();
      received_s.pop_front();
    }
  }
  const bool held =
      !exempt && epoch_s && last_applicable_s && *last_applicable_s < *epoch_s - kEstimateApplicationGuard_s;
  if (!held) {
    if (span) span->open = false;
    return false;
  }
  if (!span || !span->open) span = HeldSpan{t_s, t_s, 0, *last_applicable_s, true};
  span->last_t_s = t_s;
  span->estimate_epoch_s = *last_applicable_s;
  ++span->outputs;
  return true;
}

void DeadReckoner::add_misalignment(double t_s, const Misalignment& m) {
  add_misalignment_estimate(misalignment_, t_s, m);
}

double dead_reckoning_gnss_max_gap_s(const DeadReckonerParams& params, double gnss_period_s) {
  if (params.gnss_max_gap_s > 0.0) return params.gnss_max_gap_s;
  if (!std::isfinite(gnss_period_s)) return params.gnss_max_gap_floor_s;
  return std::max(params.gnss_max_gap_floor_s, params.gnss_max_gap_periods * gnss_period_s);
}

void DeadReckoner::pop_gnss_front() {
  gnss_.pop_front();
  gnss_gap_s_.pop_front();
}

std::optional<Geodetic> DeadReckoner::origin() const {
  if (!frame_) return std::nullopt;
  return frame_->origin();
}

Eigen::Vector3d DeadReckoner::lever_arm_enu(const Attitude& att) const {
  return params_.lever_arm_body_m ? Eigen::Vector3d(body_to_enu(att) * *params_.lever_arm_body_m)
                                  : Eigen::Vector3d::Zero();
}

bool DeadReckoner::gnss_final_at(double t_s) const {
  // Without a row at or after t_s the last row is the earlier end of any bracket of t_s: a later
  // row beyond its gap can no longer make one.
  const double gap_s = last_gnss_t_s_ ? last_gnss_gap_s_ : dead_reckoning_gnss_max_gap_s(params_, std::nan(""));
  return (last_gnss_t_s_ && *last_gnss_t_s_ >= t_s) ||
         watermark_s_ >= estimate_applies_from_s(t_s + gap_s, params_.estimate_hold_off_s);
}

bool DeadReckoner::gnss_complete_at(double t_s) const {
  return (last_gnss_t_s_ && *last_gnss_t_s_ >= t_s) ||
         watermark_s_ >= estimate_applies_from_s(t_s, params_.estimate_hold_off_s);
}

namespace {
// Indices of the GNSS epochs bracketing t_s (last <= t_s, first >= t_s), both valid and close enough.
// The gap allowed between them is the one in force after the earlier epoch (gap_s[lo]).
bool gnss_bracket(const std::deque<GnssSample>& g, const std::deque<double>& gap_s, double t_s, std::size_t& lo,
                  std::size_t& hi) {
  std::size_t i = 0;
  while (i < g.size() && g[i].t_s < t_s) ++i;
  if (i == g.size()) return false;
  if (g[i].t_s == t_s) {
    lo = hi = i;
    return g[i].valid();
  }
  if (i == 0) return false;
  lo = i - 1;
  hi = i;
  return g[lo].valid() && g[hi].valid() && g[hi].t_s - g[lo].t_s <= gap_s[lo];
}
}  // namespace

double DeadReckoner::course_min_speed_at(double t_s) const {
  if (params_.course_min_speed_mps > 0.0) return params_.course_min_speed_mps;
  std::size_t lo = 0, hi = 0;
  if (!gnss_bracket(gnss_, gnss_gap_s_, t_s, lo, hi) || !gnss_[lo].vel_std_mps || !gnss_[hi].vel_std_mps)
    return 1.0;  // no accuracy given: the 1 m/s that suits a 0.05 m/s receiver
  const double sigma = std::max(*gnss_[lo].vel_std_mps, *gnss_[hi].vel_std_mps);
  return std::max(params_.course_min_speed_floor_mps, params_.course_min_speed_sigmas * sigma);
}

std::optional<Eigen::Vector3d> DeadReckoner::gnss_velocity_at(double t_s) const {
  std::size_t lo = 0, hi = 0;
  if (!gnss_bracket(gnss_, gnss_gap_s_, t_s, lo, hi)) return std::nullopt;
  if (lo == hi) return gnss_[lo].vel_enu_mps;
  const double f = (t_s - gnss_[lo].t_s) / (gnss_[hi].t_s - gnss_[lo].t_s);
  return Eigen::Vector3d(gnss_[lo].vel_enu_mps + f * (gnss_[hi].vel_enu_mps - gnss_[lo].vel_enu_mps));
}

std::optional<Eigen::Vector3d> DeadReckoner::gnss_reference_enu(double t_s, const std::optional<Attitude>& att) const {
  std::size_t lo = 0, hi = 0;
  if (!gnss_bracket(gnss_, gnss_gap_s_, t_s, lo, hi)) return std::nullopt;
  Eigen::Vector3d p = frame_->to_enu(gnss_[lo].position);
  if (lo != hi) {
    const double f = (t_s - gnss_[lo].t_s) / (gnss_[hi].t_s - gnss_[lo].t_s);
    p += f * (frame_->to_enu(gnss_[hi].position) - p);
  }
  // The lever arm is turned by the attitude in the ENU frame at the fix, not at the origin.
  if (att) p -= frame_->rotation_from_local(gnss_[lo].position) * lever_arm_enu(*att);
  return p;
}

DeadReckoner::Readiness DeadReckoner::try_start(double t_j) {
  const bool need_attitude = params_.use_ins && params_.lever_arm_body_m.has_value();
  while (!gnss_.empty() && gnss_.front().t_s <= t_j) {
    const GnssSample& g = gnss_.front();
    // A candidate rejected here can never become valid later (its bracket is final): drop it.
    if (!g.valid()) {
      pop_gnss_front();
      continue;
    }
    const std::optional<double> count = odometer_.count_at(g.t_s, watermark_s_);
    if (!count) {
      pop_gnss_front();
      continue;
    }
    std::optional<Attitude> att;
    if (need_attitude) {
      const BracketState st = attitude_.state_at(g.t_s, watermark_s_);
      if (st == BracketState::kPending) return Readiness::kWait;
      if (st == BracketState::kMissing) {
        pop_gnss_front();
        continue;
      }
      att = attitude_.attitude_at(g.t_s, watermark_s_);
    } else if (!params_.use_ins && params_.lever_arm_body_m &&
               g.vel_enu_mps.head<2>().norm() >= course_min_speed_at(g.t_s)) {
      // Degraded mode: the lever arm turned by the GNSS course (pitch and roll unknown, taken as 0).
      att = Attitude{gnss_course_rad(g.vel_enu_mps), 0.0, 0.0};
    }
    Geodetic reference = g.position;
    if (att) reference = move_geodetic(g.position, -lever_arm_enu(*att));
    frame_.emplace(reference);
    position_ = reference;
    start_fix_ = AnchorFix{g.t_s, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), 0.0,
                           g.pos_std_m.value_or(std::numeric_limits<double>::quiet_NaN())};
    start_t_s_ = g.t_s;
    past_.clear();
    past_.push_back(Past{g.t_s, Eigen::Vector3d::Zero(), 0.0,
                         params_.lever_arm_body_m
                             ? std::optional<Eigen::Vector3d>(att ? lever_arm_enu(*att) : Eigen::Vector3d::Zero())
                             : std::optional<Eigen::Vector3d>(Eigen::Vector3d::Zero())});
    last_t_s_ = g.t_s;
    last_count_ = *count;
    distance_m_ = 0.0;
    if (!params_.use_ins && g.vel_enu_mps.head<2>().norm() >= course_min_speed_at(g.t_s)) {
      held_heading_rad_ = gnss_course_rad(g.vel_enu_mps);
      held_direction_ = 0;  // the first interval's direction is taken as the one it was measured with
    }
    return Readiness::kReady;
  }
  return Readiness::kReady;
}

std::vector<DeadReckoningOutput> DeadReckoner::process_until(double watermark_s) {
  if (std::isnan(watermark_s)) throw std::invalid_argument("DeadReckoner::process_until: watermark is NaN");
  if (watermark_s > watermark_s_) watermark_s_ = watermark_s;
  std::vector<DeadReckoningOutput> out;
  // At most one output per pending odometer sample: one allocation instead of ~log2(n) regrowths
  // that each move every output so far (a one-hour 100 Hz run emits 360 000 at once).
  out.reserve(pending_odometer_t_s_.size());
  while (!pending_odometer_t_s_.empty() && pending_odometer_t_s_.front() <= watermark_s_) {
    const double t_j = pending_odometer_t_s_.front();
    if (!frame_) {
      // The start fix is the first valid one at or before t_j: all of them must be in.
      if (!gnss_complete_at(t_j)) break;
      if (try_start(t_j) == Readiness::kWait) break;
      if (!frame_) {
        ++counters_.odometer_samples;
        ++counters_.before_start;
        pending_odometer_t_s_.pop_front();
        odometer_.drop_before(t_j);
        attitude_.drop_before(t_j - params_.turn_slip_yaw_rate_window_s);
        continue;
      }
    }
    if (t_j <= last_t_s_) {  // at or before the start fix: nothing to integrate
      ++counters_.odometer_samples;
      ++counters_.before_start;
      pending_odometer_t_s_.pop_front();
      continue;
    }
    const double mid = 0.5 * (last_t_s_ + t_j);
    if (params_.use_ins) {
      if (attitude_.state_at(mid, watermark_s_) == BracketState::kPending) break;
      if (params_.lever_arm_body_m && attitude_.state_at(t_j, watermark_s_) == BracketState::kPending) break;
    }
    // Only the degraded mode steers by GNSS (course interpolated at mid-interval).
    if (!params_.use_ins && !gnss_final_at(t_j)) break;

    const OdometerBuffer::Entry* entry = nullptr;
    for (const auto& e : odometer_.entries()) {  // near the front: earlier samples are pruned
      if (e.t_s == t_j) {
        entry = &e;
        break;
      }
    }
    // Every pending stamp was added to the buffer with it and is dropped only after its step.
    if (entry == nullptr) throw std::logic_error("dead reckoning: a pending odometer stamp is missing from its buffer");
    out.push_back(step(*entry));
    pending_odometer_t_s_.pop_front();
    // What later intervals (starting at t_j) can still need: the attitude back to the slip's yaw-rate
    // window before their mid-interval.
    odometer_.drop_before(t_j);
    attitude_.drop_before(t_j - params_.turn_slip_yaw_rate_window_s);
    while (gnss_.size() >= 2 && gnss_[1].t_s <= t_j) pop_gnss_front();
    k_history_.drop_before(t_j);
    turn_slip_.drop_before(t_j);
    misalignment_.drop_before(t_j);
  }
  return out;
}

std::vector<DeadReckoningOutput> DeadReckoner::finish() {
  return process_until(std::numeric_limits<double>::infinity());
}

std::optional<Attitude> DeadReckoner::lever_arm_attitude_at(double t_s) const {
  if (params_.use_ins) return attitude_.attitude_at(t_s, watermark_s_);
  // The held course is the direction of motion: the body faces the other way when it was measured
  // reversing.
  if (held_heading_rad_) return Attitude{wrap_two_pi(*held_heading_rad_ + (held_direction_ < 0 ? kPi : 0.0)), 0.0, 0.0};
  return std::nullopt;
}

DeadReckoningOutput DeadReckoner::step(const OdometerBuffer::Entry& sample) {
  ++counters_.odometer_samples;
  ++counters_.outputs;
  DeadReckoningOutput o;
  o.t_s = sample.t_s;
  const double t_j = sample.t_s;
  const double mid = 0.5 * (last_t_s_ + t_j);
  const double count = static_cast<double>(sample.count);
  const double pulses = count - last_count_;  // >= 0: increments are modulo 2^32
  int direction = sample.direction;
  if (direction == 0) {
    ++counters_.unknown_direction;
    direction = 1;  // unknown is taken as forward, the common case; counted so it can be audited
  } else if (direction < 0) {
    ++counters_.reversing;
  }
  const KInForce k =
      k_history_.at_or_before(t_j).value_or(KInForce{params_.nominal_k_m_per_pulse, ScaleFactorSource::kNominal});
  o.k_m_per_pulse = k.k_m_per_pulse;
  o.k_source = k.source;
  const Misalignment mis = misalignment_.at_or_before(t_j).value_or(Misalignment{});
  // Held estimates: against the latest GNSS epoch whose estimates apply at t_j.
  while (!epochs_to_apply_s_.empty() &&
         estimate_applies_from_s(epochs_to_apply_s_.front(), params_.estimate_hold_off_s) <= t_j) {
    latest_applicable_epoch_s_ = epochs_to_apply_s_.front();
    epochs_to_apply_s_.pop_front();
  }
  o.k_held = held_[static_cast<int>(HeldEstimate::kScaleFactor)].decide(t_j, latest_applicable_epoch_s_,
                                                                        k.source == ScaleFactorSource::kCommanded);
  o.misalignment_held =
      held_[static_cast<int>(HeldEstimate::kMisalignment)].decide(t_j, latest_applicable_epoch_s_, false);
  if (o.k_held) ++counters_.outputs_on_held_k;
  if (o.misalignment_held) ++counters_.outputs_on_held_misalignment;
  o.turn_slip_fraction = turn_slip_fraction_at(t_j, mid);
  const double ds = k.k_m_per_pulse * pulses * direction / (1.0 + o.turn_slip_fraction);

  Eigen::Vector3d ds_n = Eigen::Vector3d::Zero();
  bool have_heading = true;
  if (params_.use_ins) {
    std::optional<Attitude> att = attitude_.attitude_at(mid, watermark_s_);
    if (att) {
      last_attitude_ = att;
    } else {
      o.heading_held = true;
      ++counters_.heading_held;
      att = last_attitude_;
    }
    if (att) {
      if (params_.mode == DeadReckoningMode::k3D) {
        ds_n = body_to_enu(*att) * odometer_to_body(mis) * Eigen::Vector3d(ds, 0.0, 0.0);
      } else {
        // heading is clockwise from north, a_h counter-clockwise: the odometer axis points at psi - a_h.
        const double psi = att->heading_rad - mis.heading_rad;
        ds_n = Eigen::Vector3d(ds * std::sin(psi), ds * std::cos(psi), 0.0);
      }
      o.heading_rad = wrap_two_pi(att->heading_rad);
    } else {
      have_heading = false;
    }
  } else {
    o.degraded = true;
    const std::optional<Eigen::Vector3d> v = gnss_velocity_at(mid);
    if (v && v->head<2>().norm() >= course_min_speed_at(mid)) {
      held_heading_rad_ = gnss_course_rad(*v);
      held_direction_ = direction;
    } else {
      o.heading_held = true;
      ++counters_.heading_held;
    }
    if (held_heading_rad_) {
      const double c = *held_heading_rad_;
      if (held_direction_ == 0) held_direction_ = direction;
      // Measured course: the direction of motion. Held across a change of direction: motion is
      // against the course it was measured with.
      const double along = held_direction_ == direction ? std::abs(ds) : -std::abs(ds);
      ds_n = Eigen::Vector3d(along * std::sin(c), along * std::cos(c), 0.0);
      o.heading_rad = c;
    } else {
      have_heading = false;
    }
  }
  if (!have_heading) ++counters_.distance_lost;
  if (std::abs(position_.lat_rad) >= kPolarCapLatRad && heading_position_offset_enu_m_) {
    // The heading is clockwise from north at the vehicle, and near a pole north depends on where
    // exactly that is: take it where GNSS last put the DR (a constant offset of the DR position, so
    // its error stays a GNSS error), and lay the step out in the DR position's own frame.
    const Geodetic heading_at = frame_->to_geodetic(frame_->to_enu(position_) + *heading_position_offset_enu_m_);
    ds_n = enu_rotation(heading_at, position_) * ds_n;
  }
  position_ = move_geodetic(position_, ds_n);
  distance_m_ += std::abs(ds);
  last_t_s_ = t_j;
  last_count_ = count;

  o.position = position_;
  o.enu_m = frame_->to_enu(position_);
  o.origin_to_local = frame_->rotation_to_local(position_);
  o.distance_m = distance_m_;
  if (start_fix_) {
    o.gnss_fixes.push_back(*start_fix_);
    ++counters_.anchor_fixes;
    start_fix_.reset();
  }
  std::optional<Eigen::Vector3d> lever_now = Eigen::Vector3d::Zero();
  if (params_.lever_arm_body_m) {
    const std::optional<Attitude> att_now = lever_arm_attitude_at(t_j);
    lever_now = att_now ? std::optional<Eigen::Vector3d>(lever_arm_enu(*att_now)) : std::nullopt;
  }
  past_.push_back(Past{t_j, o.enu_m, distance_m_, lever_now});
  evaluate_errors(o);
  if (last_error_ && t_j - last_error_->applies_s <= last_error_->carry_s &&
      std::isfinite(last_error_->horizontal_error_m)) {
    o.gnss_reference = true;
    o.error_t_s = last_error_->epoch_s;
    o.horizontal_error_m = last_error_->horizontal_error_m;
    o.error_percent_distance = last_error_->error_percent_distance;
  }
  return o;
}

void DeadReckoner::evaluate_errors(DeadReckoningOutput& o) {
  const double t_j = o.t_s;
  const double d = params_.estimate_hold_off_s;
  while (!error_epochs_.empty() && estimate_applies_from_s(error_epochs_.front().first.t_s, d) <= t_j) {
    const GnssSample g = error_epochs_.front().first;
    const double applies_s = estimate_applies_from_s(g.t_s, d);
    // The fix describes the position at its stamp minus the latency in force when it is evaluated.
    const double t_ref = g.t_s - gnss_latency_.at_or_before(applies_s).value_or(0.0);
    // A stamp that leads its measurement by more than the hold-off (a negative latency) waits until
    // the dead reckoning has reached the instant the fix describes; from then on its error applies.
    if (t_ref > t_j) break;
    EpochError e{g.t_s, std::max(applies_s, t_ref), std::numeric_limits<double>::quiet_NaN(),
                 std::numeric_limits<double>::quiet_NaN(), error_epochs_.front().second};
    error_epochs_.pop_front();
    // DR at t_ref: between the outputs bracketing it (none before the start, or beyond the last one).
    std::size_t hi = 0;
    while (hi < past_.size() && past_[hi].t_s < t_ref) ++hi;
    // The start epoch is the start fix itself: with a negative latency (stamps that lead the
    // measurement) its t_ref lies after the start, and it must not anchor a second time.
    const bool after_start = start_t_s_ && t_ref > *start_t_s_ && g.t_s > *start_t_s_;
    if (g.valid() && after_start && hi < past_.size() && (hi > 0 || past_[0].t_s == t_ref)) {
      // Everything interpolated, so that an epoch a few ulps off an odometer instant (a stamp that
      // crossed DDS) gives the same result to 1e-9.
      const Past& b = past_[hi];
      const Past& a = b.t_s == t_ref ? b : past_[hi - 1];
      const double f = b.t_s == t_ref ? 1.0 : (t_ref - a.t_s) / (b.t_s - a.t_s);
      if (!a.lever_arm_enu_m || !b.lever_arm_enu_m) {
        ++counters_.anchor_fixes_no_attitude;  // a lever arm without the attitude to turn it
      } else {
        const Eigen::Vector3d dr = a.enu_m + f * (b.enu_m - a.enu_m);
        const Eigen::Vector3d lever = *a.lever_arm_enu_m + f * (*b.lever_arm_enu_m - *a.lever_arm_enu_m);
        const double dist = a.distance_m + f * (b.distance_m - a.distance_m);
        // The lever arm is in the ENU frame at the fix (the attitude's north is the local one
        // there); near a pole, or kilometres from the origin, that frame is turned against the
        // origin's by the meridian convergence.
        const Eigen::Vector3d ref = frame_->to_enu(g.position) - frame_->rotation_from_local(g.position) * lever;
        e.horizontal_error_m = std::hypot(dr.x() - ref.x(), dr.y() - ref.y());
        if (dist >= params_.percent_min_distance_m && dist > 0.0)
          e.error_percent_distance = 100.0 * e.horizontal_error_m / dist;
        AnchorFix fix;
        fix.t_s = g.t_s;
        fix.fix_enu_m = ref;
        fix.dr_enu_m = dr;
        fix.dr_distance_m = dist;
        fix.sigma_m = g.pos_std_m.value_or(std::numeric_limits<double>::quiet_NaN());
        heading_position_offset_enu_m_ = ref - dr;
        o.gnss_fixes.push_back(fix);
        ++counters_.anchor_fixes;
      }
    }
    last_error_ = e;
  }
  // Later epochs apply after t_j, i.e. are stamped after t_j - d, and look at the DR up to the
  // latency before their stamp: the outputs before that (but the one bracketing it) are no longer
  // needed. A later epoch's latency may be one not added yet: the margin is the one in force now
  // and at least kLatencyKeepMarginS (the online estimate searches up to 0.5 s), the same whatever
  // was added beyond the watermark, so the pipeline keeps what odonav-offline keeps.
  const double next_applies_s =
      error_epochs_.empty() ? t_j : estimate_applies_from_s(error_epochs_.front().first.t_s, d);
  constexpr double kLatencyKeepMarginS = 1.0;
  const double latency_margin_s =
      std::max(kLatencyKeepMarginS, gnss_latency_.at_or_before(std::min(t_j, next_applies_s)).value_or(0.0));
  const double keep_from =
      (error_epochs_.empty() ? t_j - d : std::min(t_j - d, error_epochs_.front().first.t_s)) - latency_margin_s;
  while (past_.size() >= 2 && past_[1].t_s <= keep_from) past_.pop_front();
  gnss_latency_.drop_before(std::min(t_j, next_applies_s));
}

}  // namespace odonav::dead_reckoning
