// What K's published sigma and converged say (identification_core.hpp honest_estimate,
// docs/ALGORITHM.md "Honest sigma of K"): the estimator's scatter, the lag after a detected change and
// the latency not yet known, combined; converged only with the latency decided.
#include <gtest/gtest.h>

#include <cmath>

#include "odonav/identification/identification_core.hpp"

namespace odonav::identification {
namespace {

ScaleFactorEstimate own_estimate() {
  ScaleFactorEstimate e;
  e.valid = true;
  e.k_m_per_pulse = 0.0125;
  e.sigma_m_per_pulse = 0.0125 * 0.0002;  // the scatter: 0.02 %
  e.converged = true;
  e.samples_used = 100;
  return e;
}

TEST(HonestEstimate, AddsTheLatencyTermToTheLargerOfScatterAndLag) {
  ScaleFactorEstimate own = own_estimate();
  own.dk_dlatency_m_per_pulse_per_s = -0.0125 * 0.2;  // 0.2 % of K per 10 ms: accelerating
  // u 5 ms: 0.1 % of K from the latency, hypot with the scatter's 0.02 %.
  ScaleFactorEstimate e = honest_estimate(own, 0.005, true, 0.001);
  EXPECT_DOUBLE_EQ(e.sigma_m_per_pulse, std::hypot(0.0125 * 0.0002, 0.0125 * 0.001));
  EXPECT_FALSE(e.converged);  // 0.102 % of K: not below 0.1 %
  EXPECT_EQ(e.k_m_per_pulse, own.k_m_per_pulse);
  // The lag replaces the scatter when larger, never adds to it.
  own.lag_sigma_m_per_pulse = 0.0125 * 0.003;
  e = honest_estimate(own, 0.0, true, 0.001);
  EXPECT_DOUBLE_EQ(e.sigma_m_per_pulse, 0.0125 * 0.003);
  own.lag_sigma_m_per_pulse = 0.0125 * 0.0001;
  e = honest_estimate(own, 0.0, true, 0.001);
  EXPECT_DOUBLE_EQ(e.sigma_m_per_pulse, own.sigma_m_per_pulse);
  EXPECT_TRUE(e.converged);
}

TEST(HonestEstimate, ConvergedNeedsTheLatencyDecidedAndTheEstimatorsOwnRule) {
  ScaleFactorEstimate own = own_estimate();
  EXPECT_TRUE(honest_estimate(own, 0.0, true, 0.001).converged);
  EXPECT_FALSE(honest_estimate(own, 0.0, false, 0.001).converged);  // latency not decided yet
  own.converged = false;                                            // e.g. fewer than min_samples
  EXPECT_FALSE(honest_estimate(own, 0.0, true, 0.001).converged);
  // At a steady speed the latency does not move K: no latency term, whatever u.
  own = own_estimate();
  EXPECT_DOUBLE_EQ(honest_estimate(own, 0.1, true, 0.001).sigma_m_per_pulse, own.sigma_m_per_pulse);
}

TEST(HonestEstimate, NoValueOrNoSigmaIsLeftAsItIs) {
  ScaleFactorEstimate none;
  EXPECT_FALSE(honest_estimate(none, 0.1, true, 0.001).valid);
  ScaleFactorEstimate commanded = own_estimate();
  commanded.sigma_m_per_pulse = 0.0;  // a commanded K without an estimate of its own: unknown
  commanded.converged = false;
  commanded.dk_dlatency_m_per_pulse_per_s = -1.0;
  EXPECT_EQ(honest_estimate(commanded, 0.1, true, 0.001).sigma_m_per_pulse, 0.0);
}

// The latency is fitted to the same samples as K: its least-squares sigmas are widened by K's
// residual correlation factor; the estimates stay, and a fixed or unknown sigma is left as it is.
TEST(WidenLatencySigma, TimesTheResidualCorrelationFactorOfK) {
  GnssLatencyEstimate l;
  l.applied_s = 0.09;
  l.applied_sigma_s = 0.010;
  l.estimate_s = 0.1;
  l.sigma_s = 0.004;
  widen_latency_sigma(l, 1.4);
  EXPECT_DOUBLE_EQ(l.applied_sigma_s, 0.014);
  EXPECT_DOUBLE_EQ(l.sigma_s, 0.004 * 1.4);
  EXPECT_EQ(l.applied_s, 0.09);
  EXPECT_EQ(l.estimate_s, 0.1);
  GnssLatencyEstimate none;  // nothing applied, no estimate: -1 stays -1
  widen_latency_sigma(none, 1.4);
  EXPECT_EQ(none.applied_sigma_s, -1.0);
  EXPECT_EQ(none.sigma_s, -1.0);
  GnssLatencyEstimate fixed;  // --gnss-latency-s: exact by definition
  fixed.fixed = true;
  fixed.applied_s = fixed.estimate_s = 0.05;
  fixed.applied_sigma_s = fixed.sigma_s = 0.0;
  widen_latency_sigma(fixed, 2.0);
  EXPECT_EQ(fixed.applied_sigma_s, 0.0);
  EXPECT_EQ(fixed.sigma_s, 0.0);
  GnssLatencyEstimate uncorrelated = l;
  widen_latency_sigma(uncorrelated, 1.0);
  EXPECT_EQ(uncorrelated.sigma_s, l.sigma_s);
}

}  // namespace
}  // namespace odonav::identification
