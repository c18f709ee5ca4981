#include "first_metres.hpp"

#include <algorithm>
#include <map>
#include <optional>
#include <sstream>

#include "odonav/geodesy.hpp"

namespace odonav::offline {

namespace {

Eigen::Vector3d horizontal(Eigen::Vector3d v) {
  v.z() = 0.0;
  return v;
}

// Mean of (fix - DR) over the fixes whose DR distance is at most max_distance_m (horizontal, m).
std::optional<Eigen::Vector3d> mean_fix_offset(const std::vector<DeadReckoningOutput>& dr, double max_distance_m) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  std::size_t n = 0;
  for (const DeadReckoningOutput& o : dr)
    for (const AnchorFix& f : o.gnss_fixes)
      if (f.dr_distance_m <= max_distance_m) {
        sum += horizontal(f.fix_enu_m - f.dr_enu_m);
        ++n;
      }
  if (n == 0) return std::nullopt;
  return sum / static_cast<double>(n);
}

}  // namespace

FirstMetres evaluate_first_metres(const Dataset& d, const std::vector<DeadReckoningOutput>& dr) {
  constexpr double kAfterM = 500.0;
  std::map<long long, const TruthSample*> truth;  // by t in ms (the DR outputs are odometer stamps)
  for (const TruthSample& t : d.truth) truth[std::llround(t.t_s * 1000.0)] = &t;
  // An origin shifted by c moves every DR position by c; (fix - DR) = (fix - truth) - (DR - truth),
  // so the DR error with that origin is e + c.
  const std::optional<Eigen::Vector3d> standstill = mean_fix_offset(dr, 0.0);
  const std::optional<Eigen::Vector3d> first_500m = mean_fix_offset(dr, kAfterM);
  FirstMetres f;
  f.max_after_500m_percent = f.drift_max_after_500m_percent = 0.0;
  if (standstill) f.standstill_origin_max_after_500m_percent = 0.0;
  if (first_500m) f.first_500m_origin_max_after_500m_percent = 0.0;
  std::optional<LocalEnuFrame> frame;
  std::optional<Eigen::Vector3d> start_offset;
  for (const DeadReckoningOutput& o : dr) {
    if (std::isnan(f.distance_on_nominal_k_m) && o.k_source == ScaleFactorSource::kIdentified)
      f.distance_on_nominal_k_m = o.distance_m;
    const auto it = truth.find(std::llround(o.t_s * 1000.0));
    if (it == truth.end()) continue;
    if (!frame) frame.emplace(it->second->position);
    const Eigen::Vector3d e = horizontal(frame->to_enu(o.position) - frame->to_enu(it->second->position));
    if (!start_offset) {
      start_offset = e;
      f.start_offset_m = e.norm();
      if (standstill) f.standstill_origin_offset_m = (e + *standstill).norm();
      if (first_500m) f.first_500m_origin_offset_m = (e + *first_500m).norm();
    }
    if (o.distance_m < 1.0) continue;
    const auto percent = [&](const Eigen::Vector3d& v) { return 100.0 * v.norm() / o.distance_m; };
    f.final_percent = percent(e);
    f.drift_final_percent = percent(e - *start_offset);
    if (o.distance_m > kAfterM) {
      f.max_after_500m_percent = std::max(f.max_after_500m_percent, f.final_percent);
      f.drift_max_after_500m_percent = std::max(f.drift_max_after_500m_percent, f.drift_final_percent);
      if (standstill)
        f.standstill_origin_max_after_500m_percent =
            std::max(f.standstill_origin_max_after_500m_percent, percent(e + *standstill));
      if (first_500m)
        f.first_500m_origin_max_after_500m_percent =
            std::max(f.first_500m_origin_max_after_500m_percent, percent(e + *first_500m));
    }
  }
  return f;
}

std::string describe(const FirstMetres& f) {
  std::ostringstream m;
  m << "final " << f.final_percent << " %D, max after 500 m " << f.max_after_500m_percent
    << " %D; start offset removed: final " << f.drift_final_percent << " %D, max after 500 m "
    << f.drift_max_after_500m_percent << " %D; start offset " << f.start_offset_m << " m; on nominal K for "
    << f.distance_on_nominal_k_m << " m; origin from the standstill fixes: offset " << f.standstill_origin_offset_m
    << " m, max after 500 m " << f.standstill_origin_max_after_500m_percent
    << " %D; origin from the fixes of the first 500 m: offset " << f.first_500m_origin_offset_m
    << " m, max after 500 m " << f.first_500m_origin_max_after_500m_percent << " %D";
  return m.str();
}

}  // namespace odonav::offline
