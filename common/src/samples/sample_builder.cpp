#include "odonav/sample_builder.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "odonav/consumer_rules.hpp"

namespace odonav {

int fix_quality_rank(int fix) {
  switch (fix) {
    case 0:
    case 6: return 0;
    case 2:
    case 3:
    case 9: return 2;
    case 5: return 3;
    case 4: return 4;
    default: return 1;
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
    {EpochStatus::kCrossTrack, &SampleBuilderCounters::cross_track, "cross_track"},
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

double effective_max_interval_s(const SampleBuilderParams& params, double gnss_period_s) {
  if (params.max_interval_s > 0.0) return params.max_interval_s;
  if (!std::isfinite(gnss_period_s)) return params.max_interval_floor_s;
  return std::max(params.max_interval_floor_s, params.max_interval_periods * gnss_period_s);
}

namespace {
// A latency block needs this many samples for a residual variance of its own (its weight).
constexpr uint64_t kLatencyBlockMinSamples = 10;
// A block whose own latency estimate lies more than this many of its sigmas from the closed blocks'
// estimate is left out of the sums: one K does not describe it (the true K stepped inside it).
// Measured on terrain, seed 1, with 15 s blocks: the block holding the -2 % step put its minimum
// 90 ms off at a sigma of 8 ms (11 sigma) and pulled the estimate by +2.5 ms although it was
// weighted down by its larger residuals; the blocks without a step lay within 2 sigma.
constexpr double kLatencyBlockMaxSigmas = 5.0;

void require(bool ok, const char* what) {
  if (!ok) throw std::invalid_argument(std::string("SampleBuilderParams: ") + what);
}
}  // namespace

SampleBuilder::SampleBuilder(const SampleBuilderParams& p)
    : params_(p), odometer_(p.max_bracket_s, p.odometer_jump_gate), attitude_(p.max_bracket_s) {
  require(p.min_speed_mps >= 0.0, "min_speed_mps must be >= 0");
  require(p.min_pulses >= 0.0, "min_pulses must be >= 0");
  require(p.min_fix_rank >= 1 && p.min_fix_rank <= 4, "min_fix_rank must be in 1..4");
  require(p.max_interval_s >= 0.0, "max_interval_s must be > 0 (or 0: derived from the GNSS period)");
  require(p.max_interval_periods > 0.0 && p.max_interval_floor_s > 0.0,
          "max_interval_periods and max_interval_floor_s must be > 0");
  require(p.gnss_period_window >= 1, "gnss_period_window must be >= 1");
  require(p.max_yaw_rate_rad_s > 0.0, "max_yaw_rate_rad_s must be > 0");
  require(p.straight_yaw_rate_rad_s >= 0.0, "straight_yaw_rate_rad_s must be >= 0");
  require(p.max_acceleration_mps2 > 0.0 && p.speed_jump_margin_mps >= 0.0,
          "max_acceleration_mps2 must be > 0 and speed_jump_margin_mps >= 0");
  require(p.speed_jump_reference_max_age_s > 0.0, "speed_jump_reference_max_age_s must be > 0");
  require(p.cross_track_n_sigma > 0.0 && p.cross_track_angle_rad >= 0.0 && p.cross_track_angle_rad < 0.5 * kPi,
          "cross_track_n_sigma must be > 0 and cross_track_angle_rad in [0, pi/2)");
  require(p.innovation_n_sigma > 0.0, "innovation_n_sigma must be > 0");
  require(p.gnss_velocity_sigma_mps > 0.0, "gnss_velocity_sigma_mps must be > 0");
  require(p.innovation_k_change_fraction >= 0.0, "innovation_k_change_fraction must be >= 0");
  require(p.innovation_max_consecutive_rejections >= 0,
          "innovation_max_consecutive_rejections must be >= 1 (or 0: derived from the GNSS period)");
  require(p.innovation_suspend_after_s > 0.0, "innovation_suspend_after_s must be > 0");
  require(p.max_bracket_s > 0.0, "max_bracket_s must be > 0");
  require(!p.lever_arm_body_m || p.lever_arm_body_m->allFinite(), "lever_arm_body_m must be finite");
  require(p.lever_arm_rate_half_window_s > 0.0, "lever_arm_rate_half_window_s must be > 0");
  require(
      !p.gnss_latency_fixed_s || (std::isfinite(*p.gnss_latency_fixed_s) && std::abs(*p.gnss_latency_fixed_s) < 10.0),
      "gnss_latency_fixed_s must be finite and within +-10 s");
  require(p.latency_search_step_s > 0.0 &&
              p.latency_search_max_s >= p.latency_search_min_s + 2.0 * p.latency_search_step_s &&
              p.latency_search_min_s > -10.0 && p.latency_search_max_s < 10.0,
          "latency search range: step > 0, max >= min + 2 steps, within +-10 s");
  require(p.latency_apply_sigma_s > 0.0, "latency_apply_sigma_s must be > 0");
  require(p.pulse_rate_half_window_s > 0.0 && p.pulse_rate_half_window_s <= 1.0,
          "pulse_rate_half_window_s must be in (0, 1] s");
  require(p.trapezoid_correction_min_interval_s > 0.0, "trapezoid_correction_min_interval_s must be > 0");
  require(p.yaw_rate_step_s > 0.0, "yaw_rate_step_s must be > 0");
  require(p.latency_fit_half_width_s >= 2.0 * p.latency_search_step_s, "latency_fit_half_width_s must be >= 2 steps");
  require(p.latency_min_samples >= 1, "latency_min_samples must be >= 1");
  require(p.latency_refine_sigma_fraction > 0.0 && p.latency_refine_sigma_fraction < 1.0,
          "latency_refine_sigma_fraction must be in (0, 1)");
  require(std::isfinite(p.latency_min_sample_time_s) && p.latency_min_sample_time_s >= 0.0,
          "latency_min_sample_time_s must be >= 0");
  require(p.latency_block_s > 0.0, "latency_block_s must be > 0");
  require(std::isfinite(p.latency_prior_sigma_s) && p.latency_prior_sigma_s >= 0.0,
          "latency_prior_sigma_s must be finite and >= 0");
  if (p.gnss_latency_fixed_s) {
    latency_.fixed = true;
    latency_.applied_s = latency_.estimate_s = *p.gnss_latency_fixed_s;
    latency_.applied_sigma_s = 0.0;
    latency_.sigma_s = 0.0;
  } else if (p.latency_estimation_enabled) {
    const int n = static_cast<int>(
                      std::floor((p.latency_search_max_s - p.latency_search_min_s) / p.latency_search_step_s + 1e-9)) +
                  1;
    for (int i = 0; i < n; ++i) latency_candidates_s_.push_back(p.latency_search_min_s + i * p.latency_search_step_s);
    latency_closed_chi2_.assign(latency_candidates_s_.size(), 0.0);
    latency_block_yphi_.assign(latency_candidates_s_.size(), 0.0);
    latency_block_phiphi_.assign(latency_candidates_s_.size(), 0.0);
    latency_chi2_.assign(latency_candidates_s_.size(), 0.0);
    latency_.reason = "no accepted sample yet";
  } else {
    latency_.reason = "estimation disabled";
  }
}

std::optional<double> SampleBuilder::pulse_rate_at(double t_s) const {
  return pulse_rate_at(t_s, params_.pulse_rate_half_window_s);
}

std::optional<double> SampleBuilder::pulse_rate_at(double t_s, double h) const {
  const std::optional<double> before = odometer_.count_at(t_s - h, watermark_s_);
  const std::optional<double> after = odometer_.count_at(t_s + h, watermark_s_);
  if (!before || !after) return std::nullopt;
  return (*after - *before) / (2.0 * h);
}

int SampleBuilder::innovation_rejections_before_suspension() const {
  if (params_.innovation_max_consecutive_rejections > 0) return params_.innovation_max_consecutive_rejections;
  const double period = std::isfinite(gnss_period_s_) && gnss_period_s_ > 0.0 ? gnss_period_s_ : 0.1;
  return std::max(3, static_cast<int>(std::lround(params_.innovation_suspend_after_s / period)));
}

void SampleBuilder::observe_gnss_period(double t_s) {
  if (last_period_row_t_s_) {
    gnss_intervals_s_.push_back(t_s - *last_period_row_t_s_);
    if (gnss_intervals_s_.size() > static_cast<std::size_t>(params_.gnss_period_window)) gnss_intervals_s_.pop_front();
    std::vector<double> sorted(gnss_intervals_s_.begin(), gnss_intervals_s_.end());
    std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2), sorted.end());
    gnss_period_s_ = sorted[sorted.size() / 2];
  }
  last_period_row_t_s_ = t_s;
}

double SampleBuilder::earliest_sensor_offset_s() const {
  // The largest latency a query may subtract (for pruning).
  double m = latency_.applied_s;
  if (!latency_candidates_s_.empty()) m = std::max(m, latency_candidates_s_.back());
  return m;
}

void SampleBuilder::defer_latency_sample(double t0_s, double t1_s, double y_m) {
  if (latency_candidates_s_.empty()) return;
  // The smallest candidate looks furthest ahead: its pulse rate at t1 - candidate ends h later.
  const double needs_until_s = t1_s - latency_candidates_s_.front() + params_.pulse_rate_half_window_s;
  latency_pending_.push_back(PendingLatencySample{t0_s, t1_s, y_m, latency_.applied_s, needs_until_s});
}

void SampleBuilder::fold_latency_sample(const PendingLatencySample& s) {
  // Gated and projected at a latency the sums were restarted away from: it would pull them back.
  if (std::abs(s.applied_s - latency_sums_applied_s_) > params_.latency_restart_s) return;
  update_latency(s.t0_s, s.t1_s, s.y_m);
}

bool SampleBuilder::fit_latency(const std::vector<double>& sums, uint64_t samples, uint64_t fitted_k,
                                GnssLatencyEstimate& out, uint64_t min_samples) const {
  const std::size_t best = static_cast<std::size_t>(std::min_element(sums.begin(), sums.end()) - sums.begin());
  std::ostringstream why;
  // Below the minimum the sums are nearly flat and their smallest value jumps from candidate to
  // candidate with the last bits of the data: no estimate yet.
  if (samples < std::max<uint64_t>(3, min_samples)) {
    why << "too few samples (" << samples << " of " << min_samples << ")";
    out.reason = why.str();
    out.sigma_s = -1.0;
    return false;
  }
  if (best == 0 || best + 1 == sums.size()) {
    why << "the residuals are smallest at the bound " << latency_candidates_s_[best] << " s of the search range ["
        << latency_candidates_s_.front() << ", " << latency_candidates_s_.back() << "] s";
    out.reason = why.str();
    out.sigma_s = -1.0;
    return false;
  }
  // A least-squares parabola through the candidates within latency_fit_half_width_s of the
  // smallest sum: the sums wiggle from candidate to candidate (pulse quantisation differs with the
  // shift), so the three nearest points alone would follow the wiggles, not the minimum.
  const double half = params_.latency_fit_half_width_s;
  Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  int points = 0;
  for (std::size_t i = 0; i < sums.size(); ++i) {
    const double x = latency_candidates_s_[i] - latency_candidates_s_[best];
    if (std::abs(x) > half + 1e-12) continue;
    const Eigen::Vector3d basis(1.0, x, x * x);
    normal += basis * basis.transpose();
    rhs += basis * sums[i];
    ++points;
  }
  const Eigen::Vector3d c = points >= 5 ? Eigen::Vector3d(normal.ldlt().solve(rhs)) : Eigen::Vector3d::Zero();
  const double curvature = c[2];  // J ~ J_min + curvature (tau - tau^)^2
  if (points < 5 || !(curvature > 0.0)) {
    out.reason = "the residuals do not depend on the latency (no acceleration yet)";
    out.sigma_s = -1.0;
    return false;
  }
  const double vertex = -c[1] / (2.0 * curvature);
  if (std::abs(vertex) > half) {
    out.reason = "the fitted minimum lies outside the fitted range";
    out.sigma_s = -1.0;
    return false;
  }
  const double j_min = std::max(0.0, c[0] - curvature * vertex * vertex);
  // Degrees of freedom: one K per block and the latency itself.
  const double dof = std::max(1.0, static_cast<double>(samples) - static_cast<double>(fitted_k) - 1.0);
  const double sigma_y2 = j_min / dof;
  out.estimate_s = latency_candidates_s_[best] + vertex;
  out.sigma_s = std::sqrt(sigma_y2 / curvature);
  out.samples = samples;
  out.reason.clear();
  return true;
}

void SampleBuilder::restart_latency_sums() {
  std::fill(latency_closed_chi2_.begin(), latency_closed_chi2_.end(), 0.0);
  latency_closed_blocks_ = 0;
  latency_closed_samples_ = 0;
  latency_closed_fit_.reset();
  latency_closed_sigma_s_ = -1.0;
  latency_.blocks_left_out = 0;
  std::fill(latency_block_yphi_.begin(), latency_block_yphi_.end(), 0.0);
  std::fill(latency_block_phiphi_.begin(), latency_block_phiphi_.end(), 0.0);
  latency_block_yy_m2_ = 0.0;
  latency_block_samples_ = 0;
  latency_samples_ = 0;
}

bool SampleBuilder::weighted_block_residuals(std::vector<double>& out) const {
  // Too few samples for a residual variance of their own (the last block before a restart, the
  // first seconds of a block).
  if (latency_block_samples_ < kLatencyBlockMinSamples) return false;
  double j_min = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < out.size(); ++i) {
    const double yphi = latency_block_yphi_[i], phiphi = latency_block_phiphi_[i];
    out[i] = phiphi > 0.0 ? std::max(0.0, latency_block_yy_m2_ - yphi * yphi / phiphi) : latency_block_yy_m2_;
    j_min = std::min(j_min, out[i]);
  }
  if (!(j_min > 0.0)) return false;
  // Scaled to (samples - 1) at the block's best candidate: a sum of squared normalised residuals.
  const double w = static_cast<double>(latency_block_samples_ - 1) / j_min;
  for (double& v : out) v *= w;
  return true;
}

