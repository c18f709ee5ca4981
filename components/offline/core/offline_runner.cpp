#include "offline_runner.hpp"

#include "odonav/consumer_rules.hpp"
#include "odonav/dead_reckoning/scale_factor_selection.hpp"

namespace odonav::offline {
namespace {

std::vector<MisalignmentOutput> run_calibration(const Dataset& d, const MisalignmentCalibratorParams& params,
                                                MisalignmentCounters* counters) {
  MisalignmentCalibrator calibrator(params);
  for (const GnssSample& g : d.gnss) calibrator.add_gnss(g);
  for (const InsSample& i : d.ins) calibrator.add_ins(i);
  std::vector<MisalignmentOutput> out = calibrator.finish();
  if (counters) *counters = calibrator.counters();
  return out;
}

// Every estimate in force from its epoch + the hold-off (consumer_rules.hpp), as the nodes add it.
template <class Consumer>
void add_applicable_misalignments(Consumer& consumer, const std::vector<MisalignmentOutput>& outputs,
                                  double hold_off_s) {
  for (const MisalignmentOutput& m : outputs)
    if (misalignment_applicable(m.converged, m.samples_used, m.misalignment.heading_rad, m.misalignment.pitch_rad,
                                m.sigma_heading_rad, m.sigma_pitch_rad))
      consumer.add_misalignment(estimate_applies_from_s(m.t_s, hold_off_s), m.misalignment);
}

std::vector<IdentificationOutput> run_identification(const Dataset& d, const IdentificationParams& params,
                                                     const std::vector<MisalignmentOutput>& misalignment,
                                                     std::vector<std::string>* names,
                                                     SampleBuilderCounters* counters) {
  IdentificationCore core(params);
  for (const OdometerSample& o : d.odometer) core.add_odometer(o);
  for (const GnssSample& g : d.gnss) core.add_gnss(g);
  for (const InsSample& i : d.ins) core.add_ins(i);
  add_applicable_misalignments(core, misalignment, params.estimate_hold_off_s);
  std::vector<IdentificationOutput> out = core.finish();
  if (names) *names = core.estimator_names();
  if (counters) *counters = core.builder_counters();
  return out;
}

std::vector<DeadReckoningOutput> run_dead_reckoning(const Dataset& d, const DeadReckonerParams& params,
                                                    const std::vector<MisalignmentOutput>& misalignment,
                                                    const std::vector<IdentificationOutput>* identification,
                                                    DeadReckonerCounters* counters) {
  DeadReckoner dr(params);
  for (const OdometerSample& o : d.odometer) dr.add_odometer(o);
  for (const InsSample& i : d.ins) dr.add_ins(i);
  for (const GnssSample& g : d.gnss) dr.add_gnss(g);
  add_applicable_misalignments(dr, misalignment, params.estimate_hold_off_s);
  // Every estimate is here: no output is on a held one (the node decides alike as they arrive).
  for (const MisalignmentOutput& m : misalignment) dr.add_estimate_received(HeldEstimate::kMisalignment, m.t_s);
  if (identification) {
    for (const IdentificationOutput& k : *identification) dr.add_estimate_received(HeldEstimate::kScaleFactor, k.t_s);
    // Every ScaleFactor carries the GNSS latency in force: the DR node adds each one alike.
    for (const IdentificationOutput& k : *identification)
      dr.add_gnss_latency(estimate_applies_from_s(k.t_s, params.estimate_hold_off_s), k.latency.applied_s);
    for (const IdentificationOutput& k : *identification)
      dr.add_turn_slip(estimate_applies_from_s(k.t_s, params.estimate_hold_off_s),
                       turn_slip_gain_to_apply(k.turn_slip.applies, k.turn_slip.g_s_per_rad), k.turn_slip_threshold_radps);
    // The dead-reckoning node's own K policy, fed as the node feeds it (one identification here).
    ScaleFactorSelection selection(params.nominal_k_m_per_pulse);
    for (const IdentificationOutput& k : *identification) {
      const IdentifiedScaleFactor s{estimate_applies_from_s(k.t_s, params.estimate_hold_off_s),
                                    k.main.valid ? k.main.k_m_per_pulse : 0.0,
                                    k.main.converged,
                                    "identification",
                                    k.main.sigma_m_per_pulse,
                                    k.samples_accepted};
      if (const auto update = selection.on_identified(s, 0.0))
        dr.add_scale_factor(update->t_s, update->k_m_per_pulse, update->source);
    }
  }
  std::vector<DeadReckoningOutput> out = dr.finish();
  if (counters) *counters = dr.counters();
  return out;
}

std::vector<AnchoredPosition> anchor_positions(const std::vector<DeadReckoningOutput>& dr,
                                               const AnchoredPositionParams& params, AnchoredPositionCounters* counters) {
  AnchoredPositionFilter filter(params);
  std::vector<AnchoredPosition> out;
  out.reserve(dr.size());
  for (const DeadReckoningOutput& o : dr) out.push_back(filter.step(o));
  if (counters) *counters = filter.counters();
  return out;
}

OfflineParams with_degraded_mode(const Dataset& d, OfflineParams p) {
  const bool ins = d.has_ins();
  p.calibration.use_ins = ins;
  p.identification.builder.use_ins = ins;
  p.dead_reckoning.use_ins = ins;
  return p;
}

std::optional<double> final_coarse_k(const std::vector<IdentificationOutput>& outputs,
                                     const std::vector<std::string>& names) {
  for (std::size_t i = 0; i < names.size(); ++i)
    if (names[i] == "coarse" && !outputs.empty() && outputs.back().all[i].valid)
      return outputs.back().all[i].k_m_per_pulse;
  return std::nullopt;
}

}  // namespace

OfflineResult run_offline(const Dataset& dataset, const OfflineParams& given) {
  OfflineParams params = with_degraded_mode(dataset, given);
  params.identification.run_all_estimators = true;
  OfflineResult r;
  r.misalignment = run_calibration(dataset, params.calibration, &r.calibration_counters);
  r.identification = run_identification(dataset, params.identification, r.misalignment, &r.estimator_names,
                                        &r.builder_counters);
  r.dr_online = run_dead_reckoning(dataset, params.dead_reckoning, r.misalignment, &r.identification, &r.dr_counters);
  r.navigation_position = anchor_positions(r.dr_online, params.anchored, &r.anchored_counters);

  if (params.coarse_k_m_per_pulse) {
    r.coarse_k_m_per_pulse = *params.coarse_k_m_per_pulse;
    r.coarse_k_origin = params.coarse_k_origin.empty() ? "given" : params.coarse_k_origin;
  } else if (auto k = final_coarse_k(r.identification, r.estimator_names)) {
    r.coarse_k_m_per_pulse = *k;
    r.coarse_k_origin = "coarse S/N of this dataset";
  } else {
    r.coarse_k_m_per_pulse = params.dead_reckoning.nominal_k_m_per_pulse;
    r.coarse_k_origin = "nominal (no straight run for S/N)";
  }
  DeadReckonerParams coarse = params.dead_reckoning;
  coarse.nominal_k_m_per_pulse = r.coarse_k_m_per_pulse;
  r.dr_coarse = run_dead_reckoning(dataset, coarse, r.misalignment, nullptr, nullptr);
  return r;
}

std::optional<double> coarse_k_of(const Dataset& dataset, const OfflineParams& given) {
  OfflineParams params = with_degraded_mode(dataset, given);
  params.identification.run_all_estimators = true;
  const auto misalignment = run_calibration(dataset, params.calibration, nullptr);
  std::vector<std::string> names;
  const auto identification = run_identification(dataset, params.identification, misalignment, &names, nullptr);
  return final_coarse_k(identification, names);
}

}  // namespace odonav::offline

