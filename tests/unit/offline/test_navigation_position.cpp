// The GNSS-anchored navigation position (anchored_position.hpp) through odonav-offline's chain on
// the simulator's terrain drive, against the simulator's truth: better than the GNSS fixes while
// GNSS is valid at 1, 5, 10 and 20 Hz, across the 120 s outage within its start error plus 0.1 %
// of the outage distance, with a receiver latency, and through minutes without GNSS.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "odonav/simulator/simulator.hpp"
#include "odonav/dataset.hpp"
#include "odonav/frames.hpp"
#include "odonav/offline/offline_runner.hpp"
#include "offline_test_params.hpp"

using namespace odonav;
using namespace odonav::offline;
using namespace odonav::offline::test;

namespace {

// Truth (INS reference point) interpolated at t_s, in the local ENU frame; and the attitude of the
// nearer sample (for the antenna's truth).
struct TruthAt {
  Eigen::Vector3d enu_m;
  Attitude attitude;
};

class Truth {
 public:
  Truth(const Dataset& d, const LocalEnuFrame& frame) : d_(d), frame_(frame) {}
  TruthAt at(double t_s) {
    const auto& tr = d_.truth;
    if (tr[i_].t_s > t_s) i_ = 0;  // asked for an earlier time: search again from the start
    while (i_ + 1 < tr.size() && tr[i_ + 1].t_s <= t_s) ++i_;
    const std::size_t j = std::min(i_ + 1, tr.size() - 1);
    const Eigen::Vector3d a = frame_.to_enu(tr[i_].position), b = frame_.to_enu(tr[j].position);
    const double f = j == i_ ? 0.0 : (t_s - tr[i_].t_s) / (tr[j].t_s - tr[i_].t_s);
    return {a + f * (b - a), f < 0.5 ? tr[i_].attitude : tr[j].attitude};
  }

