#include "odonav/offline/evaluation.hpp"

#include <sstream>

#include <algorithm>
#include <cmath>
#include <utility>

#include "odonav/frames.hpp"

namespace odonav::offline {
namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Latest reference value at or before t (the first one when t precedes all).
double reference_at(const std::vector<TimedValue>& ref, double t_s) {
  auto it = std::upper_bound(ref.begin(), ref.end(), t_s, [](double t, const TimedValue& v) { return t < v.t_s; });
  if (it == ref.begin()) return ref.front().value;
  return std::prev(it)->value;
}

// Largest time gap (s) across which a track is interpolated.
constexpr double kMaxTrackGapS = 1.5;

// Horizontal distance (m) between a DR position and the reference, the most frequent call of the
// evaluation (every DR epoch of both runs). GeographicLib's geodesic inverse costs ~1 us and was
// half the summary's time; the errors compared here are metres to kilometres, where the flat
// formula with WGS-84 radii of curvature at the mean latitude agrees with the geodesic to
// ~(d / R)^2 tan^2(lat) / 24 relative: below 1e-7 up to 1 km at mid-latitudes, below 5e-6 up to
// 10 km for |lat| < 80 deg (tests/unit/offline_speed compares it with GeographicLib). Beyond
// kNearbyLimitM, or at |lat| >= 80 deg where the formula degrades, the geodesic is used.
double horizontal_error_m(const Geodetic& a, const Geodetic& b) {
  constexpr double kNearbyLimitM = 10000.0;
  constexpr double kPolarLatRad = kPolarCapLatRad;
  const double lat_mid = 0.5 * (a.lat_rad + b.lat_rad);
  if (std::abs(a.lat_rad) < kPolarLatRad && std::abs(b.lat_rad) < kPolarLatRad) {
    const CurvatureRadii r = wgs84_radii(lat_mid);
    const double north_m = (b.lat_rad - a.lat_rad) * r.meridian_m;
    const double east_m = wrap_pi(b.lon_rad - a.lon_rad) * r.prime_vertical_m * std::cos(lat_mid);
    const double d = std::hypot(north_m, east_m);
    if (d < kNearbyLimitM) return d;
  }
  return horizontal_distance_m(a, b);
}

}  // namespace

void ScaleFactorEvaluator::Sums::add(double rel) {
  sum_sq += rel * rel;
  max_abs = std::max(max_abs, std::abs(rel));
  ++n;
}

ScaleFactorEvaluator::ScaleFactorEvaluator(std::vector<KStep> steps, const KEvaluationParams& params)
    : steps_(std::move(steps)), params_(params), settle_candidate_s_(steps_.size(), kNaN) {}

void ScaleFactorEvaluator::drop_steps_from(std::size_t n) {
  if (n >= steps_.size()) return;
  steps_.resize(n);
  settle_candidate_s_.resize(n);
  segment_ = std::min(segment_, n);
}

void ScaleFactorEvaluator::set_first_motion(double t_s) { first_motion_s_ = t_s; }

void ScaleFactorEvaluator::add(double t_s, double estimate, double reference) {
  const double rel = (estimate - reference) / reference;
  any_ = true;
  last_rel_ = rel;
  while (segment_ < steps_.size() && t_s >= steps_[segment_].t_s) ++segment_;
  bool in_window = false;
  for (const KStep& st : steps_) in_window = in_window || (t_s >= st.t_s && t_s < st.t_s + params_.settle_window_s);
  const bool within = std::abs(rel) < params_.tolerance_rel;
  // Convergence: the first time from which every estimate from first motion until the first step
  // stays within the tolerance; the RMS then covers the estimates from that time on.
  if (segment_ == 0) {
    if (!(t_s < first_motion_s_)) {
      if (within) {
        if (std::isnan(converge_candidate_s_)) {
          converge_candidate_s_ = t_s;
          since_candidate_ = {};
        }
      } else {
        converge_candidate_s_ = kNaN;
        since_candidate_ = {};
      }
    }
  } else {
    double& candidate = settle_candidate_s_[segment_ - 1];
    if (!within)
      candidate = kNaN;
    else if (std::isnan(candidate))
      candidate = t_s;
  }
  if (in_window) return;
  if (!std::isnan(converge_candidate_s_) && !(t_s < converge_candidate_s_)) since_candidate_.add(rel);
  if (!(t_s < first_motion_s_ + params_.settle_window_s)) after_window_.add(rel);
}

