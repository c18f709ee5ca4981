#include "odonav/nominal_k_option.hpp"

#include "odonav/defaults.hpp"

namespace odonav {

void add_nominal_k_option(Options& o) {
  if (o.declared("nominal-k")) return;  // identification and dead reckoning options in one tool
  o.add_double("nominal-k", 0.0,
               "the vehicle's nominal K (m/pulse): dead reckoning's K until an identified K is accepted, the "
               "pulse-jump gates' K and the reference of the set_k range (0.1x..10x); 0 = meta.json's, else 0.0125",
               0.0, 10.0);
}

double nominal_k_option_from(const Options& o) { return o.get_double("nominal-k"); }

double resolve_nominal_k(double option_m_per_pulse, std::optional<double> dataset_m_per_pulse) {
  if (option_m_per_pulse > 0.0) return option_m_per_pulse;
  return dataset_m_per_pulse.value_or(kDefaultNominalK_m_per_pulse);
}

}  // namespace odonav