 private:
  const Dataset& d_;
  const LocalEnuFrame& frame_;
  std::size_t i_ = 0;
};

double horizontal(const Eigen::Vector3d& v) { return v.head<2>().norm(); }

struct Figures {
  double nav_rms_valid_m = 0.0;  ///< anchored position vs truth while GNSS valid (after the first 60 s)
  double gnss_rms_m = 0.0;       ///< GNSS fixes (antenna) vs truth antenna, same span
  double dr_rms_valid_m = 0.0;   ///< pure DR, same span
  double outage_start_error_m = 0.0, outage_end_error_m = 0.0;
  double outage_dr_growth_m = 0.0, outage_distance_m = 0.0;
  double sigma_start_m = 0.0, sigma_end_m = 0.0;  ///< reported horizontal one-sigma across the outage
  std::size_t rejected = 0, applied = 0;
};

// latency_s: the simulator stamps the fixes this late (the chain estimates it; the DR compares each
// fix with the DR at stamp - latency).
Figures figures(uint64_t seed, double gnss_rate_hz = 10.0, double latency_s = 0.0) {
  simulator::SimulationConfig cfg = simulator::scenario_config("terrain");
  cfg.seed = seed;
  cfg.gnss_rate_hz = gnss_rate_hz;
  cfg.gnss_latency_s = latency_s;
  const Dataset d = simulator::simulate(cfg);
  const OfflineResult r = run_offline(d, default_params(d));
  EXPECT_EQ(r.navigation_position.size(), r.dr_online.size());
  const LocalEnuFrame frame(d.truth.front().position);
  Truth truth(d, frame);
  const simulator::GnssOutage outage = cfg.gnss_outages.at(0);
  const double t0 = d.truth.front().t_s;
  const double settle_s = 60.0;  // identification and calibration converge first

  Figures f;
  double nav2 = 0.0, dr2 = 0.0;
  std::size_t n = 0;
  // Across the outage: the last sample before its start and the last before GNSS is applied again.
  std::size_t i_start = 0, i_end = 0;
  for (std::size_t i = 0; i < r.navigation_position.size(); ++i) {
    const dead_reckoning::AnchoredPosition& p = r.navigation_position[i];
    const dead_reckoning::DeadReckoningOutput& dr = r.dr_online[i];
    const double t = p.t_s - t0;
    if (t < outage.start_s) i_start = i;
    if (t < outage.end_s + 0.2) i_end = i;
    if (t < settle_s || (t >= outage.start_s && t < outage.end_s + 1.0) ||
        p.status != dead_reckoning::AnchorStatus::kAnchored)
      continue;
    const Eigen::Vector3d tr = truth.at(p.t_s).enu_m;
    nav2 += std::pow(horizontal(frame.to_enu(p.position) - tr), 2);
    dr2 += std::pow(horizontal(frame.to_enu(dr.position) - tr), 2);
    ++n;
  }
  f.nav_rms_valid_m = std::sqrt(nav2 / n);
  f.dr_rms_valid_m = std::sqrt(dr2 / n);

  double g2 = 0.0;
  std::size_t m = 0;
  const Eigen::Vector3d lever = *d.meta.gnss_lever_arm_m;
  for (const GnssSample& g : d.gnss) {
    const double t = g.t_s - t0;
    if (!g.valid() || t < settle_s) continue;
    const TruthAt tr = truth.at(g.t_s - latency_s);  // where the antenna was when it measured
    const Eigen::Vector3d antenna = tr.enu_m + body_to_enu(tr.attitude) * lever;
    g2 += std::pow(horizontal(frame.to_enu(g.position) - antenna), 2);
    ++m;
  }
  f.gnss_rms_m = std::sqrt(g2 / m);

  const auto err = [&](std::size_t i) -> Eigen::Vector3d {
    const TruthAt tr = truth.at(r.navigation_position[i].t_s);
    const Eigen::Vector3d position = frame.to_enu(r.navigation_position[i].position);
    return position - tr.enu_m;
  };
  f.outage_start_error_m = horizontal(err(i_start));
  f.outage_end_error_m = horizontal(err(i_end));
  const Eigen::Vector3d dr_move =
      frame.to_enu(r.dr_online[i_end].position) - frame.to_enu(r.dr_online[i_start].position);
  const Eigen::Vector3d true_move = truth.at(r.dr_online[i_end].t_s).enu_m - truth.at(r.dr_online[i_start].t_s).enu_m;
  f.outage_dr_growth_m = horizontal(dr_move - true_move);
  f.outage_distance_m = r.dr_online[i_end].distance_m - r.dr_online[i_start].distance_m;
  EXPECT_EQ(r.navigation_position[i_end].status, dead_reckoning::AnchorStatus::kDeadReckoning);
  // From the last fix, at most one GNSS period (1 s, up to 15 m) before the last sample before the outage.
  EXPECT_NEAR(r.navigation_position[i_end].distance_since_fix_m, f.outage_distance_m, 16.0);
  f.applied = r.anchored_counters.fixes_applied;
  f.sigma_start_m = r.navigation_position[i_start].horizontal_sigma_m();
  f.sigma_end_m = r.navigation_position[i_end].horizontal_sigma_m();
  f.rejected = r.anchored_counters.fixes_rejected_gate;
  return f;
}

void print(const char* what, uint64_t seed, const Figures& f) {
  std::printf(
      "%s seed %llu: anchored RMS %.3f m, GNSS RMS %.3f m (ratio %.2f), pure DR RMS %.3f m (GNSS valid, after "
      "60 s); outage %.1f m: error %.3f -> %.3f m (goal <= %.3f; sigma %.3f -> %.3f m), pure DR growth %.3f m; "
      "fixes applied %zu, rejected %zu\n",
      what, static_cast<unsigned long long>(seed), f.nav_rms_valid_m, f.gnss_rms_m, f.nav_rms_valid_m / f.gnss_rms_m,
      f.dr_rms_valid_m, f.outage_distance_m, f.outage_start_error_m, f.outage_end_error_m,
      f.outage_start_error_m + 0.001 * f.outage_distance_m, f.sigma_start_m, f.sigma_end_m, f.outage_dr_growth_m,
      f.applied, f.rejected);
}

// The covariance is honest: the RMS error is within a factor 2 of the reported sigma, and the sigma
// grows across the outage.
void expect_honest_sigma(const Figures& f) {
  EXPECT_LT(f.nav_rms_valid_m, 2.0 * f.sigma_start_m);
  EXPECT_GT(f.nav_rms_valid_m, 0.5 * f.sigma_start_m);
  EXPECT_GT(f.sigma_end_m, f.sigma_start_m);
}

}  // namespace

