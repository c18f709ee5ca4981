#pragma once
// Offline parameters as a user gets them, for the offline accuracy tests: one definition, so every
// test measures the same configuration; and what those tests share besides (the smartLoc drive,
// converged K, the run's summary).
#include <algorithm>
#include <ostream>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "odonav/config.hpp"
#include "odonav/dataset.hpp"
#include "odonav/identification/identification_options.hpp"
#include "odonav/offline/offline_runner.hpp"
#include "odonav/offline/summary.hpp"

namespace odonav::offline::test {

/// The defaults with nominal K and lever arm from the dataset's meta.json; every other parameter as
/// the OfflineParams struct has it.
inline OfflineParams default_params(const Dataset& d) {
  OfflineParams p;
  p.dead_reckoning.nominal_k_m_per_pulse = d.meta.k_nominal_m_per_pulse.value_or(0.0125);
  p.dead_reckoning.lever_arm_body_m = d.meta.gnss_lever_arm_m;
  p.calibration.lever_arm_body_m = d.meta.gnss_lever_arm_m;
  p.identification.builder.lever_arm_body_m = d.meta.gnss_lever_arm_m;
  return p;
}

/// What odonav-offline does with a dataset and no flags: the identification's parameters through
/// identification_params_for with no options given (as the tool and the node build them), INS use and
/// lever arm from the dataset, every estimator run.
inline OfflineParams user_params(const Dataset& d) {
  Options o("test", "identification options");
  identification::add_identification_options(o);
  std::ostringstream help;
  o.parse(std::vector<std::string>{}, help);
  OfflineParams p;
  p.dead_reckoning.nominal_k_m_per_pulse = d.meta.k_nominal_m_per_pulse.value_or(0.0125);
  p.dead_reckoning.lever_arm_body_m = d.meta.gnss_lever_arm_m;
  p.dead_reckoning.use_ins = d.has_ins();
  p.calibration.lever_arm_body_m = d.meta.gnss_lever_arm_m;
  p.calibration.use_ins = d.has_ins();
  identification::IdentificationVehicleFacts facts;
  facts.use_ins = d.has_ins();
  facts.lever_arm_body_m = d.meta.gnss_lever_arm_m;
  facts.nominal_k_m_per_pulse = p.dead_reckoning.nominal_k_m_per_pulse;
  facts.run_all_estimators = true;
  p.identification = identification::identification_params_for(o, facts);
  return p;
}

/// The recorded smartLoc Berlin drive (tests/data/smartloc-berlin).
inline Dataset smartloc_dataset() {
  return read_dataset(ODONAV_SOURCE_DIR "/tests/data/smartloc-berlin", BadRowPolicy::kFail);
}

/// The main estimator's K of every converged identification output.
inline std::vector<double> converged_k(const OfflineResult& r) {
  std::vector<double> k;
  for (const identification::IdentificationOutput& o : r.identification)
    if (o.main.valid && o.main.converged) k.push_back(o.main.k_m_per_pulse);
  return k;
}

/// The median (upper one of an even count); v must not be empty.
inline double median_of(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

/// The summary of a run, as odonav-offline writes it (the dataset named by its description).
inline nlohmann::json summarize(const Dataset& d, const OfflineResult& r, const OfflineParams& p) {
  SummaryOptions o;
  o.dataset_name = d.meta.description;
  return make_summary(d, to_output_rows(r, p.identification.estimator_name), o);
}

}  // namespace odonav::offline::test
