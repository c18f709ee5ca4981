#include "offline_runner.hpp"

#include <limits>
#include <memory>
#include <utility>

#include "offline_pipeline.hpp"

namespace odonav::offline {
namespace {

// Every sample of one stream to the pipeline, then the end of data.
void feed(const SampleStream& next, OfflinePipeline& pipeline) {
  while (const std::optional<DatasetEvent> e = next()) {
    switch (e->kind) {
      case DatasetStreamKind::kOdometer: pipeline.add_odometer(e->odometer); break;
      case DatasetStreamKind::kGnss: pipeline.add_gnss(e->gnss); break;
      case DatasetStreamKind::kIns: pipeline.add_ins(e->ins); break;
    }
  }
  pipeline.finish();
}

/// Keeps every output of a run (the OfflineResult vectors).
class Collector : public PipelineSink {
 public:
  explicit Collector(OfflineResult& result, bool coarse) : r_(result), coarse_(coarse) {}
  void on_misalignment(const MisalignmentOutput& m) override {
    if (!coarse_) r_.misalignment.push_back(m);
  }
  void on_scale_factor(const IdentificationOutput& k) override { r_.identification.push_back(k); }
  void on_dead_reckoning(DeadReckoningStep step) override {
    if (coarse_) {
      r_.dr_coarse.push_back(std::move(step.output));
    } else {
      r_.dr_online.push_back(std::move(step.output));
      r_.navigation_position.push_back(std::move(step.navigation));
    }
  }

 private:
  OfflineResult& r_;
  bool coarse_;
};

OfflineParams with_degraded_mode(bool ins, OfflineParams p) {
  p.calibration.use_ins = ins;
  p.identification.builder.use_ins = ins;
  p.dead_reckoning.use_ins = ins;
  p.identification.run_all_estimators = true;
  return p;
}

std::optional<double> final_coarse_k(const std::optional<IdentificationOutput>& last,
                                     const std::vector<std::string>& names) {
  for (std::size_t i = 0; i < names.size(); ++i)
    if (names[i] == "coarse" && last && last->all[i].valid) return last->all[i].k_m_per_pulse;
  return std::nullopt;
}

/// Keeps the last estimate and passes every output on.
class LastEstimate : public PipelineSink {
 public:
  explicit LastEstimate(PipelineSink& next) : next_(next) {}
  void on_misalignment(const MisalignmentOutput& m) override { next_.on_misalignment(m); }
  void on_scale_factor(const IdentificationOutput& k) override {
    last = k;
    next_.on_scale_factor(k);
  }
  void on_dead_reckoning(DeadReckoningStep step) override { next_.on_dead_reckoning(std::move(step)); }
  std::optional<IdentificationOutput> last;

 private:
  PipelineSink& next_;
};

}  // namespace

SampleStream samples_of(const Dataset& d) {
  struct Cursor {
    const Dataset* d;
    std::size_t o = 0, g = 0, i = 0;
  };
  auto c = std::make_shared<Cursor>(Cursor{&d});
  return [c]() -> std::optional<DatasetEvent> {
    const Dataset& d = *c->d;
    constexpr double kEnd = std::numeric_limits<double>::infinity();
    const double to = c->o < d.odometer.size() ? d.odometer[c->o].t_s : kEnd;
    const double tg = c->g < d.gnss.size() ? d.gnss[c->g].t_s : kEnd;
    const double ti = c->i < d.ins.size() ? d.ins[c->i].t_s : kEnd;
    if (to == kEnd && tg == kEnd && ti == kEnd) return std::nullopt;
    DatasetEvent e;
    if (tg <= ti && tg <= to) {
      e.kind = DatasetStreamKind::kGnss;
      e.gnss = d.gnss[c->g++];
      e.t_s = tg;
    } else if (ti <= to) {
      e.kind = DatasetStreamKind::kIns;
      e.ins = d.ins[c->i++];
      e.t_s = ti;
    } else {
      e.kind = DatasetStreamKind::kOdometer;
      e.odometer = d.odometer[c->o++];
      e.t_s = to;
    }
    return e;
  };
}

OfflineRunTotals run_offline(const OpenSampleStream& open, bool has_ins, const OfflineParams& given,
                             PipelineSink& sink, PipelineSink& coarse_sink) {
  const OfflineParams params = with_degraded_mode(has_ins, given);
  OfflineRunTotals r;
  {
    PipelineConfig config;
    config.calibration = params.calibration;
    config.identification = params.identification;
    config.dead_reckoning = params.dead_reckoning;
    config.anchored = params.anchored;
    LastEstimate last(sink);
    OfflinePipeline pipeline(config, last);
    feed(open(), pipeline);
    r.last_identification = std::move(last.last);
    r.estimator_names = pipeline.identification()->estimator_names();
    r.builder_counters = pipeline.identification()->builder_counters();
    r.calibration_counters = pipeline.calibration().counters();
    r.dr_counters = pipeline.dead_reckoning()->core().counters();
    r.anchored_counters = pipeline.dead_reckoning()->anchor().counters();
  }
  if (params.coarse_k_m_per_pulse) {
    r.coarse_k_m_per_pulse = *params.coarse_k_m_per_pulse;
    r.coarse_k_origin = params.coarse_k_origin.empty() ? "given" : params.coarse_k_origin;
  } else if (auto k = final_coarse_k(r.last_identification, r.estimator_names)) {
    r.coarse_k_m_per_pulse = *k;
    r.coarse_k_origin = "coarse S/N of this dataset";
  } else {
    r.coarse_k_m_per_pulse = params.dead_reckoning.nominal_k_m_per_pulse;
    r.coarse_k_origin = "nominal (no straight run for S/N)";
  }
  // The coarse run: the same calibration, dead reckoning on the coarse K, no identification.
  PipelineConfig coarse;
  coarse.calibration = params.calibration;
  coarse.dead_reckoning = params.dead_reckoning;
  coarse.dead_reckoning->nominal_k_m_per_pulse = r.coarse_k_m_per_pulse;
  coarse.anchored = params.anchored;
  coarse.navigation = false;  // only its dead reckoning is written
  OfflinePipeline pipeline(coarse, coarse_sink);
  feed(open(), pipeline);
  return r;
}

OfflineResult run_offline(const Dataset& dataset, const OfflineParams& params) {
  OfflineResult r;
  Collector collector(r, false);
  Collector coarse_collector(r, true);
  static_cast<OfflineRunTotals&>(r) =
      run_offline([&dataset] { return samples_of(dataset); }, dataset.has_ins(), params, collector, coarse_collector);
  return r;
}

std::optional<double> coarse_k_of(const OpenSampleStream& open, bool has_ins, const OfflineParams& given) {
  const OfflineParams params = with_degraded_mode(has_ins, given);
  PipelineConfig config;
  config.calibration = params.calibration;
  config.identification = params.identification;
  PipelineSink none;
  LastEstimate last(none);
  OfflinePipeline pipeline(config, last);
  feed(open(), pipeline);
  return final_coarse_k(last.last, pipeline.identification()->estimator_names());
}

std::optional<double> coarse_k_of(const Dataset& dataset, const OfflineParams& params) {
  return coarse_k_of([&dataset] { return samples_of(dataset); }, dataset.has_ins(), params);
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