// 10 Hz, seeds 1-5: 0.49-0.72 x the fixes' RMS (the filter averages the correlated GNSS error, a
// state, over minutes), the outage within the goal (its end error at most 0.29 m above its start
// over 741 m, goal 0.74 m).
TEST(NavigationPosition, TerrainBeatsGnssWhileValidAndBridgesTheOutageFromTheLastFix) {
  for (uint64_t seed = 1; seed <= 5; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const Figures f = figures(seed);
    print("10 Hz", seed, f);
    EXPECT_LT(f.nav_rms_valid_m, 0.8 * f.gnss_rms_m);
    EXPECT_GT(f.outage_distance_m, 500.0);
    // Issue goal: the end of the outage within its start error plus 0.1 % of the outage distance.
    EXPECT_LE(f.outage_end_error_m, f.outage_start_error_m + 0.001 * f.outage_distance_m);
    expect_honest_sigma(f);
    EXPECT_EQ(f.rejected, 0u);
  }
}

// At 1 Hz the chain's own DR is poorer (pure DR RMS 2.4 m on seed 1, 4.0 m on seed 2) and there
// are a tenth of the fixes: 0.53 x the fixes' RMS on both seeds, the outage goal met (0.65 -> 0.71
// and 0.39 -> 0.59 m over 741 m, goal + 0.74 m).
TEST(NavigationPosition, AtOneHertzGnssItBeatsTheFixesAndBridgesTheOutage) {
  for (uint64_t seed = 1; seed <= 2; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const Figures f = figures(seed, 1.0);
    print("1 Hz", seed, f);
    EXPECT_LT(f.nav_rms_valid_m, f.gnss_rms_m);
    EXPECT_LE(f.nav_rms_valid_m, f.dr_rms_valid_m + 0.01);
    if (f.dr_rms_valid_m > 3.0) {
      EXPECT_LT(f.nav_rms_valid_m, 0.5 * f.dr_rms_valid_m);
    }
    EXPECT_LE(f.outage_end_error_m, f.outage_start_error_m + 0.001 * f.outage_distance_m);
    expect_honest_sigma(f);
  }
}

// 5 and 20 Hz (seed 1): 0.67 and 0.53 x the fixes' RMS, the outage goal met. The filter's
// information per second does not depend on the rate: the correlated GNSS error is a state.
TEST(NavigationPosition, AtFiveAndTwentyHertzGnssItBeatsTheFixesAndBridgesTheOutage) {
  for (double rate_hz : {5.0, 20.0}) {
    SCOPED_TRACE(std::to_string(rate_hz) + " Hz");
    const Figures f = figures(1, rate_hz);
    print(rate_hz == 5.0 ? "5 Hz" : "20 Hz", 1, f);
    EXPECT_LT(f.nav_rms_valid_m, 0.8 * f.gnss_rms_m);
    EXPECT_LE(f.outage_end_error_m, f.outage_start_error_m + 0.001 * f.outage_distance_m);
    expect_honest_sigma(f);
  }
}

// Fixes stamped 0.1 s after they measured (odonav-simulator --gnss-latency-s 0.1), 10 Hz, seed 1: the
// identification estimates the latency and the DR hands the filter each fix with the DR at stamp -
// latency, so the navigation position is what it is without a latency.
TEST(NavigationPosition, AFixStampedLateIsComparedWithTheDrWhenItMeasured) {
  const Figures late = figures(1, 10.0, 0.1);
  const Figures none = figures(1, 10.0, 0.0);
  print("10 Hz, latency 0.1 s", 1, late);
  print("10 Hz, no latency", 1, none);
  EXPECT_NEAR(late.nav_rms_valid_m, none.nav_rms_valid_m, 0.1);
  EXPECT_LT(late.nav_rms_valid_m, 0.6 * late.gnss_rms_m);
  EXPECT_LE(late.outage_end_error_m, late.outage_start_error_m + 0.001 * late.outage_distance_m);
}