KEvaluation ScaleFactorEvaluator::result() const {
  KEvaluation out;
  if (!any_) return out;
  const double t_conv = converge_candidate_s_;
  out.time_to_converge_s = std::isnan(t_conv) ? kNaN : t_conv - first_motion_s_;
  for (std::size_t s = 0; s < steps_.size(); ++s)
    out.settle_times_s.push_back(std::isnan(settle_candidate_s_[s]) ? kNaN : settle_candidate_s_[s] - steps_[s].t_s);
  // RMS after convergence (or after the settle window from the first motion when it never
  // converged), outside the settle windows after each step.
  const Sums& sums = std::isnan(t_conv) ? after_window_ : since_candidate_;
  out.epochs = sums.n;
  if (sums.n > 0) {
    out.rms_rel_error = std::sqrt(sums.sum_sq / static_cast<double>(sums.n));
    out.max_rel_error = sums.max_abs;
  }
  out.final_rel_error = last_rel_;
  return out;
}

KEvaluation evaluate_scale_factor(const std::vector<TimedValue>& estimate, const std::vector<TimedValue>& reference,
                                  const std::vector<KStep>& steps, double first_motion_t_s,
                                  const KEvaluationParams& params) {
  if (estimate.empty() || reference.empty()) return KEvaluation{};
  ScaleFactorEvaluator e(steps, params);
  e.set_first_motion(first_motion_t_s);
  for (const TimedValue& v : estimate) e.add(v.t_s, v.value, reference_at(reference, v.t_s));
  return e.result();
}

OutageList::OutageList(std::vector<Outage> outages) : outages_(std::move(outages)) {}

OutageList::OutageList(Source<GnssSample> gnss, double min_gap_s) : gnss_(std::move(gnss)), min_gap_s_(min_gap_s) {}

void OutageList::discover_through(double t_s) {
  // An outage between valid fixes a and b is known once b is read: read until a valid fix after t_s.
  while (gnss_ && (!last_valid_s_ || !(*last_valid_s_ > t_s))) {
    const std::optional<GnssSample> g = gnss_();
    if (!g) {
      gnss_ = nullptr;
      break;
    }
    if (!g->valid()) continue;
    if (last_valid_s_ && g->t_s - *last_valid_s_ >= min_gap_s_) outages_.push_back({*last_valid_s_, g->t_s});
    last_valid_s_ = g->t_s;
  }
}

void OutageList::discover_all() { discover_through(std::numeric_limits<double>::infinity()); }

DeadReckoningEvaluator::DeadReckoningEvaluator(const SourceFactory<TimedPosition>& reference, OutageList outages,
                                               double min_distance_m)
    : error_ref_(reference()), probe_ref_(reference()), outages_(std::move(outages)), min_distance_m_(min_distance_m) {}

void DeadReckoningEvaluator::add(double t_s, const Geodetic& position, double distance_m) {
  const Epoch epoch{t_s, position, distance_m};
  // The reference at this epoch: linear between the reference epochs around it.
  if (!ref_started_) {
    ref_next_ = error_ref_();
    ref_started_ = true;
  }
  while (ref_next_ && ref_next_->t_s < t_s) {
    ref_prev_ = ref_next_;
    ref_next_ = error_ref_();
  }
  std::optional<Geodetic> ref;
  if (ref_next_ && ref_next_->t_s == t_s)
    ref = ref_next_->position;
  else if (ref_next_ && ref_prev_ && !(ref_next_->t_s - ref_prev_->t_s > kMaxTrackGapS))
    ref = interpolate_geodetic(ref_prev_->position, ref_next_->position,
                               (t_s - ref_prev_->t_s) / (ref_next_->t_s - ref_prev_->t_s));
  if (ref) {
    const double err = horizontal_error_m(position, *ref);
    ++out_.epochs;
    out_.distance_m = distance_m;
    out_.final_error_m = err;
    out_.final_error_percent = distance_m > 0 ? 100.0 * err / distance_m : kNaN;
    max_err_ = std::max(max_err_, err);
    if (distance_m >= min_distance_m_) {
      max_pct_ = std::max(max_pct_, 100.0 * err / distance_m);
      any_pct_ = true;
    }
  }
  // The DR track at every reference epoch this epoch has passed (for the outages).
  if (!probe_started_) {
    probe_next_ = probe_ref_();
    probe_started_ = true;
  }
  while (probe_next_ && probe_next_->t_s < t_s) {
    resolve(*probe_next_, &epoch);
    probe_next_ = probe_ref_();
  }
  if (!last_ || last_->t_s != t_s) group_first_position_ = position;
  if (!first_) first_ = epoch;
  last_ = epoch;
}

