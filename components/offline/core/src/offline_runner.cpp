#include "odonav/offline/offline_runner.hpp"

#include <limits>
#include <memory>
#include <utility>

#include "odonav/offline/offline_pipeline.hpp"

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
  void on_misalignment(const calibration::MisalignmentOutput& m) override {
    if (!coarse_) r_.misalignment.push_back(m);
  }
  void on_scale_factor(const identification::IdentificationOutput& k) override { r_.identification.push_back(k); }
  void on_dead_reckoning(dead_reckoning::DeadReckoningStep step) override {
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

std::optional<double> final_coarse_k(const std::optional<identification::IdentificationOutput>& last,
                                     const std::vector<std::string>& names) {
  for (std::size_t i = 0; i < names.size(); ++i)
    if (names[i] == "coarse" && last && last->all[i].valid) return last->all[i].k_m_per_pulse;
  return std::nullopt;
}

/// Keeps the last estimate and passes every output on.
class LastEstimate : public PipelineSink {
 public:
  explicit LastEstimate(PipelineSink& next) : next_(next) {}
  void on_misalignment(const calibration::MisalignmentOutput& m) override { next_.on_misalignment(m); }
  void on_scale_factor(const identification::IdentificationOutput& k) override {
    last = k;
    next_.on_scale_factor(k);
  }
  void on_dead_reckoning(dead_reckoning::DeadReckoningStep step) override { next_.on_dead_reckoning(std::move(step)); }
  std::optional<identification::IdentificationOutput> last;

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

OfflineRunTotals run_offline(const OpenSampleStream& open, bool has_ins, const OfflineParams& given, PipelineSink& sink,
                             PipelineSink& coarse_sink) {
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
    for (int i = 0; i < dead_reckoning::kConsistencyChecks; ++i)
      r.consistency.push_back(
          pipeline.dead_reckoning()->monitor().state(static_cast<dead_reckoning::ConsistencyCheck>(i)));
    r.gnss_jumps = pipeline.dead_reckoning()->monitor().gnss_jumps();
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

results::OutputRows to_output_rows(const OfflineResult& result, const std::string& main_estimator) {
  results::OutputRows rows;
  rows.misalignment.reserve(result.misalignment.size());
  for (const auto& m : result.misalignment) rows.misalignment.push_back(output_row(m));
  rows.scale_factor.reserve(result.identification.size());
  for (const auto& k : result.identification)
    rows.scale_factor.push_back(output_row(k, main_estimator, result.estimator_names));
  rows.dead_reckoning.reserve(result.dr_online.size());
  for (const auto& o : result.dr_online) rows.dead_reckoning.push_back(output_row(o));
  rows.dead_reckoning_coarse.reserve(result.dr_coarse.size());
  for (const auto& o : result.dr_coarse) rows.dead_reckoning_coarse.push_back(output_row(o));
  rows.navigation_position.reserve(result.navigation_position.size());
  for (const auto& p : result.navigation_position) rows.navigation_position.push_back(output_row(p));
  return rows;
}

}  // namespace odonav::offline
