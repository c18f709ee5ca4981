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
/// the pulses): the median (median_of) of the converged K, when there is one.
struct SmartLocK {
  std::size_t converged = 0;  ///< converged outputs (converged_k)
  double median_m_per_pulse = 0.0;
  double reference_m_per_pulse = 0.0;
};
inline SmartLocK smartloc_k(OfflineParams (*params_of)(const Dataset&)) {
  const Dataset d = smartloc_dataset();
  SmartLocK r;
  r.reference_m_per_pulse = odonav::test::reference_k_m_per_pulse(d);
  const std::vector<double> k = converged_k(run_offline(d, params_of(d)));
  r.converged = k.size();
  if (!k.empty()) r.median_m_per_pulse = median_of(k);
  return r;
}

}  // namespace odonav::offline::test
