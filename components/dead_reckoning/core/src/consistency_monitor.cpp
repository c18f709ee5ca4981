#include "odonav/dead_reckoning/consistency_monitor.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "odonav/frames.hpp"
#include "odonav/printf_text.hpp"

namespace odonav::dead_reckoning {

namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// Degrees per radian: an INS heading in radians read as degrees turns this many times too little.
constexpr double kRadiansFactor = 180.0 / kPi;
}  // namespace

const char* to_string(ConsistencyCheck check) {
  switch (check) {
    case ConsistencyCheck::kHeadingRate: return "heading_rate";
    case ConsistencyCheck::kDriftGrowth: return "drift_growth";
    case ConsistencyCheck::kOdometerSpeed: return "odometer_speed";
  }
  return "unknown";
}

std::optional<std::string> heading_rate_finding(double ratio, double turned_rad, double tolerance) {
  if (!std::isfinite(ratio) || std::abs(ratio - 1.0) <= tolerance) return std::nullopt;
  const double turned_deg = rad_to_deg(turned_rad);
  if (ratio < 0.0)
    return printf_text(
        "INS heading turns opposite to the GNSS course (ratio %.2f over %.0f deg of turns): heading "
        "sign convention?",
        ratio, turned_deg);
  if (ratio > 0.0 && std::abs(1.0 / ratio - kRadiansFactor) <= 0.25 * kRadiansFactor)
    return printf_text("INS heading moves %.0f times less than the GNSS course (over %.0f deg of turns): radians?",
                       1.0 / ratio, turned_deg);
  return printf_text(
      "INS heading moves %.2f times as much as the GNSS course (over %.0f deg of turns): heading unit "
      "or another heading signal?",
      ratio, turned_deg);
}

std::optional<std::string> drift_growth_finding(double growth_percent, double allowed_percent, double floor_percent) {
  const double limit = std::max(allowed_percent, floor_percent);
  if (!std::isfinite(growth_percent) || growth_percent <= limit) return std::nullopt;
  return printf_text(
      "dead reckoning drifts from valid GNSS at %.1f %%D while K and the misalignment say converged "
      "(%.1f %%D allowed): heading or odometer input wrong?",
      growth_percent, limit);
}

std::optional<std::string> odometer_speed_finding(double ratio, double tolerance) {
  if (!std::isfinite(ratio) || std::abs(ratio - 1.0) <= tolerance) return std::nullopt;
  return printf_text(
      "the odometer distance is %.3f times the GNSS distance with the K in force: the nominal K, the "
      "pulse counter's unit or the GNSS speed?",
      ratio);
}

ConsistencyMonitor::ConsistencyMonitor(const ConsistencyParams& p) : params_(p) {
  const std::pair<const char*, double> positive[] = {{"min_speed_mps", p.min_speed_mps},
                                                     {"rate_interval_s", p.rate_interval_s},
                                                     {"max_rate_radps", p.max_rate_radps},
                                                     {"window_s", p.window_s},
                                                     {"min_interval_turn_rad", p.min_interval_turn_rad},
                                                     {"min_intervals", p.min_intervals},
                                                     {"spike_turn_rad", p.spike_turn_rad},
                                                     {"min_turn_rad", p.min_turn_rad},
                                                     {"rate_ratio_tolerance", p.rate_ratio_tolerance},
                                                     {"growth_window_m", p.growth_window_m},
                                                     {"growth_floor_percent", p.growth_floor_percent},
                                                     {"sigma_factor", p.sigma_factor},
                                                     {"gnss_position_sigma_m", p.gnss_position_sigma_m},
                                                     {"speed_ratio_tolerance", p.speed_ratio_tolerance},
                                                     {"persist_s", p.persist_s},
                                                     {"jump_speed_mps", p.jump_speed_mps},
                                                     {"jump_margin_m", p.jump_margin_m},
                                                     {"jump_max_consecutive", p.jump_max_consecutive}};
  for (const auto& [name, v] : positive)
    if (!(std::isfinite(v) && v > 0.0))
      throw std::invalid_argument(std::string("consistency monitor: ") + name + " must be finite and > 0");
  for (int c = 0; c < kConsistencyChecks; ++c) {
    disagree_since_s_[c] = kNaN;
    states_[c].last_value = kNaN;
  }
}