void SampleBuilder::fit_closed_blocks() {
  GnssLatencyEstimate closed;
  latency_closed_fit_.reset();
  latency_closed_sigma_s_ = -1.0;
  if (fit_latency(latency_closed_chi2_, latency_closed_samples_, latency_closed_blocks_, closed,
                  kLatencyBlockMinSamples)) {
    latency_closed_fit_ = closed.estimate_s;
    latency_closed_sigma_s_ = closed.sigma_s;
  }
}

bool SampleBuilder::block_consistent(const std::vector<double>& block) const {
  // The reference: the closed blocks' estimate, or right after a restart (no closed block yet) the
  // value just applied, which the samples before the restart determined. Without it the first block
  // after a restart was taken on its own, and one that one K cannot describe (the true K stepped
  // inside it) then excluded every later, correct block as inconsistent with it.
  double reference_s = 0.0, reference_sigma_s = 0.0;
  if (latency_closed_fit_) {
    reference_s = *latency_closed_fit_;
    reference_sigma_s = latency_closed_sigma_s_;
  } else if (latency_closed_blocks_ == 0 && latency_.applied_sigma_s > 0.0) {
    reference_s = latency_.applied_s;
    reference_sigma_s = latency_.applied_sigma_s;
  } else {
    return true;
  }
  // The block's own parabola (not its smallest candidate: the sums wiggle from candidate to
  // candidate by more than the latency's own signal over one block), against both sigmas: the
  // reference's alone is not small while it rests on one or two blocks.
  GnssLatencyEstimate own;
  if (!fit_latency(block, latency_block_samples_, 1, own, kLatencyBlockMinSamples)) return false;
  return std::abs(own.estimate_s - reference_s) <= kLatencyBlockMaxSigmas * std::hypot(own.sigma_s, reference_sigma_s);
}

