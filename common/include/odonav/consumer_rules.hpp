#pragma once
// When a consumer applies an estimate published upstream, and which commanded K a component takes.
// One place, so odonav-offline and the DDS nodes decide alike (and give the same numbers).
// Header-only, no middleware: part of the middleware-free common headers (common/include, the
// include directory of odonav_core and every other common area library).
#include <cmath>
#include <cstdint>
#include <optional>
#include <sstream>
#include <string>

namespace odonav {

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

/// Why a commanded K (COMMAND_SET_K's value, m/pulse) is refused, or nothing when it is acceptable.
/// Acceptable: finite, > 0 and within [0.1, 10] x nominal_k_m_per_pulse, the component's own nominal
/// K (m/pulse; finite and > 0, else that is the problem named). Both bounds are included. A K outside
/// that range is a typing error (a unit slip), not an odometer: the identification would take many
/// windows to recover from it, and dead reckoning would lay out kilometres of wrong track. Every
/// component that takes set_k (identification, dead reckoning) checks with this one function, so an
/// operator's K is accepted by both or by neither. The text names the value and the range, e.g.
/// "K = 0.126 m/pulse is outside [0.1, 10] x nominal K (0.0125 m/pulse)".
inline std::optional<std::string> commanded_k_problem(double k_m_per_pulse, double nominal_k_m_per_pulse) {
  std::ostringstream m;
  m.precision(10);
  if (!std::isfinite(nominal_k_m_per_pulse) || !(nominal_k_m_per_pulse > 0.0)) {
    m << "nominal K = " << nominal_k_m_per_pulse << " m/pulse is not finite and > 0";
    return m.str();
  }
  if (!std::isfinite(k_m_per_pulse) || !(k_m_per_pulse > 0.0)) {
    m << "K = " << k_m_per_pulse << " m/pulse is not finite and > 0";
    return m.str();
  }
  // k x 10 < nominal rather than k < 0.1 x nominal: 0.1 has no exact binary form, and exactly a tenth
  // of the nominal must pass.
  if (k_m_per_pulse * 10.0 < nominal_k_m_per_pulse || k_m_per_pulse > 10.0 * nominal_k_m_per_pulse) {
    m << "K = " << k_m_per_pulse << " m/pulse is outside [0.1, 10] x nominal K (" << nominal_k_m_per_pulse
      << " m/pulse)";
    return m.str();
  }
  return std::nullopt;
}

}  // namespace odonav
