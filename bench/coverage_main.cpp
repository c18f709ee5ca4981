// odonav-bench-coverage: are the published sigmas honest? For every scenario and seed, simulates
// the drive in memory, runs the offline chain as odonav-offline does (run_offline with a user's
// defaults), and counts, per published quantity (K, misalignment heading and pitch, GNSS latency, the
// anchored position per axis), how many of its estimates lie within 1, 2 and 3 of their published
// sigmas of the truth, and their mean normalised error squared (evaluate_coverage, coverage.hpp);
// then the same on the shipped real recording (tests/data/smartloc-berlin: K against the ratio of
// reference distance to pulses, the position against the reference fixes it has not used yet).
// Also, as a diagnosis: K without the estimates of the 20 s after each simulated K step (the lag of
// a tracking estimator, which its sigma does not describe), and the GNSS latency's online estimate
// against its own sigma (the published latency is the one in force, which lags it).
//
// It is a benchmark, not a test: it prints figures (Markdown tables, BENCHMARKS.md §11) and gates
// nothing. One process, one thread. Options: --seeds N, --first-seed S, --scenarios, --real DIR.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iomanip>
#include <iostream>
#include <limits>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "bench_scenarios.hpp"
#include "odonav/offline/coverage.hpp"
#include "odonav/calibration/calibration_options.hpp"
#include "odonav/config.hpp"
#include "odonav/dataset.hpp"
#include "odonav/logging.hpp"
#include "odonav/offline/offline_runner.hpp"
#include "reference_k.hpp"

namespace {

using odonav::offline::Coverage;
using odonav::offline::QuantityCoverage;

// One quantity in one scenario, over the seeds: pooled counts, and each seed's fraction within 2
// sigma (its worst seed says what a test on a few seeds may bound).
struct Pooled {
  Coverage all, converged;
  double worst_seed_within_2 = std::numeric_limits<double>::quiet_NaN();
  double worst_seed_converged_within_2 = std::numeric_limits<double>::quiet_NaN();
  void add(const QuantityCoverage& q) {
    all.merge(q.all);
    converged.merge(q.converged);
    const auto worst = [](double& w, const Coverage& c) {
      if (c.n > 0 && !(w <= c.fraction_within(2))) w = c.fraction_within(2);
    };
    worst(worst_seed_within_2, q.all);
    worst(worst_seed_converged_within_2, q.converged);
  }
};

std::string percent(double fraction) {
  if (!std::isfinite(fraction)) return "-";
  std::ostringstream o;
  o << std::fixed << std::setprecision(1) << 100.0 * fraction;
  return o.str();
}

std::string number(double v) {
  if (std::isnan(v)) return "-";
  if (std::isinf(v)) return "inf";
  std::ostringstream o;
  o << std::setprecision(3) << v;
  return o.str();
}

std::string cells(const Coverage& c, double worst_seed_within_2) {
  std::ostringstream o;
  o << c.n << " | " << percent(c.fraction_within(1)) << " | " << percent(c.fraction_within(2)) << " | "
    << percent(c.fraction_within(3)) << " | " << number(c.mean_nees()) << " | " << number(c.max_abs_z) << " | "
    << percent(worst_seed_within_2);
  return o.str();
}

// The diagnosis: the latency's online estimate (not the one in force) against its own sigma.
QuantityCoverage latency_estimate_coverage(const odonav::offline::OfflineResult& r, double latency_true_s) {
  QuantityCoverage q{"GNSS latency, online estimate", {}, {}};
  for (const odonav::identification::IdentificationOutput& o : r.identification) {
    if (o.latency.sigma_s < 0.0) continue;
    q.all.add(o.latency.estimate_s - latency_true_s, o.latency.sigma_s);
    if (o.main.converged) q.converged.add(o.latency.estimate_s - latency_true_s, o.latency.sigma_s);
  }
  return q;
}

// K without the rows of the settle_s after each K step of the simulation.
QuantityCoverage k_outside_steps(const odonav::Dataset& d, const odonav::results::OutputRows& rows,
                                 const odonav::simulator::SimulationConfig& cfg, double settle_s) {
  odonav::results::OutputRows kept;
  for (const odonav::results::ScaleFactorRow& r : rows.scale_factor) {
    const bool settling = std::any_of(cfg.k_steps.begin(), cfg.k_steps.end(), [&](const odonav::simulator::KStep& st) {
      const double t_step_s = cfg.start_time_s + st.t_s;
      return r.t_s >= t_step_s && r.t_s < t_step_s + settle_s;
    });
    if (!settling) kept.scale_factor.push_back(r);
  }
  for (const QuantityCoverage& q : odonav::offline::evaluate_coverage(d, kept))
    if (q.quantity == "K") return {"K, not within 20 s after a K step", q.all, q.converged};
  return {};
}

}  // namespace