void ConsistencyMonitor::count_jump(const GnssSample& g) {
  if (!last_accepted_fix_) {
    last_accepted_fix_ = g;
    return;
  }
  // Great-circle distance on the mean Earth radius: metres of accuracy at the kilometres a jump is.
  const GnssSample& a = *last_accepted_fix_;
  const double dlat = g.position.lat_rad - a.position.lat_rad;
  const double dlon = g.position.lon_rad - a.position.lon_rad;
  const double h = std::sin(dlat / 2) * std::sin(dlat / 2) + std::cos(a.position.lat_rad) *
                                                                 std::cos(g.position.lat_rad) * std::sin(dlon / 2) *
                                                                 std::sin(dlon / 2);
  const double distance_m = 2.0 * 6371008.8 * std::asin(std::min(1.0, std::sqrt(h)));
  const double allowed_m = params_.jump_speed_mps * std::abs(g.t_s - a.t_s) + params_.jump_margin_m;
  if (!(distance_m > allowed_m)) {
    last_accepted_fix_ = g;
    consecutive_jumps_ = 0;
    return;
  }
  if (++consecutive_jumps_ >= params_.jump_max_consecutive) {  // elsewhere for good: follow it
    last_accepted_fix_ = g;
    consecutive_jumps_ = 0;
    ++jumps_.relocations;
    return;
  }
  if (jumps_.jumps == 0) jumps_.first_t_s = g.t_s;
  ++jumps_.jumps;
  jumps_.largest_m = std::max(jumps_.largest_m, distance_m);
}

void ConsistencyMonitor::add_gnss(const GnssSample& g) {
  if (g.valid() && std::isfinite(g.position.lat_rad) && std::isfinite(g.position.lon_rad)) count_jump(g);
  if (!g.valid() || !g.vel_enu_mps.allFinite()) {
    last_gnss_.reset();
    return;
  }
  const double speed = g.vel_enu_mps.head<2>().norm();
  // GNSS distance: the trapezoid of the speeds between consecutive valid epochs; an invalid epoch or
  // a gap starts a new segment (distances compare within one).
  if (last_gnss_ && g.t_s > last_gnss_->t_s && g.t_s - last_gnss_->t_s <= 2.0 * params_.rate_interval_s)
    gnss_distance_m_ += 0.5 * (speed + last_gnss_->vel_enu_mps.head<2>().norm()) * (g.t_s - last_gnss_->t_s);
  else
    ++gnss_segment_;
  last_gnss_ = g;
  const double course = speed >= params_.min_speed_mps ? std::atan2(g.vel_enu_mps.x(), g.vel_enu_mps.y()) : kNaN;
  epochs_.push_back({g.t_s, course, gnss_distance_m_, gnss_segment_});
  // Outputs reach every epoch within the hold-off; never more than a few seconds of epochs wait.
  while (epochs_.size() > 200) epochs_.pop_front();
}

void ConsistencyMonitor::set_scale_factor(double k, double sigma, bool converged) {
  k_m_per_pulse_ = k;
  k_sigma_rel_ = std::isfinite(k) && k > 0.0 && std::isfinite(sigma) && sigma > 0.0 ? sigma / k : -1.0;
  k_converged_ = converged;
}

void ConsistencyMonitor::set_misalignment(double heading_std_rad, bool converged) {
  heading_std_rad_ = std::isfinite(heading_std_rad) && heading_std_rad > 0.0 ? heading_std_rad : -1.0;
  misalignment_converged_ = converged;
}

void ConsistencyMonitor::on_output(const DeadReckoningOutput& o) {
  while (!epochs_.empty() && epochs_.front().t_s <= o.t_s) {
    const Epoch e = epochs_.front();
    epochs_.pop_front();
    if (o.t_s - e.t_s > 0.5 * params_.rate_interval_s) continue;  // no output near it (a gap)
    add_pair({e.t_s, e.course_rad, o.degraded ? kNaN : o.heading_rad, e.gnss_distance_m, o.distance_m, e.segment});
  }
  for (const AnchorFix& f : o.gnss_fixes) add_fix(f);
}

