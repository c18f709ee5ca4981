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

#include "odonav/defaults.hpp"
#include "odonav/printf_text.hpp"

namespace odonav {

/// The estimate-application rule: an estimate stamped at GNSS epoch `epoch_s` (misalignment, K), or
/// a GNSS fix used as a reference, applies to the odometer samples stamped at or after
/// estimate_applies_from_s(epoch_s, hold_off_s) = epoch + hold-off (s, event time). A consumer
/// computing its output for odometer time t therefore needs the estimates of the epochs
/// <= t - hold-off only, which were produced (in normal operation) long before t: it never waits for
/// a GNSS epoch later than t, and its result does not depend on when the estimate arrived. The same
/// function decides in the DDS nodes and in odonav-offline, so both give the same numbers.
/// hold_off_s >= 0 (0 = the estimate applies from its own epoch, which makes the consumer wait).
///
/// Why 1 us earlier than epoch + hold-off for a hold-off > 0: GNSS epochs and odometer samples often
/// lie on one grid (10 Hz and 100 Hz), so epoch + hold-off is an odometer instant up to the last bit,
/// and a stamp carried over DDS (integer nanoseconds) comes back a few ulps off: the offline tool
/// and a node would then put that sample on different sides. 1 us is far above that rounding and far
/// below any sensor period, so both decide alike. With hold-off 0 the epoch itself is kept (the
/// estimate's stamp is then a stamp of the same grid, rounded alike).
constexpr double kEstimateApplicationGuard_s = 1e-6;
inline double estimate_applies_from_s(double epoch_s, double hold_off_s) {
  return hold_off_s > 0.0 ? epoch_s + hold_off_s - kEstimateApplicationGuard_s : epoch_s;
}

/// Epochs of calibration after which a misalignment estimate is applied even when not converged.
constexpr uint64_t kMisalignmentMinSamplesToApply = 100;

/// A provisional (not yet converged) estimate replaces the nominal value once it lies more than this
/// many of its own sigmas away from it (dimensionless).
/// Why: the nominal value's error is then at least (3 - 1) = 2 sigma with high probability, while the
/// estimate's is about 1 sigma, so the estimate is the better of the two. Why not a smaller factor:
/// in the first seconds the published sigmas are optimistic (the calibration's heading sigma is about
/// a third of its observed error over its first 40 epochs on sim:terrain; the K sigma rests on a
/// handful of residuals), and a false switch would be kept until the next applicable estimate.
constexpr double kProvisionalMinSigmas = 3.0;
/// ... and has at least this many samples behind it (GNSS epochs accepted).
/// Why: the sigma of the first sample or two rests on no or one residual (the estimators report their
/// noise floor there: sigma 0.5 % while the K of a first sample at 20 pulses is 3-4 % off).
constexpr uint64_t kProvisionalMinSamples = 5;

/// True when `estimate` beats `nominal` by the rule above: sigma finite and > 0 (-1 or infinity mean
/// unknown), and |estimate - nominal| > kProvisionalMinSigmas * sigma.
inline bool beats_nominal(double estimate, double nominal, double sigma) {
  return std::isfinite(estimate) && std::isfinite(sigma) && sigma > 0.0 &&
         std::abs(estimate - nominal) > kProvisionalMinSigmas * sigma;
}

/// The identification and dead reckoning apply a published misalignment (angles and one-sigmas in
/// rad; the nominal misalignment is zero) when
///   - the calibration says it converged, or
///   - it has used kMisalignmentMinSamplesToApply epochs (10 s at 10 Hz), or
///   - provisionally, from kProvisionalMinSamples epochs on, once either angle beats zero
///     (beats_nominal); both angles are then applied, since the other one's estimate is off by about
///     its own sigma, far less than what the first one gains.
/// Before: zero. Why apply early: dead reckoning's outputs are real time, so every metre driven on
/// zero misalignment keeps its cross-track error (0.8 deg over the first 100 m: 1.4 m).
/// Why the epoch count: on a real INS whose gyro heading drifts (the smartLoc drive), sigma stays
/// near 0.2 deg and never reaches the 0.02 deg convergence threshold, yet the estimate (-8.5 deg there)
/// is far better than zero: ignoring it biased K by -2.6 % and DR by 5.8 %D.
inline bool misalignment_applicable(bool converged, uint64_t samples_used, double heading_rad, double pitch_rad,
                                    double heading_std_rad, double pitch_std_rad) {
  if (converged || samples_used >= kMisalignmentMinSamplesToApply) return true;
  if (samples_used < kProvisionalMinSamples) return false;
  return beats_nominal(heading_rad, 0.0, heading_std_rad) || beats_nominal(pitch_rad, 0.0, pitch_std_rad);
}

/// While the calibration is silent, the identification and dead reckoning keep applying the last
/// misalignment they applied (stamped held_t_s, event time); their health says so, with how long
/// the calibration has been silent (wall clock): "holding misalignment of t=40.0 s (calibration
/// silent 5 s)".
inline std::string held_misalignment_text(double held_t_s, double silent_s) {
  return printf_text("holding misalignment of t=%.1f s (calibration silent %.0f s)", held_t_s, silent_s);
}

/// Dead reckoning applies an identified K (valid: finite and > 0) when its estimator says converged
/// (sigma_K / K small enough), or provisionally, from kProvisionalMinSamples accepted samples on, once
/// it beats the nominal K (beats_nominal with sigma_K, m/pulse). Before, it uses the nominal K.
/// Why early: a DR driven on a wrong nominal K never recovers the distance already driven (a nominal
/// half the true K cost 0.86 %D over 8 km on sim:terrain, waiting 14 s for "converged"), while a
/// K 3 sigma away from a nominal that is already nearly right is not taken before it converges.
/// Once a K of the same stream (the same identification instance) is in force, every later valid
/// estimate of it from kProvisionalMinSamples samples on is applied (stream_in_force): it rests on
/// more samples than the one in force, and the nominal K is no longer what it replaces. Judged
/// against the nominal, an estimate moving back towards a nominal that was nearly right fell under
/// 3 sigma and the older, worse K stayed in force (terrain at 1 Hz with a 200 ms receiver latency:
/// -3.5 % kept for 15 s while the estimates went -2.5 % ... -0.3 %).
/// Or, provisionally too, once its sigma is below the nominal K's own one-sigma
/// (nominal_sigma_m_per_pulse, m/pulse; 0 = unknown: the rule off): the estimate is then the better
/// known of the two whatever their difference. Why: the published sigma is honest (it counts the
/// latency not yet known and the lag after a change, docs/ALGORITHM.md "Honest sigma of K"), so it
/// stays larger than the scatter of the residuals for tens of seconds after the start, and a
/// nominal that is 1-2 % off would be kept for all that time by the 3 sigma test alone.
inline bool scale_factor_applicable(bool valid, bool converged, double k_m_per_pulse, double sigma_m_per_pulse,
                                    uint64_t samples_accepted, double nominal_k_m_per_pulse,
                                    bool stream_in_force = false, double nominal_sigma_m_per_pulse = 0.0) {
  if (!valid) return false;
  if (converged) return true;
  if (samples_accepted < kProvisionalMinSamples) return false;
  const bool better_known =
      std::isfinite(sigma_m_per_pulse) && sigma_m_per_pulse > 0.0 && sigma_m_per_pulse < nominal_sigma_m_per_pulse;
  return stream_in_force || better_known || beats_nominal(k_m_per_pulse, nominal_k_m_per_pulse, sigma_m_per_pulse);
}

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