std::optional<SampleBuilder::StartLatencyK> SampleBuilder::start_latency_k() const {
  const std::size_t n = latency_candidates_s_.size();
  if (n < 2 || latency_.applied_s != 0.0 || latency_restarts_ > 0 || latency_closed_blocks_ > 0 ||
      latency_.blocks_left_out > 0)
    return std::nullopt;
  std::vector<double> block(n);
  if (!weighted_block_residuals(block)) return std::nullopt;
  GnssLatencyEstimate own;
  if (!fit_latency(block, latency_block_samples_, 1, own, kLatencyBlockMinSamples)) return std::nullopt;
  if (!beats_nominal(own.estimate_s, latency_.applied_s, latency_sigma_factor_ * own.sigma_s)) return std::nullopt;
  // The block's K at its estimate, linear between the two candidates around it.
  const double x = (own.estimate_s - latency_candidates_s_.front()) / params_.latency_search_step_s;
  const std::size_t i = std::min(n - 2, static_cast<std::size_t>(std::max(0.0, std::floor(x))));
  const double f = std::clamp(x - static_cast<double>(i), 0.0, 1.0);
  if (!(latency_block_phiphi_[i] > 0.0) || !(latency_block_phiphi_[i + 1] > 0.0)) return std::nullopt;
  const double k0 = latency_block_yphi_[i] / latency_block_phiphi_[i];
  const double k1 = latency_block_yphi_[i + 1] / latency_block_phiphi_[i + 1];
  return StartLatencyK{k0 + f * (k1 - k0), own.estimate_s, own.sigma_s};
}