namespace odonav::offline {

results::MisalignmentRow to_row(const MisalignmentOutput& m) {
  results::MisalignmentRow r;
  r.t_s = m.t_s;
  r.heading_rad = m.misalignment.heading_rad;
  r.pitch_rad = m.misalignment.pitch_rad;
  r.heading_std_rad = m.sigma_heading_rad;
  r.pitch_std_rad = m.sigma_pitch_rad;
  r.converged = m.converged;
  r.state = to_string(m.state);
  r.samples_used = m.samples_used;
  return r;
}

results::ScaleFactorRow to_row(const IdentificationOutput& k, const std::string& main_estimator,
                      const std::vector<std::string>& names) {
  results::ScaleFactorRow r;
  r.t_s = k.t_s;
  auto value_of = [](const ScaleFactorEstimate& e) { return e.valid ? std::optional<double>(e.k_m_per_pulse) : std::nullopt; };
  for (std::size_t i = 0; i < names.size() && i < k.all.size(); ++i) {
    r.k_by_estimator.emplace_back(names[i], value_of(k.all[i]));
    if (names[i] == "vff_lm_rls" && k.all[i].valid) r.lambda_vff_lm_rls = k.all[i].forgetting_factor;
  }
  if (names.empty()) {  // one estimator only (the DDS node): its own column
    r.k_by_estimator.emplace_back(main_estimator, value_of(k.main));
    if (main_estimator == "vff_lm_rls" && k.main.valid) r.lambda_vff_lm_rls = k.main.forgetting_factor;
  }
  r.estimator = main_estimator;
  r.k_m_per_pulse = value_of(k.main);
  if (k.main.valid) r.sigma_m_per_pulse = k.main.sigma_m_per_pulse;
  r.forgetting_factor = k.main.forgetting_factor;
  r.window_fill = k.main.window_fill;
  r.converged = k.main.converged;
  r.samples_accepted = k.samples_accepted;
  r.samples_rejected = k.samples_rejected;
  r.epoch_status = to_string(k.epoch_status);
  r.gnss_latency_s = k.latency.applied_s;
  if (k.latency.sigma_s >= 0.0) r.gnss_latency_sigma_s = k.latency.sigma_s;
  r.turn_slip_s_per_rad = k.turn_slip.g_s_per_rad;
  if (k.turn_slip.sigma_s_per_rad >= 0.0) r.turn_slip_sigma_s_per_rad = k.turn_slip.sigma_s_per_rad;
  r.turn_slip_applies = k.turn_slip.applies;
  return r;
}

results::DeadReckoningRow to_row(const DeadReckoningOutput& o) {
  results::DeadReckoningRow r;
  r.t_s = o.t_s;
  r.lat_rad = o.position.lat_rad;
  r.lon_rad = o.position.lon_rad;
  r.height_m = o.position.height_m;
  r.distance_m = o.distance_m;
  r.k_m_per_pulse = o.k_m_per_pulse;
  r.k_source = to_string(o.k_source);
  r.east_m = o.enu_m.x();
  r.north_m = o.enu_m.y();
  r.up_m = o.enu_m.z();
  r.heading_rad = o.heading_rad;
  r.horizontal_error_m = o.horizontal_error_m;
  r.error_percent = o.error_percent_distance;
  r.error_t_s = o.error_t_s;
  return r;
}

results::NavigationPositionRow to_row(const AnchoredPosition& p) {
  results::NavigationPositionRow r;
  r.t_s = p.t_s;
  r.lat_rad = p.position.lat_rad;
  r.lon_rad = p.position.lon_rad;
  r.height_m = p.position.height_m;
  r.east_m = p.enu_m.x();
  r.north_m = p.enu_m.y();
  r.up_m = p.enu_m.z();
  r.var_east_m2 = p.covariance_enu_m2(0, 0);
  r.var_north_m2 = p.covariance_enu_m2(1, 1);
  r.var_up_m2 = p.covariance_enu_m2(2, 2);
  r.status = to_string(p.status);
  r.last_fix_t_s = p.last_fix_t_s;
  r.distance_since_fix_m = p.distance_since_fix_m;
  return r;
}

results::OutputRows to_output_rows(const OfflineResult& result, const std::string& main_estimator) {
  results::OutputRows rows;
  rows.misalignment.reserve(result.misalignment.size());
  for (const auto& m : result.misalignment) rows.misalignment.push_back(to_row(m));
  rows.scale_factor.reserve(result.identification.size());
  for (const auto& k : result.identification) rows.scale_factor.push_back(to_row(k, main_estimator, result.estimator_names));
  rows.dead_reckoning.reserve(result.dr_online.size());
  for (const auto& o : result.dr_online) rows.dead_reckoning.push_back(to_row(o));
  rows.dead_reckoning_coarse.reserve(result.dr_coarse.size());
  for (const auto& o : result.dr_coarse) rows.dead_reckoning_coarse.push_back(to_row(o));
  rows.navigation_position.reserve(result.navigation_position.size());
  for (const auto& p : result.navigation_position) rows.navigation_position.push_back(to_row(p));
  return rows;
}

}  // namespace odonav::offline
