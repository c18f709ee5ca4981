#include "evaluation.hpp"

#include <algorithm>
#include <cmath>

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

// First time from which every estimate in [from_s, until_s) stays within tol; NaN if none.
double first_time_staying_within(const std::vector<TimedValue>& est, const std::vector<double>& rel_err,
                                 double from_s, double until_s, double tol) {
  double candidate = kNaN;
  for (std::size_t i = 0; i < est.size(); ++i) {
    if (est[i].t_s < from_s) continue;
    if (est[i].t_s >= until_s) break;
    if (std::abs(rel_err[i]) < tol) {
      if (std::isnan(candidate)) candidate = est[i].t_s;
    } else {
      candidate = kNaN;
    }
  }
  return candidate;
}

// Linear interpolation of a track at t (nullopt outside its span or across a gap > max_gap_s).
std::optional<Geodetic> track_at(const std::vector<TimedPosition>& track, double t_s, double max_gap_s = 1.5) {
  if (track.empty() || t_s < track.front().t_s || t_s > track.back().t_s) return std::nullopt;
  auto it = std::lower_bound(track.begin(), track.end(), t_s,
                             [](const TimedPosition& p, double t) { return p.t_s < t; });
  if (it->t_s == t_s) return it->position;
  const TimedPosition& b = *it;
  const TimedPosition& a = *std::prev(it);
  if (b.t_s - a.t_s > max_gap_s) return std::nullopt;
  const double f = (t_s - a.t_s) / (b.t_s - a.t_s);
  return Geodetic{a.position.lat_rad + f * (b.position.lat_rad - a.position.lat_rad),
                  a.position.lon_rad + f * (b.position.lon_rad - a.position.lon_rad),
                  a.position.height_m + f * (b.position.height_m - a.position.height_m)};
}
// Horizontal distance (m) between a DR position and the reference, the most frequent call of the
// evaluation (every DR epoch of both runs). GeographicLib's geodesic inverse costs ~1 us and was
// half the summary's time; the errors compared here are metres to kilometres, where the flat
// formula with WGS-84 radii of curvature at the mean latitude agrees with the geodesic to
// ~(d / R)^2 tan^2(lat) / 24 relative: below 1e-7 up to 1 km at mid-latitudes, below 5e-6 up to
// 10 km for |lat| < 80 deg (tests/unit/offline_speed compares it with GeographicLib). Beyond
// kNearbyLimitM, or at |lat| >= 80 deg where the formula degrades, the geodesic is used.
double horizontal_error_m(const Geodetic& a, const Geodetic& b) {
  constexpr double kNearbyLimitM = 10000.0;
  constexpr double kPolarLatRad = 80.0 * kDegToRad;
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

// Distance travelled at t (the DR epoch at or before t).
double distance_at(const std::vector<TimedPosition>& dr, const std::vector<double>& distance_m, double t_s) {
  auto it = std::upper_bound(dr.begin(), dr.end(), t_s, [](double t, const TimedPosition& p) { return t < p.t_s; });
  if (it == dr.begin()) return distance_m.front();
  return distance_m[static_cast<std::size_t>(std::prev(it) - dr.begin())];
}
}  // namespace

