// Dead reckoning right from its first metre: provisional misalignment and K are applied as soon as
// their sigma says they beat the nominal values (consumer_rules.hpp), in odonav-offline's chain with
// the default parameters, against the simulator's truth (sim:terrain, fixed seeds).
#include <gtest/gtest.h>

#include <cmath>

#include "odonav/simulator/simulator.hpp"
#include "odonav/config.hpp"
#include "odonav/dataset.hpp"
#include "odonav/identification/identification_options.hpp"
#include "odonav/offline/first_metres.hpp"
#include "odonav/offline/offline_runner.hpp"
#include "offline_test_params.hpp"
#include "odonav/offline/summary.hpp"

using namespace odonav;
using namespace odonav::offline;
using namespace odonav::offline::test;
using nlohmann::json;

namespace {

simulator::SimulationConfig terrain_config(uint64_t seed) {
  simulator::SimulationConfig cfg = simulator::scenario_config("terrain");
  cfg.seed = seed;
  return cfg;
}

Dataset terrain(uint64_t seed, double k_true_m_per_pulse = 0.0) {
  simulator::SimulationConfig cfg = terrain_config(seed);
  if (k_true_m_per_pulse > 0.0) cfg.k_true_m_per_pulse = k_true_m_per_pulse;
  return simulator::simulate(cfg);
}

// odonav-offline's chain with the default parameters on d, evaluated against d's truth; the figures
// go to the test's XML report.
FirstMetres measure(const Dataset& d) {
  const FirstMetres f = evaluate_first_metres(d, run_offline(d, user_params(d)).dr_online);
  ::testing::Test::RecordProperty("figures", describe(f));
  return f;
}

}  // namespace

TEST(FirstMetre, TerrainSeed1DeadReckoningMeetsTheFinalGoal) {
  const Dataset d = terrain(1);
  const FirstMetres f = measure(d);
  SCOPED_TRACE(describe(f));
  // Measured 0.0443 %D with the track slip in turns removed (0.0507 %D without it, 0.082 %D when
  // only converged estimates were applied): the goal is 0.05 %D. Of the 0.9 m that slip had put
  // into this seed's 4.1 m, the fitted slip gain (0.054 s/rad against the simulator's 0.05) takes
  // 0.5 m out (docs/DESIGN_DECISIONS.md).
  EXPECT_LE(f.final_percent, 0.05);
  // The K (1.5 % off the nominal) is taken after 11 m of odometer distance instead of 59 m.
  EXPECT_LE(f.distance_on_nominal_k_m, 20.0);
  // Max after 500 m: 0.30 %D, of which the start offset (1.7 m of GNSS noise at the first fix) is
  // most; without it 0.074 %D (before: 0.34 %D). The 0.1 %D goal is met for the drift only:
  // an origin from the mean of the 5 s of standstill fixes would give 0.257 %D (1.50 m off), one
  // from every fix of the first 500 m 0.346 %D (1.96 m off); see AnRtkStartMeetsTheMaxAfter500mGoal.
  EXPECT_LE(f.drift_max_after_500m_percent, 0.1);
  EXPECT_LE(f.max_after_500m_percent, 0.35);
}

TEST(FirstMetre, AnRtkStartMeetsTheMaxAfter500mGoal) {
  // The max %D after 500 m is mostly the start fix's error: the simulator's GNSS error is 1.4 m per
  // axis of Gauss-Markov noise correlated over 60 s, which no origin built from the fixes of the
  // first minute averages away (BENCHMARKS.md §4.1). What does meet the goal is a start fix of
  // centimetres: the same drive with RTK-grade positions (the slow robot's 1 cm + 1 cm), the DR
  // unchanged.
  simulator::SimulationConfig cfg = terrain_config(1);
  cfg.gnss_pos_gm_std_m = 0.01;
  cfg.gnss_pos_white_std_m = 0.01;
  const Dataset d = simulator::simulate(cfg);
  const FirstMetres f = measure(d);
  SCOPED_TRACE(describe(f));
  EXPECT_LE(f.start_offset_m, 0.1);
  EXPECT_LE(f.max_after_500m_percent, 0.1);
  EXPECT_LE(f.final_percent, 0.05);
}

TEST(FirstMetre, NominalKHundredPercentWrongCostsOnlyTheFirstMetres) {
  const Dataset d = terrain(1, 0.025);  // true K twice the nominal 0.0125
  const FirstMetres f = measure(d);
  SCOPED_TRACE(describe(f));
  // Measured 0.049 %D (0.86 %D when the DR waited 14 s for a converged K): goal 0.1 %D.
  EXPECT_LE(f.final_percent, 0.1);
  // Identified K from about 5 m of odometer distance on (before: 75 m).
  EXPECT_LE(f.distance_on_nominal_k_m, 10.0);
}

TEST(FirstMetre, ARightNominalIsNotReplacedByAnEarlyNoisyK) {
  // With the nominal equal to the true K nothing is gained by switching K early, and no provisional
  // K is taken (the first identified K comes after 54 m, converged); the early misalignment still
  // helps: measured 0.038 %D final, 0.078 % drift max after 500 m (converged-only rules: 0.078 %D,
  // 0.25 %).
  // The premise, a nominal known to be right, declared as such (0.3 %): with the default 3 % the
  // rule that takes a K known better than the nominal (consumer_rules.hpp) takes one within the
  // first tens of metres, as it should when the nominal is as uncertain as declared.
  const Dataset d = terrain(2, 0.0125);
  OfflineParams p = user_params(d);
  p.dead_reckoning.nominal_k_rel_sigma = 0.003;
  const FirstMetres f = evaluate_first_metres(d, run_offline(d, p).dr_online);
  SCOPED_TRACE(describe(f));
  EXPECT_LE(f.final_percent, 0.05);
  EXPECT_LE(f.drift_max_after_500m_percent, 0.1);
  EXPECT_GE(f.distance_on_nominal_k_m, 40.0);
}
