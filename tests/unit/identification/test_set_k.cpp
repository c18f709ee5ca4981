// IdentificationCore::set_k on a simulated straight drive (fixed seed, truth K known): the commanded
// K is reported exactly at once and held exactly while frozen, counters are kept, the window starts
// again, and after unfreezing the identification converges back to the true K from the commanded one.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "odonav/simulator/simulator.hpp"
#include "odonav/identification/identification_core.hpp"

namespace {

using namespace odonav;
using namespace odonav::identification;

constexpr double kNominalK = 0.0125;  // m/pulse

/// 120 s of the straight scenario (start standing, then 10 m/s): K_true = 0.0125 x 1.015.
const Dataset& drive() {
  static const Dataset d = [] {
    simulator::SimulationConfig cfg = simulator::scenario_config("straight");
    cfg.duration_s = 120.0;
    return simulator::simulate(cfg);
  }();
  return d;
}

double true_k() { return simulator::scenario_config("straight").k_true_m_per_pulse; }

/// Core fed with every sample of the drive (processing happens in process_until).
IdentificationCore fed_core(const std::string& estimator) {
  IdentificationParams p;
  p.estimator_name = estimator;
  IdentificationCore core(p);
  for (const auto& o : drive().odometer) core.add_odometer(o);
  for (const auto& g : drive().gnss) core.add_gnss(g);
  for (const auto& i : drive().ins) core.add_ins(i);
  return core;
}

TEST(SetK, CommandedKProblemNamesTheValueAndTheRange) {
  EXPECT_FALSE(IdentificationCore::commanded_k_problem(0.0126, kNominalK));
  EXPECT_FALSE(IdentificationCore::commanded_k_problem(0.125, kNominalK));    // exactly 10x
  EXPECT_FALSE(IdentificationCore::commanded_k_problem(0.00125, kNominalK));  // exactly 0.1x
  for (double bad : {0.0, -0.0125, std::nan(""), std::numeric_limits<double>::infinity()}) {
    const auto why = IdentificationCore::commanded_k_problem(bad, kNominalK);
    ASSERT_TRUE(why) << bad;
    EXPECT_NE(why->find("is not finite and > 0"), std::string::npos) << *why;
  }
  const auto too_big = IdentificationCore::commanded_k_problem(0.126, kNominalK);
  ASSERT_TRUE(too_big);
  EXPECT_NE(too_big->find("K = 0.126 m/pulse is outside [0.1, 10] x nominal K (0.0125 m/pulse)"), std::string::npos)
      << *too_big;
  EXPECT_TRUE(IdentificationCore::commanded_k_problem(0.00124, kNominalK));
  EXPECT_TRUE(IdentificationCore::commanded_k_problem(0.0125, 0.0));  // a bad nominal is named too
}

TEST(SetK, RejectsNonFiniteValuesWithoutChangingTheEstimate) {
  IdentificationCore core = fed_core("vff_lm_rls");
  const auto before = core.process_until(60.0);
  ASSERT_FALSE(before.empty());
  EXPECT_THROW(core.set_k(std::nan(""), 60.0), std::invalid_argument);
  EXPECT_THROW(core.set_k(-1.0, 60.0), std::invalid_argument);
  EXPECT_THROW(core.set_k(0.0125, std::numeric_limits<double>::infinity()), std::invalid_argument);
  EXPECT_EQ(core.main_estimator().estimate().k_m_per_pulse, before.back().main.k_m_per_pulse);
  EXPECT_FALSE(core.commanded_k_m_per_pulse());
}

TEST(SetK, ReseedsAtTheCommandedKHoldsItFrozenAndConvergesBackAfterwards) {
  IdentificationCore core = fed_core("vff_lm_rls");
  const auto first = core.process_until(60.0);
  ASSERT_FALSE(first.empty());
  const IdentificationOutput& last = first.back();
  ASSERT_TRUE(last.main.valid && last.main.converged);
  EXPECT_NEAR(last.main.k_m_per_pulse / true_k(), 1.0, 2e-3);  // identified before the command
  const std::size_t window_before = static_cast<std::size_t>(last.main.window_fill * 100.0 + 0.5);
  EXPECT_EQ(window_before, 100u) << "the default window (100 samples) was full";

  // Command 2 % above the truth, frozen first: the published K must be exactly the command.
  const double commanded = true_k() * 1.02;
  core.freeze();
  const IdentificationOutput now = core.set_k(commanded, last.t_s);
  EXPECT_EQ(now.t_s, last.t_s);
  EXPECT_TRUE(now.main.valid);
  EXPECT_EQ(now.main.k_m_per_pulse, commanded);
  EXPECT_FALSE(now.main.converged) << "one pseudo-sample is not a converged estimate";
  EXPECT_DOUBLE_EQ(now.main.window_fill, 1.0 / 100.0) << "window cleared, then the seed only";
  EXPECT_EQ(now.samples_accepted, last.samples_accepted) << "counters are kept";
  EXPECT_EQ(now.samples_rejected, last.samples_rejected);
  EXPECT_TRUE(now.frozen);
  ASSERT_TRUE(core.commanded_k_m_per_pulse());
  EXPECT_EQ(*core.commanded_k_m_per_pulse(), commanded);

  const auto frozen = core.process_until(80.0);
  ASSERT_GT(frozen.size(), 150u);  // 20 s of 10 Hz epochs
  for (const auto& o : frozen) {
    EXPECT_EQ(o.main.k_m_per_pulse, commanded) << "t=" << o.t_s;
    EXPECT_EQ(o.samples_accepted, last.samples_accepted) << "no sample used while frozen";
  }

  // Unfrozen: the identification continues from the commanded K and finds the truth again within
  // a window (10 s); the first update moves off the command towards the data.
  core.unfreeze();
  const auto resumed = core.finish();
  ASSERT_GT(resumed.size(), 300u);
  const auto first_update = std::find_if(resumed.begin(), resumed.end(), [&](const IdentificationOutput& o) {
    return o.samples_accepted > last.samples_accepted;
  });
  ASSERT_NE(first_update, resumed.end());
  EXPECT_LT(std::abs(first_update->main.k_m_per_pulse / true_k() - 1.0), 0.02)
      << "the first real sample outweighs the one-pulse seed";
  EXPECT_NEAR(resumed.back().main.k_m_per_pulse / true_k(), 1.0, 2e-3);
  EXPECT_TRUE(resumed.back().main.converged);
  std::cerr << "K before " << last.main.k_m_per_pulse << ", commanded " << commanded << ", first update "
            << first_update->main.k_m_per_pulse << ", final " << resumed.back().main.k_m_per_pulse << " (true "
            << true_k() << ")\n";
}

TEST(SetK, ResetForgetsTheCommand) {
  IdentificationCore core = fed_core("vff_lm_rls");
  core.process_until(30.0);
  core.set_k(0.013, 30.0);
  core.reset();
  EXPECT_FALSE(core.commanded_k_m_per_pulse());
  EXPECT_FALSE(core.main_estimator().estimate().valid);
}

TEST(SetK, CoarseEstimatorReportsTheCommandUntilItsFirstRun) {
  IdentificationCore core = fed_core("coarse");
  const auto before = core.process_until(5.0);  // standing still: no straight run counted yet
  ASSERT_FALSE(before.empty());
  const IdentificationOutput now = core.set_k(0.0131, before.back().t_s);
  EXPECT_TRUE(now.main.valid);
  EXPECT_EQ(now.main.k_m_per_pulse, 0.0131);
  const auto after = core.finish();
  ASSERT_FALSE(after.empty());
  EXPECT_EQ(after.front().main.k_m_per_pulse, 0.0131);
  // The drive's straight runs then give the coarse estimate of the truth.
  EXPECT_NEAR(after.back().main.k_m_per_pulse / true_k(), 1.0, 5e-3);
}

}  // namespace