double SampleBuilder::latency_in_force_uncertainty_s(double sigma_factor) const {
  if (latency_.fixed || latency_candidates_s_.empty()) return 0.0;
  if (latency_.sigma_s >= 0.0)
    return std::hypot(latency_.estimate_s - latency_.applied_s, sigma_factor * latency_.sigma_s);
  // Sums restarted after an application: what was known when the value in force was applied.
  if (latency_.applied_sigma_s >= 0.0) return sigma_factor * latency_.applied_sigma_s;
  // No estimate over the sums yet: the open block's own (coarser) fit, as start_latency_k uses.
  std::vector<double> block(latency_candidates_s_.size());
  GnssLatencyEstimate own;
  if (weighted_block_residuals(block) && fit_latency(block, latency_block_samples_, 1, own, kLatencyBlockMinSamples))
    return std::hypot(own.estimate_s - latency_.applied_s, sigma_factor * own.sigma_s);
  return params_.latency_prior_sigma_s;
}

bool SampleBuilder::latency_decided() const {
  if (latency_.fixed || latency_candidates_s_.empty() || latency_.applied_sigma_s >= 0.0) return true;
  // Confirmed: a sigma the apply rule would act on, and the estimate does not beat the value in
  // force (beats_nominal, 3 sigma: the test a provisional estimate passes). Within 2 sigma the
  // estimate's own wandering at 1 Hz (sigma 5-10 ms) left drives unconverged at their end.
  return latency_.sigma_s >= 0.0 && latency_.sigma_s <= params_.latency_apply_coarse_sigma_s &&
         !beats_nominal(latency_.estimate_s, latency_.applied_s, latency_sigma_factor_ * latency_.sigma_s);
}