// The DR track at reference epoch q, when every DR epoch before `next` (the first after q.t_s;
// nullptr after the last) has been added: the DR position at q's time (interpolated as
// evaluate_dead_reckoning does; none outside the DR's span) and the distance of the last DR epoch
// at or before it (of the first when none is).
void DeadReckoningEvaluator::resolve(const TimedPosition& q, const Epoch* next) {
  outages_.discover_through(q.t_s);
  if (outage_states_.size() < outages_.outages().size()) outage_states_.resize(outages_.outages().size());
  Probe p{q, std::nullopt, kNaN};
  if (last_ && last_->t_s == q.t_s) {
    p.dr = group_first_position_;
    p.dr_distance_m = last_->distance_m;
  } else if (last_) {
    if (next && !(next->t_s - last_->t_s > kMaxTrackGapS))
      p.dr = interpolate_geodetic(last_->position, next->position, (q.t_s - last_->t_s) / (next->t_s - last_->t_s));
    p.dr_distance_m = last_->distance_m;
  } else if (next) {
    p.dr_distance_m = next->distance_m;
  }
  close_outages(p);
  last_probe_ = p;
}

// Outages: the reference's last epoch at or before the start and first at or after the end
// bracket the outage (a GNSS reference has no samples inside it).
void DeadReckoningEvaluator::close_outages(const Probe& p) {
  for (std::size_t i = 0; i < outage_states_.size(); ++i) {
    OutageState& st = outage_states_[i];
    const Outage& o = outages_.outages()[i];
    if (st.done) continue;
    if (!st.start_decided && p.reference.t_s > o.start_s) {
      st.start_decided = true;
      st.start = last_probe_;
    }
    if (!st.start_decided || p.reference.t_s < o.end_s) continue;
    st.done = true;
    if (!st.start || !st.start->dr || !p.dr) continue;
    const Probe& a = *st.start;
    const LocalEnuFrame frame(a.reference.position);
    const Eigen::Vector3d dr_delta = frame.to_enu(*p.dr) - frame.to_enu(*a.dr);
    const Eigen::Vector3d ref_delta = frame.to_enu(p.reference.position);
    st.error_m = (dr_delta - ref_delta).head<2>().norm();
    st.error_percent =
        p.dr_distance_m > a.dr_distance_m ? 100.0 * st.error_m / (p.dr_distance_m - a.dr_distance_m) : kNaN;
  }
}

DrEvaluation DeadReckoningEvaluator::finish() {
  outages_.discover_all();
  if (outage_states_.size() < outages_.outages().size()) outage_states_.resize(outages_.outages().size());
  if (!probe_started_) {
    probe_next_ = probe_ref_();
    probe_started_ = true;
  }
  const auto open = [&] {
    return std::any_of(outage_states_.begin(), outage_states_.end(), [](const OutageState& s) { return !s.done; });
  };
  while (probe_next_ && open()) {
    resolve(*probe_next_, nullptr);
    probe_next_ = probe_ref_();
  }
  DrEvaluation out = out_;
  if (out.epochs > 0) out.max_error_m = max_err_;
  if (any_pct_) out.max_error_percent = max_pct_;
  for (const OutageState& st : outage_states_) {
    out.outage_error_m.push_back(st.error_m);
    out.outage_error_percent.push_back(st.error_percent);
  }
  return out;
}

