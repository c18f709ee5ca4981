#include "odonav/offline/first_metres.hpp"

#include <algorithm>
#include <optional>
#include <sstream>

#include "odonav/geodesy.hpp"

namespace odonav::offline {

namespace {

Eigen::Vector3d horizontal(Eigen::Vector3d v) {
  v.z() = 0.0;
  return v;
}

constexpr double kAfterM = 500.0;

}  // namespace

std::optional<Eigen::Vector3d> FirstMetresAccumulator::Origin::mean() const {
  if (n == 0) return std::nullopt;
  return sum / static_cast<double>(n);
}

FirstMetresAccumulator::FirstMetresAccumulator(SourceFactory<TruthSample> truth) : factory_(std::move(truth)) {
  f_.max_after_500m_percent = f_.drift_max_after_500m_percent = 0.0;
}

// The last truth sample whose stamp rounds to t_ms (as a map by millisecond keeps it), if any.
std::optional<TruthSample> FirstMetresAccumulator::truth_at_ms(long long t_ms) {
  if (matched_valid_ && t_ms == matched_ms_) return matched_;
  if (!truth_started_ || (matched_valid_ && t_ms < matched_ms_)) {  // first call, or back in time
    truth_ = factory_ ? factory_() : Source<TruthSample>([] { return std::optional<TruthSample>(); });
    truth_next_ = truth_();
    truth_started_ = true;
  }
  const auto ms = [](const TruthSample& t) { return std::llround(t.t_s * 1000.0); };
  while (truth_next_ && ms(*truth_next_) < t_ms) truth_next_ = truth_();
  matched_.reset();
  while (truth_next_ && ms(*truth_next_) == t_ms) {
    matched_ = truth_next_;
    truth_next_ = truth_();
  }
  matched_ms_ = t_ms;
  matched_valid_ = true;
  return matched_;
}

void FirstMetresAccumulator::count_past_500m(const Past500m& p) {
  const auto percent = [&](const Eigen::Vector3d& v) { return 100.0 * v.norm() / p.distance_m; };
  const auto count = [&](const Origin& origin, double& max_percent) {
    const std::optional<Eigen::Vector3d> c = origin.mean();
    if (!c) return;
    if (std::isnan(max_percent)) max_percent = 0.0;  // a maximum from 0 once the origin exists
    max_percent = std::max(max_percent, percent(p.error_m + *c));
  };
  count(standstill_, f_.standstill_origin_max_after_500m_percent);
  count(first_500m_, f_.first_500m_origin_max_after_500m_percent);
}

void FirstMetresAccumulator::add(const dead_reckoning::DeadReckoningOutput& o) {
  // An origin shifted by c moves every DR position by c; (fix - DR) = (fix - truth) - (DR - truth),
  // so the DR error with that origin is e + c.
  for (const dead_reckoning::AnchorFix& fix : o.gnss_fixes)
    for (Origin* origin : {&standstill_, &first_500m_}) {
      if (fix.dr_distance_m <= origin->max_distance_m) {
        origin->sum += horizontal(fix.fix_enu_m - fix.dr_enu_m);
        ++origin->n;
      } else {
        origin->complete = true;
      }
    }
  if (std::isnan(f_.distance_on_nominal_k_m) && o.k_source == dead_reckoning::ScaleFactorSource::kIdentified)
    f_.distance_on_nominal_k_m = o.distance_m;
  const std::optional<TruthSample> truth = truth_at_ms(std::llround(o.t_s * 1000.0));
  if (truth) {
    if (!frame_) frame_.emplace(truth->position);
    const Eigen::Vector3d e = horizontal(frame_->to_enu(o.position) - frame_->to_enu(truth->position));
    if (!start_offset_) {
      start_offset_ = e;
      f_.start_offset_m = e.norm();
    }
    if (o.distance_m >= 1.0) {
      const auto percent = [&](const Eigen::Vector3d& v) { return 100.0 * v.norm() / o.distance_m; };
      f_.final_percent = percent(e);
      f_.drift_final_percent = percent(e - *start_offset_);
      if (o.distance_m > kAfterM) {
        f_.max_after_500m_percent = std::max(f_.max_after_500m_percent, f_.final_percent);
        f_.drift_max_after_500m_percent = std::max(f_.drift_max_after_500m_percent, f_.drift_final_percent);
        waiting_.push_back({e, o.distance_m});
      }
    }
  }
  if (standstill_.complete && first_500m_.complete) {
    for (const Past500m& p : waiting_) count_past_500m(p);
    waiting_.clear();
  }
}

FirstMetres FirstMetresAccumulator::finish() {
  const std::optional<Eigen::Vector3d> standstill = standstill_.mean(), first_500m = first_500m_.mean();
  if (standstill && std::isnan(f_.standstill_origin_max_after_500m_percent))
    f_.standstill_origin_max_after_500m_percent = 0.0;
  if (first_500m && std::isnan(f_.first_500m_origin_max_after_500m_percent))
    f_.first_500m_origin_max_after_500m_percent = 0.0;
  for (const Past500m& p : waiting_) count_past_500m(p);
  waiting_.clear();
  if (start_offset_) {
    if (standstill) f_.standstill_origin_offset_m = (*start_offset_ + *standstill).norm();
    if (first_500m) f_.first_500m_origin_offset_m = (*start_offset_ + *first_500m).norm();
  }
  return f_;
}

FirstMetres evaluate_first_metres(const Dataset& d, const std::vector<dead_reckoning::DeadReckoningOutput>& dr) {
  FirstMetresAccumulator acc(vector_source(d.truth));
  for (const dead_reckoning::DeadReckoningOutput& o : dr) acc.add(o);
  return acc.finish();
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