void SampleBuilder::update_latency(double t0_s, double t1_s, double y_m) {
  if (latency_candidates_s_.empty()) return;
  // Every candidate on the same samples: skip a sample for which one candidate has no count.
  // The candidates compare like with like: y is the trapezoid of the two GNSS speeds, so the pulses
  // are the trapezoid of the two pulse rates. Against the exact pulse count the trapezoid's own
  // error (T^3/12 times the speed's second derivative, which is large where an acceleration ends)
  // would correlate with the speed change and pull the estimate by milliseconds at 10 Hz.
  const std::size_t n = latency_candidates_s_.size();
  std::vector<double> phi(n);
  const double dt = t1_s - t0_s;
  for (std::size_t i = 0; i < n; ++i) {
    const std::optional<double> r0 = pulse_rate_at(t0_s - latency_candidates_s_[i]);
    const std::optional<double> r1 = pulse_rate_at(t1_s - latency_candidates_s_[i]);
    if (!r0 || !r1) return;
    phi[i] = 0.5 * dt * (*r0 + *r1);
  }
  // Each candidate fits its own K over a block: the residual sum of a block at candidate i is
  // sum y^2 - (sum y phi_i)^2 / sum phi_i^2. The K estimate lags a change of K for seconds, and its
  // error times the speed profile of those seconds pulled the latency; a K of the candidate's own
  // samples has no lag. A block is weighted by its own residual variance, so a block that one K
  // cannot describe (the true K stepped in it, a slipping stretch) counts little instead of a lot.
  std::vector<double> block(n);
  if (latency_block_samples_ > 0 && t1_s >= latency_block_start_s_ + params_.latency_block_s) {
    if (weighted_block_residuals(block)) {
      if (block_consistent(block)) {
        for (std::size_t i = 0; i < n; ++i) latency_closed_chi2_[i] += block[i];
        ++latency_closed_blocks_;
        latency_closed_samples_ += latency_block_samples_;
        fit_closed_blocks();
      } else {
        ++latency_.blocks_left_out;
      }
    }
    std::fill(latency_block_yphi_.begin(), latency_block_yphi_.end(), 0.0);
    std::fill(latency_block_phiphi_.begin(), latency_block_phiphi_.end(), 0.0);
    latency_block_yy_m2_ = 0.0;
    latency_block_samples_ = 0;
  }
  if (latency_block_samples_ == 0) latency_block_start_s_ = t1_s;
  latency_block_yy_m2_ += y_m * y_m;
  for (std::size_t i = 0; i < n; ++i) {
    latency_block_yphi_[i] += y_m * phi[i];
    latency_block_phiphi_[i] += phi[i] * phi[i];
  }
  ++latency_block_samples_;
  const bool open_block = weighted_block_residuals(block) && block_consistent(block);
  for (std::size_t i = 0; i < n; ++i) latency_chi2_[i] = latency_closed_chi2_[i] + (open_block ? block[i] : 0.0);
  latency_samples_ = latency_closed_samples_ + (open_block ? latency_block_samples_ : 0);
  const double applied_s = latency_.applied_s;
  const double applied_sigma_s = latency_.applied_sigma_s;
  latency_.samples = latency_samples_;
  const bool have = fit_latency(latency_chi2_, latency_samples_, latency_closed_blocks_ + (open_block ? 1 : 0),
                                latency_, latency_min_samples_in_force());
  latency_.applied_s = applied_s;
  latency_.applied_sigma_s = applied_sigma_s;
  if (!have) return;
  // Apply a precise estimate, or one that says the value in force is clearly wrong (a latency of
  // 100 ms spoils every sample long before the estimate is within a few ms).
  // Each change of the applied value moves K a little (0.1 % per 10 ms at 1 m/s^2 and 10 m/s), so a
  // change must be significant, not the estimate's own wandering.
  // The thresholds on sigma are precision requirements; whether a change is significant is judged
  // against the honest sigma (the residuals' serial correlation counted, set_latency_sigma_factor):
  // against the plain one a 1 Hz drive without latency had 40.8 ms applied at 5.2 plain sigmas.
  const double change_s = std::abs(latency_.estimate_s - applied_s);
  const double honest_sigma_s = latency_sigma_factor_ * latency_.sigma_s;
  const bool precise = latency_.sigma_s <= params_.latency_apply_sigma_s && change_s > honest_sigma_s;
  const bool clearly_off = latency_.sigma_s <= params_.latency_apply_coarse_sigma_s && change_s > 5.0 * honest_sigma_s;
  // Or one that knows the latency clearly better than the value in force did when it was applied:
  // at 1 Hz sigma ends near 5 ms and never meets the precise rule, so without this the first coarse
  // estimate (sigma 10-12 ms, up to 34 ms off on terrain) would stay in force for the whole drive.
  const bool refined = applied_sigma_s > 0.0 &&
                       latency_.sigma_s <= params_.latency_refine_sigma_fraction * applied_sigma_s &&
                       change_s > honest_sigma_s;
  if (!precise && !clearly_off && !refined) return;
  latency_.applied_s = latency_.estimate_s;
  latency_.applied_sigma_s = latency_.sigma_s;
  if (std::abs(latency_.applied_s - latency_sums_applied_s_) > params_.latency_restart_s) {
    // The samples summed so far were gated and projected at a latency far from the new one (the
    // innovation gate kept those that fitted it, which pulls the minimum towards it): start again.
    restart_latency_sums();
    latency_sums_applied_s_ = latency_.applied_s;
    ++latency_restarts_;
  }
}

OdometerAddResult SampleBuilder::add_odometer(const OdometerSample& sample) {
  const OdometerAddResult result = odometer_.add(sample);
  counters_.odometer_jumps_rejected = odometer_.jumps_rejected();
  counters_.odometer_rebases = odometer_.rebases();
  return result;
}

void SampleBuilder::add_gnss(const GnssSample& sample) { queue_gnss_sample(sample, last_gnss_t_s_, pending_gnss_); }

void SampleBuilder::add_ins(const InsSample& sample) {
  if (params_.use_ins) attitude_.add(sample);
}

void SampleBuilder::add_misalignment(double t_s, const Misalignment& m) {
  add_misalignment_estimate(misalignment_, t_s, m);
}

void SampleBuilder::add_scale_factor_estimate(double t_s, double k, double sigma) {
  if (!std::isfinite(k) || !(k > 0.0) || !std::isfinite(sigma) || sigma < 0.0) {
    std::ostringstream s;
    s << "scale_factor_estimate: at t=" << t_s << " s, K=" << k << " m/pulse must be finite and > 0 and sigma=" << sigma
      << " finite and >= 0";
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
    // Wait until the epoch's odometer count and attitude are final (see stream_buffers.hpp) at its
    // sensor time: nothing after it is needed (the windows look backward). Before the epoch, the
    // deferred latency samples whose look-ahead this epoch's data covers enter the latency sums, one
    // at a time and in order: a latency decided from them applies from this epoch on. The order of
    // these steps depends on the stamps only, so any chunking of the calls gives the same result.
    bool ready = true;
    for (;;) {
      const double needed = sensor_time(t);
      if (odometer_.state_at(needed, watermark_s_) == BracketState::kPending ||
          (params_.use_ins && attitude_.state_at(needed, watermark_s_) == BracketState::kPending)) {
        ready = false;
        break;
      }
      if (latency_pending_.empty() || latency_pending_.front().needs_until_s > needed) break;
      fold_latency_sample(latency_pending_.front());
      latency_pending_.pop_front();
    }
    if (!ready) break;
    out.push_back(process_epoch(pending_gnss_.front()));
    pending_gnss_.pop_front();
    // Everything before this epoch's earliest sensor time is no longer needed: the next interval
    // starts here.
    // The deferred latency samples still need their own interval at every candidate.
    const double oldest = latency_pending_.empty() ? t : std::min(t, latency_pending_.front().t0_s);
    // The trapezoid correction's rate windows reach back 2h before an interval's start, h at most a
    // quarter of the longest interval (trapezoid_rate_half_window_s).
    const double rate_h = std::max(params_.pulse_rate_half_window_s, 0.25 * max_interval_in_force_s());
    const double earliest = oldest - std::max(0.0, earliest_sensor_offset_s()) - 2.0 * rate_h;
    odometer_.drop_before(earliest);
    // Keep the INS window [t - h, ...] for the next epoch's body rate (lever arm).
    attitude_.drop_before(compensates_lever_arm() ? earliest - params_.lever_arm_rate_half_window_s : earliest);
    misalignment_.drop_before(t);
    k_estimates_.drop_before(t);
    if (on_epoch) on_epoch(out.back());
  }
  return out;
}

