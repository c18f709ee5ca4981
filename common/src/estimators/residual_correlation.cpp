#include "odonav/residual_correlation.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace odonav {

void ResidualCorrelationTracker::add(double r_in, double clip) {
  const double r = std::clamp(r_in, -clip, clip);
  ++count_;
  const double weight = std::max(alpha_, 1.0 / static_cast<double>(count_));
  gamma_[0] += weight * (r * r - gamma_[0]);
  // gamma_k averages r_t r_(t-k) over the residuals that have a k-th predecessor.
  for (std::size_t k = 1; k <= kLags; ++k) {
    if (count_ <= k) break;
    const double weight_k = std::max(alpha_, 1.0 / static_cast<double>(count_ - k));
    gamma_[k] += weight_k * (r * recent_[k - 1] - gamma_[k]);
  }
  for (std::size_t k = kLags - 1; k > 0; --k) recent_[k] = recent_[k - 1];
  recent_[0] = r;
}

double ResidualCorrelationTracker::sigma_factor() const {
  if (count_ <= kLags || !(gamma_[0] > 0.0)) return 1.0;
  double long_run = gamma_[0];
  for (std::size_t k = 1; k <= kLags; ++k)
    long_run += 2.0 * (1.0 - static_cast<double>(k) / static_cast<double>(kLags + 1)) * gamma_[k];
  return std::sqrt(std::max(1.0, long_run / gamma_[0]));
}

void ResidualCorrelationTracker::restore_state(const State& s) {
  for (double v : s.recent)
    if (!std::isfinite(v)) throw std::runtime_error("residual correlation: a recent residual is not finite");
  for (double v : s.gamma)
    if (!std::isfinite(v)) throw std::runtime_error("residual correlation: a running mean is not finite");
  if (s.gamma[0] < 0.0) throw std::runtime_error("residual correlation: the variance is negative");
  count_ = s.count;
  recent_ = s.recent;
  gamma_ = s.gamma;
}

}  // namespace odonav
