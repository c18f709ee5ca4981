#include "odonav/dead_reckoning/drift_evaluator.hpp"

#include <cmath>
#include <stdexcept>

#include "odonav/frames.hpp"

namespace odonav::dead_reckoning {

DriftEvaluator::DriftEvaluator(double min_distance_m) : min_distance_m_(min_distance_m) {
  if (!(min_distance_m >= 0.0)) throw std::invalid_argument("DriftEvaluator: min_distance_m must be >= 0");
}

void DriftEvaluator::add(double distance_m, double horizontal_error_m) {
  if (std::isnan(horizontal_error_m) || !(distance_m >= min_distance_m_) || !(distance_m > 0.0)) return;
  const double percent = 100.0 * horizontal_error_m / distance_m;
  ++summary_.points;
  summary_.final_distance_m = distance_m;
  summary_.final_error_m = horizontal_error_m;
  summary_.final_percent = percent;
  if (std::isnan(summary_.max_percent) || percent > summary_.max_percent) {
    summary_.max_percent = percent;
    summary_.max_percent_distance_m = distance_m;
  }
}

TruthTrack::TruthTrack(const std::vector<TruthSample>& truth, double max_gap_s) : max_gap_s_(max_gap_s) {
  for (const TruthSample& r : truth)
    if (std::isfinite(r.position.lat_rad) && std::isfinite(r.position.lon_rad) && std::isfinite(r.position.height_m))
      rows_.push_back(r);
}

std::optional<Geodetic> TruthTrack::position_at(double t_s) const {
  if (rows_.empty() || t_s < rows_.front().t_s || t_s > rows_.back().t_s) return std::nullopt;
  std::size_t lo = 0, hi = rows_.size() - 1;
  while (hi - lo > 1) {  // binary search: rows_[lo].t_s <= t_s <= rows_[hi].t_s
    const std::size_t m = (lo + hi) / 2;
    (rows_[m].t_s <= t_s ? lo : hi) = m;
  }
  const TruthSample& a = rows_[lo];
  const TruthSample& b = rows_[hi];
  if (b.t_s - a.t_s > max_gap_s_) return std::nullopt;
  const double f = b.t_s > a.t_s ? (t_s - a.t_s) / (b.t_s - a.t_s) : 0.0;
  return Geodetic{a.position.lat_rad + f * (b.position.lat_rad - a.position.lat_rad),
                  a.position.lon_rad + f * wrap_pi(b.position.lon_rad - a.position.lon_rad),
                  a.position.height_m + f * (b.position.height_m - a.position.height_m)};
}

}  // namespace odonav::dead_reckoning
