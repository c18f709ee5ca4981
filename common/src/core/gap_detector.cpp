#include "odonav/gap_detector.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "odonav/printf_text.hpp"

namespace odonav {

GapDetector::GapDetector(double declared_period_s) : declared_period_s_(declared_period_s) {
  if (!std::isfinite(declared_period_s) || declared_period_s < 0.0)
    throw std::invalid_argument("odonav::GapDetector: the period must be finite and >= 0 (0: learned), got " +
                                std::to_string(declared_period_s));
}

std::optional<double> GapDetector::period_s() const {
  if (declared_period_s_ > 0.0) return declared_period_s_;
  return learned_period_s_;
}

std::optional<OutputGap> GapDetector::offer(double t_s) {
  if (!std::isfinite(t_s)) return std::nullopt;
  if (!last_t_s_) {
    last_t_s_ = t_s;
    return std::nullopt;
  }
  const double dt = t_s - *last_t_s_;
  if (!(dt > 0.0)) return std::nullopt;  // repeat or backwards: not ours to judge
  const double before = *last_t_s_;
  last_t_s_ = t_s;
  if (declared_period_s_ <= 0.0 && (!learned_period_s_ || dt < *learned_period_s_)) {
    learned_period_s_ = dt;
    return std::nullopt;
  }
  const double period = *period_s();
  if (dt <= 1.5 * period) return std::nullopt;
  const auto slots = static_cast<std::uint64_t>(std::llround(dt / period));
  if (slots < 2) return std::nullopt;
  OutputGap g{before + period, t_s - period, slots - 1};
  missed_ += g.missed;
  ++gaps_;
  last_gap_ = g;
  return g;
}

std::string describe_gap(const OutputGap& gap, const std::string& what) {
  return printf_text("missed %llu %s outputs t=%.3f-%.3f s", static_cast<unsigned long long>(gap.missed), what.c_str(),
                     gap.first_missing_t_s, gap.last_missing_t_s);
}

std::vector<OutputGap> missing_epochs(std::vector<double> epochs_s, std::vector<double> rows_s) {
  constexpr double kMatch_s = 1e-6;
  std::sort(epochs_s.begin(), epochs_s.end());
  epochs_s.erase(std::unique(epochs_s.begin(), epochs_s.end()), epochs_s.end());
  std::sort(rows_s.begin(), rows_s.end());
  std::vector<OutputGap> runs;
  std::optional<OutputGap> run;
  for (const double e : epochs_s) {
    if (!std::isfinite(e)) continue;
    const auto it = std::lower_bound(rows_s.begin(), rows_s.end(), e - kMatch_s);
    if (it != rows_s.end() && *it <= e + kMatch_s) {
      if (run) runs.push_back(*run);
      run.reset();
      continue;
    }
    if (!run) run = OutputGap{e, e, 0};
    run->last_missing_t_s = e;
    ++run->missed;
  }
  if (run) runs.push_back(*run);
  return runs;
}

}  // namespace odonav
