#include "odonav/dead_reckoning/dead_reckoning_options.hpp"

#include <algorithm>
#include <string>

#include "odonav/hold_off_option.hpp"
#include "odonav/lever_arm_option.hpp"
#include "odonav/nominal_k_option.hpp"

namespace odonav::dead_reckoning {

void add_dead_reckoning_options(Options& o) {
  add_nominal_k_option(o);
  add_estimate_hold_off_option(o);
  o.add_double("nominal-k-sigma-percent", 0.0,
               "one-sigma of the nominal K, % of it (0: meta.json's odometer.k_nominal_sigma_percent, else " +
                   std::to_string(static_cast<int>(100.0 * kDefaultNominalKRelSigma)) +
                   "); an identified K whose sigma is below it replaces the nominal K",
               0.0, 100.0);
  o.add_choice("dr-mode", "3d", {"3d", "2d"}, "3d: full attitude and height; 2d: heading only, height held");
  // The GNSS-anchored navigation position (anchored_position.hpp); its hold-off is
  // --estimate-hold-off-s, the DR's.
  const AnchoredPositionParams a;
  o.add_double("anchor-drift-percent", a.drift_percent_distance,
               "navigation position: one-sigma random walk of the offset per axis, % of distance at 400 m (what the "
               "scale and heading states do not model); without INS at least 1",
               1e-6, 100.0);
  o.add_double("anchor-scale-sigma-percent", a.scale_sigma_percent,
               "navigation position: prior one-sigma of the DR increments' scale (K) error, % (0: K taken as right)",
               0.0, 100.0);
  o.add_double("anchor-scale-walk-percent-per-sqrt-km", a.scale_random_walk_percent_per_sqrt_km,
               "navigation position: random walk of that scale error, % per sqrt(km)", 0.0, 100.0);
  o.add_double("anchor-heading-sigma-deg", a.heading_sigma_deg,
               "navigation position: prior one-sigma of the DR increments' heading error, deg (0: taken as right)", 0.0,
               90.0);
  o.add_double("anchor-heading-walk-deg-per-sqrt-s", a.heading_random_walk_deg_per_sqrt_s,
               "navigation position: random walk of that heading error, deg per sqrt(s)", 0.0, 10.0);
  o.add_double("anchor-gnss-correlation-s", a.fix_correlation_time_s,
               "navigation position: correlation time of the GNSS position error (Gauss-Markov), s", 1e-3, 1e5);
  o.add_double("anchor-gnss-correlated-fraction", a.fix_correlated_fraction,
               "navigation position: share of a fix's variance (pos_std_m^2) that is correlated, the rest white", 0.0,
               0.999);
  o.add_double("anchor-gate-sigma", a.gate_sigma,
               "navigation position: a fix whose innovation exceeds this many predicted sigmas is rejected", 1e-3, 1e6);
}

DeadReckonerParams dead_reckoning_params_from(const Options& o) {
  DeadReckonerParams p;
  p.nominal_k_m_per_pulse = nominal_k_option_from(o);
  p.mode = o.get_string("dr-mode") == "2d" ? DeadReckoningMode::k2D : DeadReckoningMode::k3D;
  return p;
}

DeadReckoningFacts dead_reckoning_facts_from(const Options& o) {
  const DeadReckonerParams p = dead_reckoning_params_from(o);
  DeadReckoningFacts f;
  f.mode = p.mode;
  f.nominal_k_option_m_per_pulse = p.nominal_k_m_per_pulse;
  f.nominal_k_sigma_option_percent = o.get_double("nominal-k-sigma-percent");
  f.lever_arm_body_m = lever_arm_from(o);
  f.estimate_hold_off_s = estimate_hold_off_from(o);
  AnchoredPositionParams& a = f.anchored;
  a.drift_percent_distance = o.get_double("anchor-drift-percent");
  a.scale_sigma_percent = o.get_double("anchor-scale-sigma-percent");
  a.scale_random_walk_percent_per_sqrt_km = o.get_double("anchor-scale-walk-percent-per-sqrt-km");
  a.heading_sigma_deg = o.get_double("anchor-heading-sigma-deg");
  a.heading_random_walk_deg_per_sqrt_s = o.get_double("anchor-heading-walk-deg-per-sqrt-s");
  a.fix_correlation_time_s = o.get_double("anchor-gnss-correlation-s");
  a.fix_correlated_fraction = o.get_double("anchor-gnss-correlated-fraction");
  a.gate_sigma = o.get_double("anchor-gate-sigma");
  return f;
}

DeadReckonerParams dead_reckoner_params(const DeadReckoningFacts& f) {
  DeadReckonerParams p;
  p.mode = f.mode;
  p.use_ins = f.use_ins;
  p.lever_arm_body_m = f.lever_arm_body_m;
  p.estimate_hold_off_s = f.estimate_hold_off_s;
  p.nominal_k_m_per_pulse = resolve_nominal_k(f.nominal_k_option_m_per_pulse, f.dataset_nominal_k_m_per_pulse);
  if (f.nominal_k_sigma_option_percent > 0.0)
    p.nominal_k_rel_sigma = f.nominal_k_sigma_option_percent / 100.0;
  else if (f.dataset_nominal_k_sigma_percent)
    p.nominal_k_rel_sigma = *f.dataset_nominal_k_sigma_percent / 100.0;
  return p;
}

AnchoredPositionParams anchored_position_params(const DeadReckoningFacts& facts) {
  AnchoredPositionParams p = facts.anchored;
  // One hold-off: a fix applies when the DR's estimates of its epoch do (the DR reports it then).
  p.hold_off_s = facts.estimate_hold_off_s;
  if (!facts.use_ins) p.drift_percent_distance = std::max(p.drift_percent_distance, kDegradedAnchorDriftPercent);
  return p;
}

}  // namespace odonav::dead_reckoning