std::vector<SampleBuilderEpoch> SampleBuilder::finish(const EpochCallback& on_epoch) {
  std::vector<SampleBuilderEpoch> out = process_until(std::numeric_limits<double>::infinity(), on_epoch);
  // End of data: the samples still deferred enter the sums with what there is (the latency they
  // decide applies to no epoch any more, it is only reported).
  while (!latency_pending_.empty()) {
    fold_latency_sample(latency_pending_.front());
    latency_pending_.pop_front();
  }
  return out;
}

bool SampleBuilder::compensates_lever_arm() const { return params_.use_ins && params_.lever_arm_body_m.has_value(); }

Eigen::Vector3d SampleBuilder::reference_point_velocity(const GnssSample& g, const Attitude& att) const {
  if (!compensates_lever_arm()) return g.vel_enu_mps;
  // The rate over [t - h, t], the window that ends at the epoch: nothing after the epoch is needed,
  // so its sample leaves when the epoch's own data is in. Its lag (h / 2) is measured in
  // docs/DESIGN_DECISIONS.md against the centred window it replaced.
  const double h = params_.lever_arm_rate_half_window_s;
  const double t = sensor_time(g.t_s);
  const std::optional<Attitude> before = attitude_.attitude_at(t - h, watermark_s_);
  if (!before) return g.vel_enu_mps;  // no rate: leave uncompensated (isolated INS sample)
  const Attitude& after = att;
  const double window_s = h;
  const Eigen::Vector3d omega_b = body_rate_rad_s(*before, att, after, window_s);
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

  const double t_sensor = sensor_time(g.t_s);
  const std::optional<double> count_now = odometer_.count_at(t_sensor, watermark_s_);
  if (!count_now) return EpochStatus::kNoOdometer;
  Attitude att;
  if (params_.use_ins) {
    const std::optional<Attitude> a = attitude_.attitude_at(t_sensor, watermark_s_);
    if (!a) return EpochStatus::kNoAttitude;
    att = *a;
  }
  in.misalignment = misalignment_.at_or_before(g.t_s).value_or(Misalignment{});
  const Eigen::Vector3d vel_enu_mps = reference_point_velocity(g, att);
  const double v = forward_speed(vel_enu_mps, att, in.misalignment);
  in.forward_speed_mps = v;
  // Backwards is a good velocity while the odometer says so (reversing samples).
  if (v < 0.0 && !(params_.reversing_samples && odometer_.direction_at(t_sensor) == OdometerDirection::kReversing))
    return EpochStatus::kNegativeSpeed;
  if (params_.use_ins && params_.cross_track_gate_enabled) {
    const Eigen::Vector3d v_odo = odometer_to_body(in.misalignment).transpose() * (enu_to_body(att) * vel_enu_mps);
    const double sigma_v = g.vel_std_mps && *g.vel_std_mps > 0.0 ? *g.vel_std_mps : params_.gnss_velocity_sigma_mps;
    const double bound = params_.cross_track_n_sigma * sigma_v + std::tan(params_.cross_track_angle_rad) * std::abs(v);
    if (std::hypot(v_odo.y(), v_odo.z()) > bound) return EpochStatus::kCrossTrack;
  }

  // Speed jump against the last epoch whose velocity was judged good (if recent enough).
  if (last_good_speed_) {
    const double dt = g.t_s - last_good_speed_->first;
    if (dt <= std::max(params_.speed_jump_reference_max_age_s, max_interval_in_force_s()) &&
        std::abs(v - last_good_speed_->second) > params_.max_acceleration_mps2 * dt + params_.speed_jump_margin_mps)
      return EpochStatus::kSpeedJump;
  }
  in.epoch = GoodEpoch{g.t_s, vel_enu_mps, att, *count_now};
  return std::nullopt;
}

uint64_t SampleBuilder::latency_min_samples_in_force() const {
  // The period is observed before any sample exists (it needs two GNSS rows; a sample needs two good
  // epochs), so the count follows the receiver's rate from the first sample on.
  const double period = std::isfinite(gnss_period_s_) && gnss_period_s_ > 0.0 ? gnss_period_s_ : 0.1;
  const double by_time = std::ceil(params_.latency_min_sample_time_s / period - 1e-9);
  return static_cast<uint64_t>(std::max<double>(params_.latency_min_samples, by_time));
}

double trapezoid_rate_half_window_s(const SampleBuilderParams& p, double k_m_per_pulse, double sigma_v_mps,
                                    double interval_s) {
  // A count is off by a uniform fraction of a pulse (variance 1/12), so the rate over +-h carries
  // sqrt(2/12) / (2h) pulses/s, |K| times that in m/s. Where that is a sizeable share of the GNSS
  // velocity noise (terrain: 0.0125 m/pulse, 0.05 m/s: 0.05 m/s at h = 0.05 s, as much as the
  // noise the correction sits on), widen h until it is a quarter of it; never beyond a quarter of
  // the interval, so the correction still reads the interval's own shape.
  const double wanted = std::abs(k_m_per_pulse) * std::sqrt(2.0 / 12.0) / (2.0 * 0.25 * sigma_v_mps);
  const double widest = std::max(p.pulse_rate_half_window_s, 0.25 * interval_s);
  return std::isfinite(wanted) ? std::clamp(wanted, p.pulse_rate_half_window_s, widest) : widest;
}

