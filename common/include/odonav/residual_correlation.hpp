#pragma once
// Serial correlation of regression residuals, as a factor on a one-sigma (used by the K estimators
// of estimators.hpp and by the misalignment calibration).
#include <array>
#include <cstddef>
#include <cstdint>

namespace odonav {

/// How much the serial correlation of a regression's residuals widens the one-sigma of its
/// estimate. sigma / sqrt(sum phi^2) holds for independent residuals; neighbouring samples that
/// share an error (two K samples share the GNSS speed of their common epoch, a smooth acceleration
/// error spans several) move together, and the plain formula is then optimistic. The factor is
/// sqrt(long-run variance / variance) of the a-priori residuals r (any unit, e.g. m or m/s): the
/// long-run variance by Bartlett weights over kLags lags (Newey-West),
/// gamma_0 + 2 sum_k (1 - k / (kLags + 1)) gamma_k, each gamma a running mean of products with the
/// weight max(alpha, 1/n). Negative correlation (pulse quantisation) never narrows a sigma: the
/// factor is at least 1, and at most sqrt(1 + kLags) by construction.
class ResidualCorrelationTracker {
 public:
  static constexpr std::size_t kLags = 3;
  /// alpha in (0, 1]: weight of a new product (the first ones form a plain mean, as in
  /// ResidualScaleTracker).
  explicit ResidualCorrelationTracker(double alpha) : alpha_(alpha) {}
  /// Adds the next residual r, clipped to [-clip, clip] (clip > 0, same unit: e.g. 3 sigma, so one
  /// outlier does not read as correlation).
  void add(double r, double clip);
  /// sqrt(long-run variance / variance), in [1, sqrt(1 + kLags)]; 1 until kLags + 1 residuals are in.
  double sigma_factor() const;
  void reset() { *this = ResidualCorrelationTracker(alpha_); }

  /// For save/restore: the residuals added, the last kLags residuals (newest first) and the
  /// running means gamma_0..gamma_kLags (the residual's unit squared).
  struct State {
    uint64_t count = 0;
    std::array<double, kLags> recent{};
    std::array<double, kLags + 1> gamma{};
    template <class Archive, class Self>  // checkpoint fields (checkpoint_state.hpp)
    static void state_fields(Archive& a, Self& s) {
      a("count", s.count)("recent", s.recent)("gamma", s.gamma);
    }
  };
  State state() const { return {count_, recent_, gamma_}; }
  /// Throws std::runtime_error when a value is not finite or gamma_0 is negative.
  void restore_state(const State& s);

 private:
  double alpha_;
  uint64_t count_ = 0;
  std::array<double, kLags> recent_{};
  std::array<double, kLags + 1> gamma_{};
};

}  // namespace odonav
