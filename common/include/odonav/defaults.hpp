#pragma once
// The product defaults more than one component uses: one constant each, so a component's parameter
// struct, its flag and the simulator cannot drift apart.

namespace odonav {

/// Hold-off d (s) of the estimate-application rule (consumer_rules.hpp), when no
/// --estimate-hold-off-s is given. It covers a GNSS receiver's normal latency (the fix reaches the
/// gateway ~0.05-0.1 s after its epoch) plus one processing hop (an estimate leaves its producer ms
/// after the fix arrives), with margin.
inline constexpr double kDefaultEstimateHoldOff_s = 0.2;

/// Nominal odometer scale factor K (m/pulse) when neither --nominal-k nor the dataset's meta.json
/// gives one: the reference of the pulse-jump gate, of the set-K range and the K before
/// identification converges.
inline constexpr double kDefaultNominalK_m_per_pulse = 0.0125;
/// One-sigma of the nominal K relative to it (dimensionless) unless declared (--nominal-k-sigma-percent,
/// meta.json odometer.k_nominal_sigma_percent): what a K from the odometer's data sheet (wheel
/// circumference over pulses per turn) is known to before it is identified on the vehicle, tyre
/// pressure, load and wear moving the rolling circumference by 1-3 %: the upper end, so a K that is
/// known better is taken. Dead reckoning applies an identified K whose sigma is
/// below it (consumer_rules.hpp scale_factor_applicable).
inline constexpr double kDefaultNominalKRelSigma = 0.03;

}  // namespace odonav
