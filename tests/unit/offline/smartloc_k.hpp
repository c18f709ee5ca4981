#pragma once
// The smartLoc drive's K against its independent reference, for the offline accuracy tests that
// check it with their own parameters and tolerances (acceptance, sensor rates). Apart from
// offline_test_params.hpp so that its other users do not see namespace odonav::test as well.
#include <gtest/gtest.h>

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

/// Checks the run's K against the reference: enough outputs claim 0.3 % and enough are converged,
/// and the medians of both groups are within `tolerance` (a fraction) of the reference. Its
/// published sigma counts the residuals' correlation: since, few outputs claim 0.1 % (converged:
/// 16 of 1 372, 174 before) while most claim 0.3 %; both groups are held to the reference.
inline void expect_smartloc_k_near_reference(const SmartLocK& k, double tolerance) {
  ASSERT_GT(k.within_claim, 500u);
  ASSERT_GE(k.converged, 10u);
  EXPECT_NEAR(k.converged_median_m_per_pulse / k.reference_m_per_pulse, 1.0, tolerance);
  const double median = k.median_m_per_pulse, k_reference = k.reference_m_per_pulse;
  EXPECT_NEAR(median / k_reference, 1.0, tolerance) << "median " << median << " reference " << k_reference;
}

}  // namespace odonav::offline::test
