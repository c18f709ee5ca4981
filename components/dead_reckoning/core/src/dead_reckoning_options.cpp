#include "odonav/dead_reckoning/dead_reckoning_options.hpp"

namespace odonav {

void add_dead_reckoning_options(Options& o) {
  o.add_double("nominal-k", 0.0, "K before identification converges (m/pulse); 0 = meta.json's, else 0.0125", 0.0, 10.0);
  o.add_choice("dr-mode", "3d", {"3d", "2d"}, "3d: full attitude and height; 2d: heading only, height held");
}

DeadReckonerParams dead_reckoning_params_from(const Options& o) {
  DeadReckonerParams p;
  p.nominal_k_m_per_pulse = o.get_double("nominal-k");
  p.mode = o.get_string("dr-mode") == "2d" ? DeadReckoningMode::k2D : DeadReckoningMode::k3D;
  return p;
}

}  // namespace odonav