int main(int argc, char** argv) {
  odonav::Options opts("odonav-bench-coverage",
                       "Sigma coverage benchmark: per published quantity and scenario, the fraction of estimates "
                       "within 1, 2, 3 published sigmas of the truth and the mean NEES, over several seeds and on "
                       "a real recording. Prints Markdown tables. Not a test.");
  odonav::bench::add_scenario_bench_options(
      opts, "terrain,terrain+1hz,terrain+lat100,terrain+1hz+lat100,slow_robot,straight",
      "comma-separated scenarios; variants: +<N>hz (GNSS rate), +lat<ms> (GNSS latency)");
  opts.add_string("real", ODONAV_SOURCE_DIR "/tests/data/smartloc-berlin",
                  "a recorded dataset without truth.csv to evaluate too (empty: none)");
  odonav::offline::OfflineParams base;
  if (const auto status = odonav::bench::parse_scenario_bench(opts, argc, argv, "bench-coverage", base)) return *status;
  const odonav::bench::ScenarioRuns runs = odonav::bench::scenario_runs(opts);

  try {
    const auto t0 = std::chrono::steady_clock::now();
    // quantity -> scenario -> pooled over seeds; the order of first appearance kept for printing.
    std::map<std::string, std::map<std::string, Pooled>> table;
    std::vector<std::string> quantities;
    const auto add = [&](const QuantityCoverage& q, const std::string& scenario) {
      if (std::find(quantities.begin(), quantities.end(), q.quantity) == quantities.end())
        quantities.push_back(q.quantity);
      table[q.quantity][scenario].add(q);
    };
    // A seed whose estimates of a quantity mostly miss their 3 sigma is named, so it can be rerun
    // alone (odonav-sim --scenario ... --seed S): a pooled figure hides a single bad drive. (Within
    // one drive the errors of an estimate move together, so an honest sigma still leaves about 5 %
    // of drives mostly outside 2 sigma, but hardly any mostly outside 3.)
    const auto add_seed = [&](const QuantityCoverage& q, const std::string& scenario, uint64_t seed) {
      add(q, scenario);
      if (q.all.n > 0 && q.all.fraction_within(3) < 0.5)
        std::cerr << "seed " << seed << ", " << scenario << ": " << q.quantity << " "
                  << percent(q.all.fraction_within(3)) << " % of " << q.all.n
                  << " estimates within 3 sigma (max |error| / sigma " << number(q.all.max_abs_z) << ")\n";
    };
    for (uint64_t seed = runs.first_seed; seed < runs.first_seed + runs.seeds; ++seed) {
      for (const std::string& scenario : runs.scenarios) {
        const odonav::Dataset d = odonav::bench::simulate(scenario, seed);
        const odonav::offline::OfflineParams p = odonav::bench::params_for(d, base, opts);
        const odonav::offline::OfflineResult r = odonav::offline::run_offline(d, p);
        const auto rows = odonav::offline::to_output_rows(r, p.identification.estimator_name);
        for (const QuantityCoverage& q : odonav::offline::evaluate_coverage(d, rows)) add_seed(q, scenario, seed);
        const odonav::simulator::SimulationConfig cfg = odonav::bench::scenario_variant(scenario);
        if (!cfg.k_steps.empty()) add_seed(k_outside_steps(d, rows, cfg, 20.0), scenario, seed);
        add_seed(latency_estimate_coverage(r, cfg.gnss_latency_s), scenario, seed);
      }
      std::cerr << "seed " << seed << " done ("
                << std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() << " s)\n";
    }
    std::string real_name;
    if (!opts.get_string("real").empty()) {
      const odonav::Dataset d = odonav::read_dataset(opts.get_string("real"), odonav::BadRowPolicy::kFail);
      real_name = d.meta.vehicle_id.empty() ? "real" : d.meta.vehicle_id;
      const odonav::offline::OfflineParams p = odonav::bench::params_for(d, base, opts);
      const odonav::offline::OfflineResult r = odonav::offline::run_offline(d, p);
      odonav::offline::CoverageOptions co;
      co.k_reference_m_per_pulse = odonav::test::reference_k_m_per_pulse(d);
      co.hold_off_s = p.dead_reckoning.estimate_hold_off_s;
      for (const QuantityCoverage& q : odonav::offline::evaluate_coverage(
               d, odonav::offline::to_output_rows(r, p.identification.estimator_name), co))
        add(q, real_name);
    }

    std::cout << "## Sigma coverage (simulator truth, seeds " << runs.first_seed << ".."
              << runs.first_seed + runs.seeds - 1;
    if (!real_name.empty()) std::cout << "; " << real_name << " against its reference";
    std::cout
        << ")\n\nPer quantity and scenario: estimates with a published sigma from the first one (n), % of "
           "|error| within 1 / 2 / 3 sigma (honest: 68.3 / 95.4 / 99.7), mean NEES (honest: 1), the largest "
           "|error| / sigma, and the worst seed's % within 2 sigma; then the same for the rows flagged "
           "converged (GNSS latency: K converged; position: anchored). 'all sim' pools the simulated "
           "scenarios.\n\n"
        << "| quantity | scenario | n | 1σ | 2σ | 3σ | NEES | max | worst seed 2σ | converged n | 1σ | 2σ | 3σ | NEES | max "
           "| worst seed 2σ |\n"
        << "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    for (const std::string& quantity : quantities) {
      Pooled pooled_sim;
      for (const std::string& scenario : runs.scenarios) {
        const auto it = table[quantity].find(scenario);
        if (it == table[quantity].end()) continue;
        const Pooled& c = it->second;
        pooled_sim.all.merge(c.all);
        pooled_sim.converged.merge(c.converged);
        std::cout << "| " << quantity << " | " << scenario << " | " << cells(c.all, c.worst_seed_within_2) << " | "
                  << cells(c.converged, c.worst_seed_converged_within_2) << " |\n";
      }
      if (pooled_sim.all.n > 0)
        std::cout << "| " << quantity << " | all sim | " << cells(pooled_sim.all, std::nan("")) << " | "
                  << cells(pooled_sim.converged, std::nan("")) << " |\n";
      const auto real = table[quantity].find(real_name);
      if (!real_name.empty() && real != table[quantity].end())
        std::cout << "| " << quantity << " | " << real_name << " | " << cells(real->second.all, std::nan("")) << " | "
                  << cells(real->second.converged, std::nan("")) << " |\n";
    }
    std::cout << "\n(run time " << std::fixed << std::setprecision(1)
              << std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() << " s)\n";
  } catch (const std::exception& e) {
    std::cerr << "odonav-bench-coverage: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
