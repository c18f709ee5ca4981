#pragma once
// The smartLoc drive's K against its independent reference, for the offline accuracy tests that
// check it with their own parameters and tolerances (acceptance, sensor rates). Apart from
// offline_test_params.hpp so that its other users do not see namespace odonav::test as well.
#include <cstddef>
#include <vector>

#include "odonav/dataset.hpp"
#include "odonav/offline/offline_runner.hpp"
#include "offline_test_params.hpp"
#include "reference_k.hpp"

namespace odonav::offline::test {

/// The smartLoc drive's K run with the parameters params_of(d), against a reference computed
/// independently of the product (reference_k_m_per_pulse: the reference trajectory's length over
/// the pulses): the median (median_of) of the K that claim 0.3 % (published sigma below 0.3 % of
/// K), and of the converged K (sigma below 0.1 %), when there are some.
struct SmartLocK {
  std::size_t within_claim = 0;  ///< outputs whose sigma is below 0.3 % of K
  double median_m_per_pulse = 0.0;
  std::size_t converged = 0;  ///< converged outputs (converged_k)
  double converged_median_m_per_pulse = 0.0;
  double reference_m_per_pulse = 0.0;
};
inline SmartLocK smartloc_k(OfflineParams (*params_of)(const Dataset&)) {
  const Dataset d = smartloc_dataset();
  SmartLocK r;
  r.reference_m_per_pulse = odonav::test::reference_k_m_per_pulse(d);
  const OfflineResult run = run_offline(d, params_of(d));
  std::vector<double> claimed;
  for (const identification::IdentificationOutput& o : run.identification)
    if (o.main.valid && o.main.sigma_m_per_pulse > 0.0 && o.main.sigma_m_per_pulse < 0.003 * o.main.k_m_per_pulse)
      claimed.push_back(o.main.k_m_per_pulse);
  r.within_claim = claimed.size();
  if (!claimed.empty()) r.median_m_per_pulse = median_of(claimed);
  const std::vector<double> k = converged_k(run);
  r.converged = k.size();
  if (!k.empty()) r.converged_median_m_per_pulse = median_of(k);
  return r;
}

}  // namespace odonav::offline::test