DrEvaluation evaluate_dead_reckoning(const std::vector<TimedPosition>& dr, const std::vector<double>& distance_m,
                                     const std::vector<TimedPosition>& reference, const std::vector<Outage>& outages,
                                     double min_distance_m) {
  DeadReckoningEvaluator e(vector_source(reference), OutageList(outages), min_distance_m);
  for (std::size_t i = 0; i < dr.size(); ++i) e.add(dr[i].t_s, dr[i].position, distance_m[i]);
  return e.finish();
}

std::optional<std::string> truth_mismatch(Source<GnssSample>&& gnss, Source<TruthSample>&& truth, std::size_t fixes,
                                          double min_speed_mps, double max_median_m) {
  const auto has_position = [](const TruthSample& t) {
    return std::isfinite(t.position.lat_rad) && std::isfinite(t.position.lon_rad);
  };
  std::optional<TruthSample> before = truth();
  while (before && !has_position(*before)) before = truth();
  if (!before) return std::nullopt;  // no truth position: nothing to compare
  const double truth_first_s = before->t_s;
  std::optional<TruthSample> after = before;
  std::vector<double> moving_m, resting_m;  // distance fix - truth, moving and at rest
  std::optional<double> first_fix_s, last_fix_s;
  while (moving_m.size() < fixes) {
    const std::optional<GnssSample> g = gnss();
    if (!g) break;
    if (!g->valid()) continue;
    if (!first_fix_s) first_fix_s = g->t_s;
    last_fix_s = g->t_s;
    if (g->t_s < truth_first_s) continue;  // before the truth starts
    while (after && after->t_s < g->t_s) {
      before = after;
      do after = truth();
      while (after && !has_position(*after));
    }
    if (!after) break;  // the truth ended
    const double span = after->t_s - before->t_s;
    const double f = span > 0.0 ? (g->t_s - before->t_s) / span : 0.0;
    const double lat = before->position.lat_rad + f * (after->position.lat_rad - before->position.lat_rad);
    const double lon = before->position.lon_rad + f * wrap_pi(after->position.lon_rad - before->position.lon_rad);
    // Great-circle distance on the mean Earth radius: ample for telling metres from kilometres.
    const double dlat = g->position.lat_rad - lat, dlon = wrap_pi(g->position.lon_rad - lon);
    const double h = std::sin(dlat / 2) * std::sin(dlat / 2) +
                     std::cos(lat) * std::cos(g->position.lat_rad) * std::sin(dlon / 2) * std::sin(dlon / 2);
    const double d = 2.0 * 6371008.8 * std::asin(std::min(1.0, std::sqrt(h)));
    if (!std::isfinite(d)) continue;
    if (g->vel_enu_mps.head<2>().norm() >= min_speed_mps)
      moving_m.push_back(d);
    else if (resting_m.size() < fixes)
      resting_m.push_back(d);
  }
  if (!first_fix_s) return std::nullopt;  // no valid fix: nothing to compare
  std::vector<double>& d = moving_m.empty() ? resting_m : moving_m;
  if (d.empty()) {
    std::ostringstream m;
    m << "truth.csv (from t = " << truth_first_s
      << " s) does not overlap the valid GNSS fixes in time (t = " << *first_fix_s << " .. " << *last_fix_s << " s)";
    return m.str();
  }
  std::sort(d.begin(), d.end());
  const double median = d[d.size() / 2];
  if (median <= max_median_m) return std::nullopt;
  std::ostringstream m;
  m.precision(4);
  m << "truth.csv is " << (median >= 10e3 ? median / 1000.0 : median) << (median >= 10e3 ? " km" : " m")
    << " from the GNSS fixes (median of " << d.size() << (moving_m.empty() ? " fixes at rest" : " moving fixes")
    << " from t = " << *first_fix_s << " s; at most " << max_median_m
    << " m expected): the truth of another drive, or shifted in time?";
  return m.str();
}

}  // namespace odonav::offline
