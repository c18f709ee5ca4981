#include "odonav/dead_reckoning/dead_reckoning_options.hpp"

#include "odonav/hold_off_option.hpp"
#include "odonav/lever_arm_option.hpp"

namespace odonav {

void add_dead_reckoning_options(Options& o) {
  o.add_double("nominal-k", 0.0, "K before identification converges (m/pulse); 0 = meta.json's, else 0.0125", 0.0, 10.0);
  add_estimate_hold_off_option(o);
  o.add_choice("dr-mode", "3d", {"3d", "2d"}, "3d: full attitude and height; 2d: heading only, height held");
}

DeadReckonerParams dead_reckoning_params_from(const Options& o) {
  DeadReckonerParams p;
  p.nominal_k_m_per_pulse = o.get_double("nominal-k");
  p.mode = o.get_string("dr-mode") == "2d" ? DeadReckoningMode::k2D : DeadReckoningMode::k3D;
  return p;
}

DeadReckoningFacts dead_reckoning_facts_from(const Options& o) {
  const DeadReckonerParams p = dead_reckoning_params_from(o);
  DeadReckoningFacts f;
  f.mode = p.mode;
  f.nominal_k_option_m_per_pulse = p.nominal_k_m_per_pulse;
  f.lever_arm_body_m = lever_arm_from(o);
  f.estimate_hold_off_s = estimate_hold_off_from(o);
  return f;
}

DeadReckonerParams dead_reckoner_params(const DeadReckoningFacts& f) {
  DeadReckonerParams p;
  p.mode = f.mode;
  p.use_ins = f.use_ins;
  p.lever_arm_body_m = f.lever_arm_body_m;
  p.estimate_hold_off_s = f.estimate_hold_off_s;
  p.nominal_k_m_per_pulse = f.nominal_k_option_m_per_pulse > 0.0
                                ? f.nominal_k_option_m_per_pulse
                                : f.dataset_nominal_k_m_per_pulse.value_or(kDefaultNominalK_m_per_pulse);
  return p;
}

AnchoredPositionParams anchored_position_params(const DeadReckoningFacts& facts) {
  AnchoredPositionParams p;
  if (!facts.use_ins) p.drift_percent_distance = 1.0;
  return p;
}

}  // namespace odonav