EpochStatus SampleBuilder::check_interval(const GnssSample& g, const EpochInputs& in, ScaleFactorSample& sample,
                                          double& speed_trapezoid_m, TurnSlipSample* turn) const {
  GoodEpoch s = *chain_start_;
  // Both ends at the latency in force now: the start's count and attitude again at its sensor
  // time, so a latency applied since the start cannot make the two ends inconsistent.
  const double start_sensor_t = sensor_time(s.t_s);
  if (const std::optional<double> n = odometer_.count_at(start_sensor_t, watermark_s_)) s.count_pulses = *n;
  if (params_.use_ins)
    if (const std::optional<Attitude> a = attitude_.attitude_at(start_sensor_t, watermark_s_)) s.attitude = *a;
  const double dt = g.t_s - s.t_s;
  const OdometerDirection direction = odometer_.direction_over(start_sensor_t, sensor_time(g.t_s));
  const bool backwards = direction == OdometerDirection::kReversing && params_.reversing_samples;
  // Speeds along the direction of travel: with INS the forward speed is negative backwards.
  const double sign = backwards && params_.use_ins ? -1.0 : 1.0;
  const double v = sign * in.forward_speed_mps;
  // Both ends with the same (latest) misalignment, so the sample is one consistent projection.
  const double v_start = sign * forward_speed(s.vel_enu_mps, s.attitude, in.misalignment);
  double yaw_rate = 0.0;
  if (params_.use_ins) {
    yaw_rate = wrap_pi(in.epoch.attitude.heading_rad - s.attitude.heading_rad) / dt;
    // Over a long interval (1 Hz GNSS) the mean hides the turn in it: take the largest rate over
    // steps of yaw_rate_step_s, so the gate means the same at every GNSS rate.
    // The margin keeps an interval of exactly one step (up to the rounding of its stamps) one step.
    const int steps = static_cast<int>(std::ceil(dt / params_.yaw_rate_step_s - 1e-6));
    if (steps > 1) {
      const double step_s = dt / steps;
      std::optional<Attitude> previous = s.attitude;
      for (int i = 1; i <= steps; ++i) {
        const std::optional<Attitude> now = i == steps
                                                ? std::optional<Attitude>(in.epoch.attitude)
                                                : attitude_.attitude_at(start_sensor_t + i * step_s, watermark_s_);
        if (!now) continue;  // no INS inside a gap: the mean over the interval still stands
        const double rate = wrap_pi(now->heading_rad - previous->heading_rad) / step_s;
        if (std::abs(rate) > std::abs(yaw_rate)) yaw_rate = rate;
        previous = now;
      }
    }
  } else {
    yaw_rate = wrap_pi(gnss_course_rad(g.vel_enu_mps) - gnss_course_rad(s.vel_enu_mps)) / dt;
  }
  const double phi = in.epoch.count_pulses - s.count_pulses;
  if (dt > max_interval_in_force_s()) return EpochStatus::kGap;
  if (v_start < params_.min_speed_mps || v < params_.min_speed_mps) return EpochStatus::kMinSpeed;
  if (direction != OdometerDirection::kForward && !backwards) return EpochStatus::kReversing;
  // A turn is kept out of K, but (with INS and a K estimate to compare with) measures the slip.
  const bool turning = params_.yaw_rate_gate_enabled && std::abs(yaw_rate) > params_.max_yaw_rate_rad_s;
  const std::optional<KEstimate> k_before = k_estimates_.before(g.t_s);
  if (turning && !(turn != nullptr && params_.use_ins && k_before && phi >= params_.min_pulses))
    return EpochStatus::kYawRate;
  if (!(phi > 0.0)) return EpochStatus::kNoPulses;
  if (phi < params_.min_pulses) return EpochStatus::kMinSpeed;
  sample.t_s = g.t_s;
  sample.phi_pulses = phi;
  sample.dt_s = dt;
  sample.y_m = 0.5 * (v_start + v) * dt;
  sample.speed_change_mps = v - v_start;
  speed_trapezoid_m = sample.y_m;
  if (dt >= params_.trapezoid_correction_min_interval_s) {
    // Long intervals: the trapezoid of the two speeds misses the speed's curvature in between
    // (T^3/12 v'', centimetres at 1 Hz where an acceleration ends). The odometer sees that shape:
    // add K^ times the pulses the same trapezoid misses (K^: the latest estimate, else nominal).
    // The shape is read over the interval shifted back by h, where the pulse rates' windows
    // [t - 2h, t] end at the epochs: the sample needs no odometer after its epoch. The curvature
    // moves little in h (0.05 s against a 1 s interval).
    const std::optional<KEstimate> k = k_estimates_.before(g.t_s);
    const double k_m = k ? k->k_m_per_pulse : params_.odometer_jump_gate.k_m_per_pulse;
    const double sigma_v = g.vel_std_mps && *g.vel_std_mps > 0.0 ? *g.vel_std_mps : params_.gnss_velocity_sigma_mps;
    const double h = trapezoid_rate_half_window_s(params_, k_m, sigma_v, dt);
    const double end_sensor_t = sensor_time(g.t_s);
    const std::optional<double> n0 = odometer_.count_at(start_sensor_t - h, watermark_s_);
    const std::optional<double> n1 = odometer_.count_at(end_sensor_t - h, watermark_s_);
    const std::optional<double> r0 = pulse_rate_at(start_sensor_t - h, h);
    const std::optional<double> r1 = pulse_rate_at(end_sensor_t - h, h);
    if (n0 && n1 && r0 && r1) {
      sample.y_m += k_m * ((*n1 - *n0) - 0.5 * dt * (*r0 + *r1));
    }
  }
  sample.gnss_position_enu_m = frame_->to_enu(g.position);
  sample.straight = std::abs(yaw_rate) < params_.straight_yaw_rate_rad_s;
  if (turning) {
    const std::optional<double> x = turn_pulses_radps(start_sensor_t, sensor_time(g.t_s), s);
    if (!x) return EpochStatus::kYawRate;
    const double sigma_v = g.vel_std_mps && *g.vel_std_mps > 0.0 ? *g.vel_std_mps : params_.gnss_velocity_sigma_mps;
    turn->t_s = g.t_s;
    turn->dt_s = dt;
    turn->phi_pulses = phi;
    turn->y_m = sample.y_m;
    turn->turn_pulses_radps = *x;
    turn->k_m_per_pulse = k_before->k_m_per_pulse;
    turn->sigma_y_m = std::sqrt(regression_noise_variance_m2(sigma_v, dt, k_before->k_m_per_pulse));
    return EpochStatus::kYawRate;
  }
  return EpochStatus::kAccepted;
}