void ConsistencyMonitor::add_pair(const Pair& p) {
  // Heading rate: changes over rate_interval_s between moving epochs.
  if (std::isfinite(p.course_rad) && std::isfinite(p.heading_rad)) {
    if (!anchor_ || p.t_s - anchor_->t_s > 3.0 * params_.rate_interval_s) {
      anchor_ = p;
    } else if (p.t_s - anchor_->t_s >= params_.rate_interval_s) {
      const double dt = p.t_s - anchor_->t_s;
      const double dchi = wrap_pi(p.course_rad - anchor_->course_rad);
      const double dpsi = wrap_pi(p.heading_rad - anchor_->heading_rad);
      // A course that jumps and comes back over two adjacent intervals: an outlier epoch between them.
      const bool spike = !changes_.empty() && changes_.back().t_s == anchor_->t_s &&
                         std::abs(changes_.back().dchi_rad) >= params_.spike_turn_rad &&
                         std::abs(dchi) >= params_.spike_turn_rad && changes_.back().dchi_rad * dchi < 0.0 &&
                         std::abs(changes_.back().dchi_rad + dchi) <=
                             0.5 * std::min(std::abs(changes_.back().dchi_rad), std::abs(dchi));
      if (spike)
        changes_.pop_back();
      else if (std::abs(dchi) >= params_.min_interval_turn_rad && std::abs(dchi) <= params_.max_rate_radps * dt)
        changes_.push_back({p.t_s, dpsi / dchi, dchi});
      anchor_ = p;
    }
  } else {
    anchor_.reset();
  }
  while (!changes_.empty() && changes_.front().t_s < p.t_s - params_.window_s) changes_.pop_front();
  double turned = 0.0;
  for (const Change& c : changes_) turned += std::abs(c.dchi_rad);
  if (turned >= params_.min_turn_rad && static_cast<double>(changes_.size()) >= params_.min_intervals) {
    std::vector<double> ratios;
    ratios.reserve(changes_.size());
    for (const Change& c : changes_) ratios.push_back(c.ratio);
    const auto mid = ratios.begin() + static_cast<std::ptrdiff_t>(ratios.size() / 2);
    std::nth_element(ratios.begin(), mid, ratios.end());
    const double ratio = *mid;
    evidence(ConsistencyCheck::kHeadingRate, p.t_s, heading_rate_finding(ratio, turned, params_.rate_ratio_tolerance),
             ratio);
  }

  // Odometer speed: distances over the last growth_window_m of GNSS distance.
  if (!speed_pairs_.empty() &&
      (p.segment != speed_pairs_.back().segment || p.odometer_distance_m < speed_pairs_.back().odometer_distance_m))
    speed_pairs_.clear();  // a GNSS gap: the GNSS distance compares from here
  speed_pairs_.push_back(p);
  while (speed_pairs_.size() >= 2 && p.gnss_distance_m - speed_pairs_[1].gnss_distance_m >= params_.growth_window_m)
    speed_pairs_.pop_front();
  const Pair& first = speed_pairs_.front();
  const double gnss_m = p.gnss_distance_m - first.gnss_distance_m;
  if (gnss_m >= params_.growth_window_m && p.t_s - first.t_s <= 10.0 * params_.window_s) {
    const double ratio = (p.odometer_distance_m - first.odometer_distance_m) / gnss_m;
    evidence(ConsistencyCheck::kOdometerSpeed, p.t_s, odometer_speed_finding(ratio, params_.speed_ratio_tolerance),
             ratio);
  }
}

void ConsistencyMonitor::add_fix(const AnchorFix& f) {
  const Eigen::Vector3d e = f.dr_enu_m - f.fix_enu_m;
  const double sigma = std::isfinite(f.sigma_m) && f.sigma_m > 0.0 ? f.sigma_m : params_.gnss_position_sigma_m;
  if (!fixes_.empty() && f.dr_distance_m < fixes_.back().distance_m) fixes_.clear();
  fixes_.push_back({f.t_s, f.dr_distance_m, e.x(), e.y(), sigma});
  while (fixes_.size() >= 2 && f.dr_distance_m - fixes_[1].distance_m >= params_.growth_window_m) fixes_.pop_front();
  const Fix& a = fixes_.front();
  const double d = f.dr_distance_m - a.distance_m;
  if (d < params_.growth_window_m) return;
  if (!k_converged_ || !misalignment_converged_) {
    evidence(ConsistencyCheck::kDriftGrowth, f.t_s, std::nullopt, kNaN);  // nothing claimed: nothing to check
    return;
  }
  const double growth = 100.0 * std::hypot(e.x() - a.east_m, e.y() - a.north_m) / d;
  // What the estimates allow: a K error moves the track along, a heading error across it, each
  // sigma_factor sigmas; the two fixes' noise over the distance; unknown sigmas count as 0 (the floor
  // holds then).
  const double k_rel = k_sigma_rel_ > 0.0 ? k_sigma_rel_ : 0.0;
  const double heading = heading_std_rad_ > 0.0 ? heading_std_rad_ : 0.0;
  const double allowed = 100.0 * params_.sigma_factor * (std::hypot(k_rel, heading) + std::hypot(sigma, a.sigma_m) / d);
  evidence(ConsistencyCheck::kDriftGrowth, f.t_s, drift_growth_finding(growth, allowed, params_.growth_floor_percent),
           growth);
}

void ConsistencyMonitor::evidence(ConsistencyCheck c, double t_s, const std::optional<std::string>& finding,
                                  double value) {
  const int i = static_cast<int>(c);
  ConsistencyState& s = states_[i];
  s.last_value = value;
  const bool violated = finding.has_value();
  if (violated == s.raised) {
    disagree_since_s_[i] = kNaN;
    if (violated) s.text = *finding;  // the latest numbers
    return;
  }
  if (std::isnan(disagree_since_s_[i])) disagree_since_s_[i] = t_s;
  if (violated) pending_text_[i] = *finding;
  if (t_s - disagree_since_s_[i] < params_.persist_s) return;
  disagree_since_s_[i] = kNaN;
  s.raised = violated;
  if (violated) {
    s.text = pending_text_[i];
    s.raised_at_s = t_s;
    ++s.times_raised;
    ++raised_count_;
  } else {
    --raised_count_;
  }
}

std::string ConsistencyMonitor::reason() const {
  std::string r;
  for (const ConsistencyState& s : states_)
    if (s.raised) r += (r.empty() ? "" : "; ") + s.text;
  return r;
}

}  // namespace odonav::dead_reckoning
