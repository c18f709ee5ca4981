#pragma once
// The simulated scenarios and the parameters of the accuracy benchmarks (odonav-bench-accuracy,
// odonav-bench-coverage): one definition, so both measure the same drives with the defaults a user
// gets.
#include <cstdint>
#include <iostream>
#include <optional>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "odonav/simulator/simulator.hpp"
#include "odonav/calibration/calibration_options.hpp"
#include "odonav/config.hpp"
#include "odonav/consumer_rules.hpp"
#include "odonav/dead_reckoning/dead_reckoning_options.hpp"
#include "odonav/identification/identification_options.hpp"
#include "odonav/lever_arm_option.hpp"
#include "odonav/logging.hpp"
#include "odonav/offline/offline_runner.hpp"

namespace odonav::bench {

// A scenario with variants: "terrain", "terrain+1hz" (GNSS rate), "terrain+lat50" (GNSS latency in
// ms), combinable ("ring+1hz+lat100"). Throws std::invalid_argument naming an unknown modifier.
inline simulator::SimulationConfig scenario_variant(const std::string& spec) {
  std::stringstream parts(spec);
  std::string name;
  std::getline(parts, name, '+');
  simulator::SimulationConfig cfg = simulator::scenario_config(name);
  for (std::string m; std::getline(parts, m, '+');) {
    if (m.size() > 2 && m.compare(m.size() - 2, 2, "hz") == 0) {
      cfg.gnss_rate_hz = std::stod(m.substr(0, m.size() - 2));
    } else if (m.rfind("lat", 0) == 0) {
      cfg.gnss_latency_s = std::stod(m.substr(3)) / 1000.0;
    } else {
      throw std::invalid_argument("scenario '" + spec + "': unknown modifier '" + m + "' (<N>hz or lat<ms>)");
    }
  }
  return cfg;
}

inline Dataset simulate(const std::string& scenario, uint64_t seed) {
  simulator::SimulationConfig cfg = scenario_variant(scenario);
  cfg.seed = seed;
  return simulator::simulate(cfg);
}

// What odonav-offline's main does with a dataset before running (apply_dataset_defaults): the
// lever arm and nominal K from meta.json unless given, dead_reckoner_params for DR and
// identification_params_for with the same vehicle facts, so the bench measures the defaults a user
// gets.
inline offline::OfflineParams params_for(const Dataset& d, offline::OfflineParams p, const Options& opts) {
  dead_reckoning::DeadReckoningFacts facts = dead_reckoning::dead_reckoning_facts_from(opts);
  if (!facts.lever_arm_body_m && d.meta.gnss_lever_arm_m) {
    facts.lever_arm_body_m = d.meta.gnss_lever_arm_m;
    p.calibration.lever_arm_body_m = d.meta.gnss_lever_arm_m;
  }
  facts.use_ins = d.has_ins();
  facts.dataset_nominal_k_m_per_pulse = d.meta.k_nominal_m_per_pulse;
  facts.dataset_nominal_k_sigma_percent = d.meta.k_nominal_sigma_percent;
  p.dead_reckoning = dead_reckoning::dead_reckoner_params(facts);
  identification::IdentificationVehicleFacts vehicle;
  vehicle.use_ins = d.has_ins();
  vehicle.lever_arm_body_m = p.dead_reckoning.lever_arm_body_m;
  vehicle.nominal_k_m_per_pulse = p.dead_reckoning.nominal_k_m_per_pulse;
  vehicle.run_all_estimators = true;
  p.identification = identification::identification_params_for(opts, vehicle);
  p.calibration.use_ins = d.has_ins();
  return p;
}

// The options every benchmark over scenarios takes besides its own: --seeds, --first-seed,
// --scenarios (default_scenarios; help names the variants), --log-level and the estimators' flags
// (identification, calibration, dead reckoning, lever arm), as odonav-offline has them.
inline void add_scenario_bench_options(Options& opts, const std::string& default_scenarios,
                                       const std::string& scenarios_help) {
  opts.add_int("seeds", 10, "seeds per scenario", 1, 1000);
  opts.add_int("first-seed", 1, "first seed", 0, std::numeric_limits<int64_t>::max() / 2);
  opts.add_string("scenarios", default_scenarios, scenarios_help);
  opts.add_string("log-level", "warn", "trace, debug, info, warn, error, critical, off");
  identification::add_identification_options(opts);
  calibration::add_calibration_options(opts);
  dead_reckoning::add_dead_reckoning_options(opts);
  add_lever_arm_option(opts);
}

// Parses the command line: nullopt with `base` set to the OfflineParams of the flags (before any
// dataset's defaults: params_for) and logging set up as `tool`; or the exit status, 0 after --help,
// 2 after a bad flag (named on standard error after "<tool>: ").
inline std::optional<int> parse_scenario_bench(Options& opts, int argc, char** argv, const std::string& tool,
                                               offline::OfflineParams& base) {
  try {
    if (opts.parse(argc, argv) == ParseResult::kHelp) return 0;
    setup_logging(tool, opts.get_string("log-level"));
    base.identification = identification::identification_params_from(opts);
    base.calibration = calibration::calibration_params_from(opts);
    base.dead_reckoning = dead_reckoning::dead_reckoner_params(dead_reckoning::dead_reckoning_facts_from(opts));
    base.calibration.lever_arm_body_m = base.dead_reckoning.lever_arm_body_m;
  } catch (const ConfigError& e) {
    std::cerr << "odonav-" << tool << ": " << e.what() << "\n";
    return 2;
  }
  return std::nullopt;
}

// --scenarios as a list (empty items skipped).
inline std::vector<std::string> scenario_list(const Options& opts) {
  std::vector<std::string> scenarios;
  std::stringstream list(opts.get_string("scenarios"));
  for (std::string s; std::getline(list, s, ',');)
    if (!s.empty()) scenarios.push_back(s);
  return scenarios;
}

// What a benchmark over scenarios runs: --seeds seeds from --first-seed, on each of --scenarios.
struct ScenarioRuns {
  std::size_t seeds = 0;
  uint64_t first_seed = 0;
  std::vector<std::string> scenarios;
};
inline ScenarioRuns scenario_runs(const Options& opts) {
  return {static_cast<std::size_t>(opts.get_int("seeds")), static_cast<uint64_t>(opts.get_int("first-seed")),
          scenario_list(opts)};
}

}  // namespace odonav::bench