// GNSS absent for over three minutes (290-490 s, 2.3 km between the simulator's K steps), 10 Hz,
// seed 1: the status says dead reckoning from 2.5 s after the last fix, the sigma stays above its
// value at the outage's start and covers the error (1.5 m against 2.5 m at the end), and
// when GNSS returns the position moves by no more than the first fix says. Not covered: a K step
// inside the outage (the +3 % at 250 s within a 200-500 s outage gives 13.8 m after 725 m with a
// sigma of 1.9 m): no GNSS, no identification, and the filter's scale walk is for slow changes.
TEST(NavigationPosition, MinutesWithoutGnssGrowTheSigmaSayDeadReckoningAndReturnWithoutAJump) {
  simulator::SimulationConfig cfg = simulator::scenario_config("terrain");
  cfg.seed = 1;
  cfg.gnss_outages = {simulator::GnssOutage{290.0, 490.0}};
  const Dataset d = simulator::simulate(cfg);
  const OfflineResult r = run_offline(d, default_params(d));
  const LocalEnuFrame frame(d.truth.front().position);
  Truth truth(d, frame);
  const double t0 = d.truth.front().t_s;
  const auto error = [&](std::size_t i) {
    return horizontal(frame.to_enu(r.navigation_position[i].position) - truth.at(r.navigation_position[i].t_s).enu_m);
  };
  double previous_sigma_m = 0.0;
  std::size_t last_before_return = 0, checked = 0;
  for (std::size_t i = 0; i < r.navigation_position.size(); ++i) {
    const dead_reckoning::AnchoredPosition& p = r.navigation_position[i];
    const double t = p.t_s - t0;
    if (t > 293.0 && p.last_fix_t_s - t0 < 290.0) {  // bridging
      ASSERT_EQ(p.status, dead_reckoning::AnchorStatus::kDeadReckoning) << t;
      if (previous_sigma_m == 0.0) previous_sigma_m = p.horizontal_sigma_m();
      ASSERT_GE(p.horizontal_sigma_m(), previous_sigma_m) << t;
      ASSERT_LT(error(i), 3.0 * p.horizontal_sigma_m()) << t;
      last_before_return = i;
      ++checked;
    }
  }
  ASSERT_GT(checked, 19000u);  // ~197 s at 100 Hz
  const std::size_t b = last_before_return, a = b + 1;
  const dead_reckoning::AnchoredPosition& before = r.navigation_position[b];
  const dead_reckoning::AnchoredPosition& after = r.navigation_position[a];
  const Eigen::Vector3d dr_move = frame.to_enu(r.dr_online[a].position) - frame.to_enu(r.dr_online[b].position);
  const double jump_m = horizontal(frame.to_enu(after.position) - frame.to_enu(before.position) - dr_move);
  std::printf(
      "200 s without GNSS (%.0f m): error %.3f m (sigma %.3f m) before GNSS returns, %.3f m after its first "
      "fix (jump %.3f m, sigma %.3f m)\n",
      before.distance_since_fix_m, error(b), before.horizontal_sigma_m(), error(a), jump_m, after.horizontal_sigma_m());
  EXPECT_EQ(after.status, dead_reckoning::AnchorStatus::kAnchored);
  EXPECT_GT(before.horizontal_sigma_m(), 1.2 * r.navigation_position[b - 19000].horizontal_sigma_m());
  // The jump is a fraction of the discrepancy the fix shows (error before + the fix's own error).
  EXPECT_LT(jump_m, error(b) + 3.0 * 1.5);
  EXPECT_LT(after.horizontal_sigma_m(), before.horizontal_sigma_m());
}