KEvaluation evaluate_scale_factor(const std::vector<TimedValue>& estimate, const std::vector<TimedValue>& reference,
                                  const std::vector<KStep>& steps, double first_motion_t_s,
                                  const KEvaluationParams& params) {
  KEvaluation out;
  if (estimate.empty() || reference.empty()) return out;
  std::vector<double> rel(estimate.size());
  for (std::size_t i = 0; i < estimate.size(); ++i) {
    const double k_ref = reference_at(reference, estimate[i].t_s);
    rel[i] = (estimate[i].value - k_ref) / k_ref;
  }
  const double inf = std::numeric_limits<double>::infinity();
  const double first_step_s = steps.empty() ? inf : steps.front().t_s;
  const double t_conv = first_time_staying_within(estimate, rel, first_motion_t_s, first_step_s, params.tolerance_rel);
  out.time_to_converge_s = std::isnan(t_conv) ? kNaN : t_conv - first_motion_t_s;
  for (std::size_t s = 0; s < steps.size(); ++s) {
    const double until = s + 1 < steps.size() ? steps[s + 1].t_s : inf;
    const double t_settle = first_time_staying_within(estimate, rel, steps[s].t_s, until, params.tolerance_rel);
    out.settle_times_s.push_back(std::isnan(t_settle) ? kNaN : t_settle - steps[s].t_s);
  }
  // RMS after convergence (or after the settle window from the first motion when it never
  // converged), outside the settle windows after each step.
  const double rms_from = std::isnan(t_conv) ? first_motion_t_s + params.settle_window_s : t_conv;
  double sum_sq = 0.0, max_abs = 0.0;
  for (std::size_t i = 0; i < estimate.size(); ++i) {
    const double t = estimate[i].t_s;
    if (t < rms_from) continue;
    bool in_window = false;
    for (const KStep& st : steps) in_window = in_window || (t >= st.t_s && t < st.t_s + params.settle_window_s);
    if (in_window) continue;
    sum_sq += rel[i] * rel[i];
    max_abs = std::max(max_abs, std::abs(rel[i]));
    ++out.epochs;
  }
  if (out.epochs > 0) {
    out.rms_rel_error = std::sqrt(sum_sq / static_cast<double>(out.epochs));
    out.max_rel_error = max_abs;
  }
  out.final_rel_error = rel.back();
  return out;
}

DrEvaluation evaluate_dead_reckoning(const std::vector<TimedPosition>& dr, const std::vector<double>& distance_m,
                                     const std::vector<TimedPosition>& reference, const std::vector<Outage>& outages,
                                     double min_distance_m) {
  DrEvaluation out;
  double max_err = 0.0, max_pct = 0.0;
  bool any_pct = false;
  for (std::size_t i = 0; i < dr.size(); ++i) {
    const std::optional<Geodetic> ref = track_at(reference, dr[i].t_s);
    if (!ref) continue;
    const double err = horizontal_error_m(dr[i].position, *ref);
    ++out.epochs;
    out.distance_m = distance_m[i];
    out.final_error_m = err;
    out.final_error_percent = distance_m[i] > 0 ? 100.0 * err / distance_m[i] : kNaN;
    max_err = std::max(max_err, err);
    if (distance_m[i] >= min_distance_m) {
      max_pct = std::max(max_pct, 100.0 * err / distance_m[i]);
      any_pct = true;
    }
  }
  if (out.epochs > 0) out.max_error_m = max_err;
  if (any_pct) out.max_error_percent = max_pct;

  // Outages: the reference's last epoch at or before the start and first at or after the end
  // bracket the outage (a GNSS reference has no samples inside it).
  for (const Outage& o : outages) {
    double err_m = kNaN, pct = kNaN;
    auto ref_start = std::upper_bound(reference.begin(), reference.end(), o.start_s,
                                      [](double t, const TimedPosition& p) { return t < p.t_s; });
    auto ref_end = std::lower_bound(reference.begin(), reference.end(), o.end_s,
                                    [](const TimedPosition& p, double t) { return p.t_s < t; });
    if (ref_start != reference.begin() && ref_end != reference.end()) {
      --ref_start;
      const std::optional<Geodetic> dr_start = track_at(dr, ref_start->t_s);
      const std::optional<Geodetic> dr_end = track_at(dr, ref_end->t_s);
      if (dr_start && dr_end) {
        const LocalEnuFrame frame(ref_start->position);
        const Eigen::Vector3d dr_delta = frame.to_enu(*dr_end) - frame.to_enu(*dr_start);
        const Eigen::Vector3d ref_delta = frame.to_enu(ref_end->position);
        err_m = (dr_delta - ref_delta).head<2>().norm();
        const double d0 = distance_at(dr, distance_m, ref_start->t_s), d1 = distance_at(dr, distance_m, ref_end->t_s);
        pct = d1 > d0 ? 100.0 * err_m / (d1 - d0) : kNaN;
      }
    }
    out.outage_error_m.push_back(err_m);
    out.outage_error_percent.push_back(pct);
  }
  return out;
}

}  // namespace odonav::offline
