#pragma once
// When a consumer applies an estimate published upstream. One place, so odonav-offline and the DDS
// nodes decide alike (and give the same numbers).
namespace odonav {

#include <cstdint>

/// Epochs of calibration after which a misalignment estimate is applied even when not converged.
constexpr uint64_t kMisalignmentMinSamplesToApply = 100;

/// The identification and dead reckoning apply a published misalignment once the calibration says it
/// converged, or once it has used kMisalignmentMinSamplesToApply epochs (10 s at 10 Hz). Before: zero.
/// Why not "converged" alone: on a real INS whose gyro heading drifts (the smartLoc drive), sigma stays
/// near 0.2 deg and never reaches the 0.02 deg convergence threshold, yet the estimate (-8.5 deg there)
/// is far better than zero: ignoring it biased K by -2.6 % and DR by 5.8 %D. An estimate from fewer
/// epochs can be off by tenths of a degree, which DR would keep as cross-track error.
inline bool misalignment_applicable(bool converged, uint64_t samples_used) {
  return converged || samples_used >= kMisalignmentMinSamplesToApply;
}


/// Dead reckoning applies an identified K once its estimator says converged (sigma small enough);
/// before, it uses the nominal K. An unconverged K from the first seconds can be off by percents.
inline bool scale_factor_applicable(bool valid, bool converged) { return valid && converged; }

}  // namespace odonav
