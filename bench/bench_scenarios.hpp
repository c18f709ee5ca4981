#pragma once
// The simulated scenarios and the parameters of the accuracy benchmarks (odonav-bench-accuracy,
// odonav-bench-coverage): one definition, so both measure the same drives with the defaults a user
// gets.
#include <cstdint>
#include <sstream>
#include <stdexcept>
#include <string>

#include "core/simulator.hpp"
#include "odonav/config.hpp"
#include "odonav/consumer_rules.hpp"
#include "odonav/dead_reckoning/dead_reckoning_options.hpp"
#include "odonav/identification/identification_options.hpp"
#include "offline_runner.hpp"

namespace odonav::bench {

// A scenario with variants: "terrain", "terrain+1hz" (GNSS rate), "terrain+lat50" (GNSS latency in
// ms), combinable ("ring+1hz+lat100"). Throws std::invalid_argument naming an unknown modifier.
inline sim::SimulationConfig scenario_variant(const std::string& spec) {
  std::stringstream parts(spec);
  std::string name;
  std::getline(parts, name, '+');
  sim::SimulationConfig cfg = sim::scenario_config(name);
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
  sim::SimulationConfig cfg = scenario_variant(scenario);
  cfg.seed = seed;
  return sim::simulate(cfg);
}

// What odonav-offline's main does with a dataset before running (apply_dataset_defaults): the
// lever arm and nominal K from meta.json unless given, dead_reckoner_params for DR and
// identification_params_for with the same vehicle facts, so the bench measures the defaults a user
// gets.
inline offline::OfflineParams params_for(const Dataset& d, offline::OfflineParams p, const Options& opts) {
  DeadReckoningFacts facts = dead_reckoning_facts_from(opts);
  if (!facts.lever_arm_body_m && d.meta.gnss_lever_arm_m) {
    facts.lever_arm_body_m = d.meta.gnss_lever_arm_m;
    p.calibration.lever_arm_body_m = d.meta.gnss_lever_arm_m;
  }
  facts.use_ins = d.has_ins();
  facts.dataset_nominal_k_m_per_pulse = d.meta.k_nominal_m_per_pulse;
  p.dead_reckoning = dead_reckoner_params(facts);
  IdentificationVehicleFacts vehicle;
  vehicle.use_ins = d.has_ins();
  vehicle.lever_arm_body_m = p.dead_reckoning.lever_arm_body_m;
  vehicle.nominal_k_m_per_pulse = p.dead_reckoning.nominal_k_m_per_pulse;
  vehicle.run_all_estimators = true;
  p.identification = identification_params_for(opts, vehicle);
  p.calibration.use_ins = d.has_ins();
  return p;
}

}  // namespace odonav::bench
