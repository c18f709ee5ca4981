// The CUSUM change detector shared by kf_rw and vff_lm_rls (CusumChangeDetector).
#include <cmath>
#include <stdexcept>

#include "odonav/estimators.hpp"

namespace odonav {

std::optional<uint64_t> CusumChangeDetector::add(double z, uint64_t index) {
  // A side at 0 starts a new run with this sample: if it ends in a change, the change began here.
  if (high_ == 0.0) high_start_ = index;
  if (low_ == 0.0) low_start_ = index;
  high_ = std::max(0.0, high_ + z - drift_);
  low_ = std::max(0.0, low_ - z - drift_);
  if (!(high_ > threshold_) && !(low_ > threshold_)) return std::nullopt;
  const uint64_t start = high_ > threshold_ ? high_start_ : low_start_;
  high_ = 0.0;
  low_ = 0.0;
  ++changes_;
  return start;
}

void CusumChangeDetector::set_state(const State& s) {
  if (!std::isfinite(s.high) || !std::isfinite(s.low) || s.high < 0.0 || s.low < 0.0)
    throw std::runtime_error("change detector state: CUSUM sums must be finite and >= 0");
  high_ = s.high;
  low_ = s.low;
  high_start_ = s.high_start;
  low_start_ = s.low_start;
  changes_ = s.changes;
}

}  // namespace odonav