std::optional<double> SampleBuilder::turn_pulses_radps(double start_sensor_t, double end_sensor_t,
                                                       const GoodEpoch& start) const {
  // Steps of yaw_rate_step_s, as the gate's rate: X = sum of each step's pulses times its rate
  // beyond the threshold (turn_slip.hpp). No INS or count inside the interval: no sample.
  const double dt = end_sensor_t - start_sensor_t;
  const int steps = std::max(1, static_cast<int>(std::ceil(dt / params_.yaw_rate_step_s - 1e-6)));
  const double step_s = dt / steps;
  double heading0 = start.attitude.heading_rad;
  double count0 = start.count_pulses;
  double x = 0.0;
  for (int i = 1; i <= steps; ++i) {
    const double t = start_sensor_t + i * step_s;
    const std::optional<Attitude> a = attitude_.attitude_at(t, watermark_s_);
    const std::optional<double> n = odometer_.count_at(t, watermark_s_);
    if (!a || !n) return std::nullopt;
    const double rate = wrap_pi(a->heading_rad - heading0) / step_s;
    x += (*n - count0) * std::max(0.0, std::abs(rate) - params_.max_yaw_rate_rad_s);
    heading0 = a->heading_rad;
    count0 = *n;
  }
  return x;
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
  if (consecutive_innovation_rejections_ < innovation_rejections_before_suspension()) {
    ++consecutive_innovation_rejections_;
    return InnovationVerdict::kOutlier;
  }
  return InnovationVerdict::kSuspended;
}

SampleBuilderEpoch SampleBuilder::process_epoch(const GnssSample& g) {
  ++counters_.epochs;
  observe_gnss_period(g.t_s);
  SampleBuilderEpoch r;
  r.t_s = g.t_s;
  r.latency = latency_;
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
  std::optional<double> latency_start_t_s;
  double speed_trapezoid_m = 0.0;
  if (!chain_start_) {
    r.status = EpochStatus::kChainStart;
  } else {
    ScaleFactorSample sample;
    TurnSlipSample turn;
    turn.dt_s = -1.0;  // filled (dt > 0) only for a turn that measures the slip
    r.status = check_interval(g, in, sample, speed_trapezoid_m, &turn);
    if (r.status == EpochStatus::kYawRate && turn.dt_s > 0.0) r.turn_sample = turn;
    if (r.status == EpochStatus::kAccepted) {
      switch (innovation_gate(g, sample)) {
        case InnovationVerdict::kPassed:
          r.sample = sample;
          latency_start_t_s = chain_start_->t_s;
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
  if (r.status == EpochStatus::kAccepted && params_.reversing_samples &&
      odometer_.direction_over(sensor_time(chain_start_->t_s), sensor_time(g.t_s)) == OdometerDirection::kReversing)
    ++counters_.reversing_accepted;
  // The latency candidates learn from samples that passed against a K estimate (a suspended test
  // means the estimate is stale, and without one there is nothing to compare with).
  if (latency_start_t_s) {
    // Only once the innovation gate tests against a precise K: before it, a velocity outlier that
    // the other gates let through would enter the sums. The sums fit their own K (update_latency).
    // They take y without the trapezoid correction (1 Hz): the correction reads the pulse profile at
    // the latency in force, so against the candidates' trapezoids of pulse rates it would put the
    // speed's curvature, which follows the accelerations, into every candidate but the one in force.
    const std::optional<KEstimate> k = k_estimates_.before(g.t_s);
    if (k && k->sigma_m_per_pulse <= params_.latency_max_k_rel_sigma * k->k_m_per_pulse)
      defer_latency_sample(*latency_start_t_s, g.t_s, speed_trapezoid_m);
  }
  if (velocity_good) {
    chain_start_ = in.epoch;
    last_good_speed_ = std::make_pair(g.t_s, in.forward_speed_mps);
  } else {
    chain_start_.reset();
  }
  return r;
}

}  // namespace odonav
