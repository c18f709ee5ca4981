// odonav-offline: runs calibration -> identification -> dead reckoning over a dataset directory
// without DDS, writes the output files and summary.json, prints a summary. See README.md.

#include <atomic>
#include <chrono>
#include <exception>
#include <functional>
#include <thread>
#include <variant>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "odonav/calibration/calibration_options.hpp"
#include "odonav/config.hpp"
#include "odonav/dataset.hpp"
#include "odonav/dataset_stream.hpp"
#include "odonav/estimators.hpp"
#include "odonav/results/output_files.hpp"
#include "odonav/dead_reckoning/dead_reckoning_options.hpp"
#include "odonav/identification/identification_options.hpp"
#include "odonav/logging.hpp"
#include "odonav/task_dispatcher.hpp"
#include "odonav/run_provenance.hpp"
#include "odonav/safe_output.hpp"
#include "odonav/stream_buffers.hpp"
#include "odonav/tool_output.hpp"
#include "odonav/offline/offline_runner.hpp"
#include "odonav/offline/run_diagnosis.hpp"
#include "odonav/offline/summary.hpp"

namespace {

std::string base_name(std::string path) {
  while (path.size() > 1 && path.back() == '/') path.pop_back();
  const auto slash = path.find_last_of('/');
  return slash == std::string::npos ? path : path.substr(slash + 1);
}

odonav::Options make_options() {
  odonav::Options opts("odonav-offline",
                       "Runs misalignment calibration, scale-factor identification (every estimator side by "
                       "side) and dead reckoning (with the identified K and with a coarse K) over a dataset "
                       "directory (docs/DATASET.md), without DDS. Writes misalignment.csv, scale_factor.csv, "
                       "dead_reckoning.csv, dead_reckoning_coarse.csv, navigation_position.csv (the GNSS-anchored "
                       "position) and summary.json into --out, and prints a "
                       "summary; with truth.csv it also evaluates against the truth.");
  opts.add_positional("dataset", "dataset directory");
  opts.add_string("out", "",
                  "output directory (created if missing; an existing one must be empty or an odonav "
                  "output directory, see --force); required");
  opts.add_bool("force", false, "write into an existing non-empty directory that is not an odonav output directory");
  opts.add_choice("on-bad-row", "fail", {"fail", "skip"},
                  "a bad input row stops the run (fail) or is skipped and counted");
  opts.add_double("coarse-k", 0.0, "K for the coarse DR run (m/pulse); 0 = see --coarse-k-from", 0.0, 10.0);
  opts.add_string("coarse-k-from", "",
                  "dataset whose coarse S/N calibration gives the coarse K (e.g. a 'straight' run); empty = this "
                  "dataset's own coarse S/N estimate");
  opts.add_string("log-level", "",
                  "trace, debug, info, warn, error, critical, off (default: $ODONAV_LOG_LEVEL or info)");
  odonav::identification::add_identification_options(opts);
  odonav::calibration::add_calibration_options(opts);
  odonav::dead_reckoning::add_dead_reckoning_options(opts);
  odonav::add_lever_arm_option(opts);
  return opts;
}

/// Parses the command line and sets up logging. An exit code when the program ends here (0 after
/// --help, 2 for a bad flag or log level), nullopt to go on.
std::optional<int> parse_command_line(odonav::Options& opts, int argc, char** argv) {
  try {
    if (opts.parse(argc, argv) == odonav::ParseResult::kHelp) return 0;
  } catch (const odonav::ConfigError& e) {
    odonav::setup_logging("offline", "");
    spdlog::error("{}", e.what());
    spdlog::error("see odonav-offline --help");
    return 2;
  }
  try {
    odonav::setup_logging("offline", opts.get_string("log-level"));
  } catch (const odonav::ConfigError& e) {
    odonav::setup_logging("offline", "info");
    spdlog::error("{}", e.what());
    return 2;
  }
  return std::nullopt;
}

/// What the flags leave open, from the dataset's meta.json: the GNSS lever arm (body frame, m) and
/// the nominal K (m/pulse: the flag, else meta.json, else 0.0125, dead_reckoner_params); then the identification
/// parameters from the flags and these vehicle facts.
void apply_dataset_defaults(const odonav::DatasetMeta& meta, bool has_ins, const odonav::Options& opts,
                            odonav::dead_reckoning::DeadReckoningFacts dr_facts,
                            odonav::offline::OfflineParams& params) {
  if (!dr_facts.lever_arm_body_m && meta.gnss_lever_arm_m) {
    const Eigen::Vector3d& l = *meta.gnss_lever_arm_m;
    spdlog::info("GNSS lever arm from meta.json: ({}, {}, {}) m (forward, left, up)", l.x(), l.y(), l.z());
    dr_facts.lever_arm_body_m = l;
    params.calibration.lever_arm_body_m = l;
  }
  dr_facts.use_ins = has_ins;
  dr_facts.dataset_nominal_k_m_per_pulse = meta.k_nominal_m_per_pulse;
  dr_facts.dataset_nominal_k_sigma_percent = meta.k_nominal_sigma_percent;
  params.dead_reckoning = odonav::dead_reckoning::dead_reckoner_params(dr_facts);  // as odonav-dead-reckoning's
  params.anchored = odonav::dead_reckoning::anchored_position_params(dr_facts);    // likewise
  // The same function as odonav-identification, with the same vehicle facts the launcher gives
  // it as flags (deploy/launch): INS present, lever arm, nominal K (the pulse-jump gate's K).
  odonav::identification::IdentificationVehicleFacts vehicle;
  vehicle.use_ins = has_ins;
  vehicle.lever_arm_body_m = params.dead_reckoning.lever_arm_body_m;
  vehicle.nominal_k_m_per_pulse = params.dead_reckoning.nominal_k_m_per_pulse;
  vehicle.run_all_estimators = true;  // every estimator side by side
  params.identification = odonav::identification::identification_params_for(opts, vehicle);
}

/// A pass over the dataset's sensor files, as one time-ordered stream. The first pass reads through
/// `first` (opened to learn meta.json and the files present; its report counts the bad rows); each
/// later pass opens the files again, quietly (its bad rows are those the first pass reported).
odonav::offline::SampleStream open_pass(const std::string& dir, odonav::BadRowPolicy policy,
                                        std::shared_ptr<odonav::DatasetStream>& first) {
  std::shared_ptr<odonav::DatasetStream> stream = std::move(first);
  if (!stream) {
    const auto level = spdlog::get_level();
    spdlog::set_level(spdlog::level::err);  // the bad-row warnings were given by the first pass
    try {
      stream = std::make_shared<odonav::DatasetStream>(dir, policy);
    } catch (...) {
      spdlog::set_level(level);
      throw;
    }
    spdlog::set_level(level);
    return [stream]() -> std::optional<odonav::DatasetEvent> {
      const auto level = spdlog::get_level();
      spdlog::set_level(spdlog::level::err);
      std::optional<odonav::DatasetEvent> e;
      try {
        e = stream->next();
      } catch (...) {
        spdlog::set_level(level);
        throw;
      }
      spdlog::set_level(level);
      return e;
    };
  }
  return [stream] { return stream->next(); };
}

/// The coarse K of --coarse-k or --coarse-k-from (neither: run_offline takes this dataset's own).
/// False (logged) when the --coarse-k-from dataset has no straight run long enough.
bool apply_coarse_k(const odonav::Options& opts, odonav::offline::OfflineParams& params) {
  if (opts.get_double("coarse-k") > 0.0) {
    params.coarse_k_m_per_pulse = opts.get_double("coarse-k");
    params.coarse_k_origin = "--coarse-k";
  } else if (!opts.get_string("coarse-k-from").empty()) {
    const std::string from = opts.get_string("coarse-k-from");
    auto stream = std::make_shared<odonav::DatasetStream>(from, odonav::BadRowPolicy::kFail);
    const bool has_ins = stream->has_ins();
    const auto k = odonav::offline::coarse_k_of(
        [stream] { return odonav::offline::SampleStream([stream] { return stream->next(); }); }, has_ins, params);
    if (!k) {
      spdlog::error("{}: no straight run long enough for a coarse S/N calibration", from);
      return false;
    }
    params.coarse_k_m_per_pulse = *k;
    params.coarse_k_origin = "coarse S/N of " + base_name(from);
  }
  return true;
}

/// The output files written as the pipeline makes them, each row also given to the summary and the
/// run diagnosis.
class OutputFiles : public odonav::offline::PipelineSink {
 public:
  OutputFiles(const odonav::OutputDirectory& out, std::string main_estimator, std::vector<std::string> estimators,
              odonav::offline::SummaryAccumulator& summary, odonav::offline::RunDiagnosisAccumulator& diagnosis)
      : misalignment_(out.file("misalignment.csv")),
        scale_factor_(out.file("scale_factor.csv")),
        dead_reckoning_(out.file("dead_reckoning.csv")),
        navigation_(out.file("navigation_position.csv")),
        main_estimator_(std::move(main_estimator)),
        estimators_(std::move(estimators)),
        summary_(summary),
        diagnosis_(diagnosis) {}

  void on_misalignment(const odonav::calibration::MisalignmentOutput& m) override {
    const odonav::results::MisalignmentRow row = odonav::calibration::output_row(m);
    misalignment_.write(row);
    summary_.add(row);
    diagnosis_.add_misalignment(m);
  }
  void on_scale_factor(const odonav::identification::IdentificationOutput& k) override {
    const odonav::results::ScaleFactorRow row = odonav::identification::output_row(k, main_estimator_, estimators_);
    scale_factor_.write(row);
    summary_.add(row);
    diagnosis_.add_identification(k.main, k.latency, k.latency_decided);
  }
  void on_dead_reckoning(odonav::dead_reckoning::DeadReckoningStep step) override {
    const odonav::results::DeadReckoningRow dr = odonav::dead_reckoning::output_row(step.output);
    dead_reckoning_.write(dr);
    summary_.add_dead_reckoning(dr);
    diagnosis_.add_dead_reckoning(step.output.t_s, step.output.position);
    const odonav::results::NavigationPositionRow nav = odonav::dead_reckoning::output_row(step.navigation);
    navigation_.write(nav);
    summary_.add(nav);
    ++navigation_rows_;
  }
  /// Renames the complete files into place (a navigation file only when it has rows, as before).
  void close() {
    misalignment_.close();
    scale_factor_.close();
    dead_reckoning_.close();
    if (navigation_rows_ > 0) navigation_.close();
  }

 private:
  odonav::results::MisalignmentCsv misalignment_;
  odonav::results::ScaleFactorCsv scale_factor_;
  odonav::results::DeadReckoningCsv dead_reckoning_;
  odonav::results::NavigationPositionCsv navigation_;
  std::string main_estimator_;
  std::vector<std::string> estimators_;
  odonav::offline::SummaryAccumulator& summary_;
  odonav::offline::RunDiagnosisAccumulator& diagnosis_;
  std::size_t navigation_rows_ = 0;
};

/// dead_reckoning_coarse.csv, from the second pass.
class CoarseFile : public odonav::offline::PipelineSink {
 public:
  CoarseFile(const odonav::OutputDirectory& out, odonav::offline::SummaryAccumulator& summary)
      : csv_(out.file("dead_reckoning_coarse.csv")), summary_(summary) {}
  void on_dead_reckoning(odonav::dead_reckoning::DeadReckoningStep step) override {
    const odonav::results::DeadReckoningRow row = odonav::dead_reckoning::output_row(step.output);
    csv_.write(row);
    summary_.add_dead_reckoning_coarse(row);
    ++rows_;
  }
  void close() {
    if (rows_ > 0) csv_.close();
  }

 private:
  odonav::results::DeadReckoningCsv csv_;
  odonav::offline::SummaryAccumulator& summary_;
  std::size_t rows_ = 0;
};

/// The first pass's sample times, for the summary and the diagnosis.
struct InputTime {
  odonav::DatasetStreamKind kind;
  double t_s;
};

/// What the output side receives, in the order the run makes it.
struct CoarseStep {
  odonav::dead_reckoning::DeadReckoningStep step;
};
using OutputItem =
    std::variant<InputTime, odonav::calibration::MisalignmentOutput, odonav::identification::IdentificationOutput,
                 odonav::dead_reckoning::DeadReckoningStep, CoarseStep>;

/// The output side of the run (the files, the summary, the diagnosis) on a second thread, so that
/// formatting and evaluating overlap with processing: items are handed over in batches, in the
/// order they were made, and handled one at a time there, so every figure is what one thread
/// would give. At most kMaxBatches batches wait: memory stays bounded when the output side is the
/// slower one. An error there is rethrown by the next push() or by finish().
class OutputThread {
 public:
  explicit OutputThread(std::function<void(OutputItem&)> handle) : handle_(std::move(handle)) {
    worker_ = std::thread(
        [this] { dispatcher_.run([this] { return stop_.load(); }, nullptr, std::chrono::milliseconds(50)); });
  }
  ~OutputThread() {
    if (worker_.joinable()) stop_and_join();
  }
  OutputThread(const OutputThread&) = delete;
  OutputThread& operator=(const OutputThread&) = delete;

  /// One item (an alternative of OutputItem), made in place in the batch.
  template <class T>
  void push(T&& item) {
    batch_.emplace_back(std::forward<T>(item));
    if (batch_.size() >= kBatchItems) hand_over();
  }
  /// Handles everything pushed, stops the thread; rethrows an error of the output side.
  void finish() {
    hand_over();
    stop_and_join();
    dispatcher_.run_pending();  // what the thread had not started when it stopped
    if (error_) std::rethrow_exception(error_);
  }

 private:
  static constexpr std::size_t kBatchItems = 1024;
  static constexpr std::size_t kMaxBatches = 4;
  void hand_over() {
    if (error_) std::rethrow_exception(error_);
    if (batch_.empty()) return;
    while (dispatcher_.queue_depth() >= kMaxBatches) std::this_thread::sleep_for(std::chrono::microseconds(100));
    auto batch = std::make_shared<std::vector<OutputItem>>(std::move(batch_));
    batch_.clear();
    batch_.reserve(kBatchItems);
    dispatcher_.post([this, batch] {
      if (error_) return;
      try {
        for (OutputItem& item : *batch) handle_(item);
      } catch (...) {
        error_ = std::current_exception();
      }
    });
  }
  void stop_and_join() {
    stop_ = true;
    worker_.join();
  }

  std::function<void(OutputItem&)> handle_;
  odonav::TaskDispatcher dispatcher_;  // kQueued: run() executes on worker_
  std::atomic<bool> stop_{false};
  std::exception_ptr error_;  // set on the worker, read after a hand-over or the join
  std::vector<OutputItem> batch_;
  std::thread worker_;
};

/// The pipeline's outputs to the output thread.
class HandOver : public odonav::offline::PipelineSink {
 public:
  HandOver(OutputThread& thread, bool coarse) : thread_(thread), coarse_(coarse) {}
  void on_misalignment(const odonav::calibration::MisalignmentOutput& m) override {
    if (!coarse_) thread_.push(m);
  }
  void on_scale_factor(const odonav::identification::IdentificationOutput& k) override { thread_.push(k); }
  void on_dead_reckoning(odonav::dead_reckoning::DeadReckoningStep step) override {
    if (coarse_)
      thread_.push(CoarseStep{std::move(step)});
    else
      thread_.push(std::move(step));
  }

 private:
  OutputThread& thread_;
  bool coarse_;
};

/// The first pass's samples: their counts, span and fingerprint here, their times to the output
/// thread (summary, diagnosis).
struct InputTap {
  OutputThread& output;
  odonav::DatasetFingerprint& fingerprint;
  std::size_t odometer = 0, gnss = 0, ins = 0;
  double first_s = std::numeric_limits<double>::quiet_NaN();
  double last_s = std::numeric_limits<double>::quiet_NaN();
  void operator()(const odonav::DatasetEvent& e) {
    if (odometer + gnss + ins == 0) first_s = e.t_s;
    last_s = e.t_s;
    switch (e.kind) {
      case odonav::DatasetStreamKind::kOdometer: ++odometer; break;
      case odonav::DatasetStreamKind::kGnss:
        ++gnss;
        fingerprint.add(e.gnss);
        break;
      case odonav::DatasetStreamKind::kIns: ++ins; break;
    }
    output.push(InputTime{e.kind, e.t_s});
  }
};

/// summary.json's additions to the summary: the identification gates' counts, the skipped bad
/// rows, the turn slip of the last estimate and the brakings to a standstill withdrawn from K.
void add_run_facts(nlohmann::json& summary, const odonav::offline::OfflineRunTotals& totals,
                   const odonav::DatasetReadReport& report) {
  const odonav::SampleBuilderCounters& c = totals.builder_counters;
  summary["gates"] = {{"epochs", c.epochs},
                      {"accepted", c.accepted},
                      {"invalid_fix", c.invalid_fix},
                      {"speed_jump", c.speed_jump},
                      {"min_speed", c.min_speed},
                      {"yaw_rate", c.yaw_rate},
                      {"gap", c.gap},
                      {"innovation", c.innovation},
                      {"cross_track", c.cross_track},
                      {"reversing", c.reversing},
                      {"reversing_accepted", c.reversing_accepted}};
  summary["bad_rows_skipped"] = report.total_bad();
  summary["gnss_position_jumps"] = {
      {"count", totals.gnss_jumps.jumps},
      {"first_t_s", totals.gnss_jumps.jumps ? nlohmann::json(totals.gnss_jumps.first_t_s) : nlohmann::json()},
      {"largest_m", totals.gnss_jumps.largest_m},
      {"relocations", totals.gnss_jumps.relocations}};
  if (totals.last_identification && summary.contains("scale_factor")) {
    const odonav::TurnSlipEstimate& slip = totals.last_identification->turn_slip;
    summary["scale_factor"]["turn_slip_samples"] = slip.samples;
    summary["scale_factor"]["turn_slip_outliers"] = slip.outliers;
    summary["scale_factor"]["turn_slip_reason"] = slip.reason;  // why it is not applied; "" when it is
    // Brakings that ended in a standstill, whose samples were withdrawn from K (braking_stop.hpp).
    const odonav::identification::BrakingStopCounters& stops = totals.last_identification->braking_stop;
    summary["scale_factor"]["braking_stops"] = stops.stops;
    summary["scale_factor"]["braking_samples_withdrawn"] = stops.samples_withdrawn;
  }
}

/// Reads, runs, writes the files as the outputs come and prints the summary. Exit code 0, 1 (an
/// error, logged) or kExitNoUsableResult (no K or no dead reckoning: the warnings say why).
int run(const odonav::Options& opts, const std::string& dataset_dir, const std::string& out_dir,
        odonav::offline::OfflineParams params, const odonav::dead_reckoning::DeadReckoningFacts& dr_facts) {
  const auto t_start = std::chrono::steady_clock::now();
  // Checked before any work: a user's directory (or the dataset itself) is never written into.
  odonav::OutputPolicy policy;
  policy.force = opts.get_bool("force");
  policy.inputs = {dataset_dir, opts.get_string("coarse-k-from")};
  const odonav::OutputDirectory out(out_dir, policy);
  const odonav::BadRowPolicy bad_rows = odonav::parse_bad_row_policy(opts.get_string("on-bad-row"));
  odonav::DatasetReadReport report;
  auto first = std::make_shared<odonav::DatasetStream>(dataset_dir, bad_rows, &report);
  const odonav::DatasetMeta meta = first->meta();
  const bool has_ins = first->has_ins();
  bool has_truth = first->has_truth();
  // A truth file of another drive would score this one against the wrong track: refused (the run
  // is evaluated against the GNSS fixes instead), named in the log and in summary.json.
  std::optional<std::string> truth_refused;
  if (has_truth) {
    truth_refused = odonav::offline::truth_mismatch(
        odonav::offline::Source<odonav::GnssSample>(odonav::gnss_rows(dataset_dir, bad_rows)),
        odonav::offline::Source<odonav::TruthSample>(odonav::truth_rows(dataset_dir, bad_rows)));
    if (truth_refused) {
      spdlog::warn("{}: {}; evaluating against the GNSS fixes instead", dataset_dir, *truth_refused);
      has_truth = false;
    }
  }
  if (!has_ins) spdlog::warn("{}: no ins.csv: degraded mode (no misalignment; DR on the GNSS course)", dataset_dir);
  apply_dataset_defaults(meta, has_ins, opts, dr_facts, params);
  if (!apply_coarse_k(opts, params)) return 1;

  odonav::offline::SummaryInputs inputs;
  inputs.meta = meta;
  // The summary's evaluations read these files with cursors of their own, which move side by side
  // through the first pass (shared_source: each file parsed once for them).
  // truth.csv's first reader counts its rows and tells its bad rows (into the report, as for the
  // sensor files); the readers of later generations are quiet.
  // Its report is its own while the output thread reads it (the sensor files' report is the first
  // stream's), merged into the run's at the end.
  odonav::DatasetReadReport truth_file_report;
  auto truth_report = std::make_shared<std::optional<odonav::TruthStream>>();
  const auto open_truth = [dataset_dir, bad_rows, &truth_file_report,
                           truth_report]() -> odonav::offline::Source<odonav::TruthSample> {
    if (!*truth_report) {
      truth_report->emplace(dataset_dir, bad_rows, &truth_file_report);
      return [truth_report] { return (*truth_report)->next(); };
    }
    return odonav::truth_rows(dataset_dir, bad_rows);
  };
  if (has_truth) inputs.truth = odonav::offline::shared_source<odonav::TruthSample>(open_truth);
  inputs.gnss = odonav::offline::shared_source<odonav::GnssSample>([dataset_dir, bad_rows] {
    return odonav::offline::Source<odonav::GnssSample>(odonav::gnss_rows(dataset_dir, bad_rows));
  });
  if (has_ins)
    inputs.ins = odonav::offline::shared_source<odonav::InsSample>([dataset_dir, bad_rows] {
      return odonav::offline::Source<odonav::InsSample>(odonav::ins_rows(dataset_dir, bad_rows));
    });
  inputs.options.dataset_name = base_name(dataset_dir);
  odonav::offline::SummaryAccumulator summary(std::move(inputs));
  odonav::offline::RunDiagnosisAccumulator diagnosis;
  odonav::DatasetFingerprint fingerprint(meta.vehicle_id);

  std::vector<std::string> estimators;
  if (params.identification.run_all_estimators) estimators = odonav::estimator_names();
  OutputFiles files(out, params.identification.estimator_name, estimators, summary, diagnosis);
  CoarseFile coarse(out, summary);
  OutputThread output([&](OutputItem& item) {
    if (const auto* t = std::get_if<InputTime>(&item)) {
      switch (t->kind) {
        case odonav::DatasetStreamKind::kOdometer:
          summary.add_odometer(t->t_s);
          diagnosis.add_odometer(t->t_s);
          break;
        case odonav::DatasetStreamKind::kGnss: diagnosis.add_gnss(t->t_s); break;
        case odonav::DatasetStreamKind::kIns: diagnosis.add_ins(t->t_s); break;
      }
    } else if (const auto* m = std::get_if<odonav::calibration::MisalignmentOutput>(&item)) {
      files.on_misalignment(*m);
    } else if (const auto* k = std::get_if<odonav::identification::IdentificationOutput>(&item)) {
      files.on_scale_factor(*k);
    } else if (auto* step = std::get_if<odonav::dead_reckoning::DeadReckoningStep>(&item)) {
      files.on_dead_reckoning(std::move(*step));
    } else {
      coarse.on_dead_reckoning(std::move(std::get<CoarseStep>(item).step));
    }
  });
  HandOver to_files(output, false), to_coarse_file(output, true);
  InputTap tap{output, fingerprint};
  int pass = 0;
  const odonav::offline::OpenSampleStream open = [&]() -> odonav::offline::SampleStream {
    odonav::offline::SampleStream stream = open_pass(dataset_dir, bad_rows, first);
    if (pass++ == 0)
      return [stream, &tap]() {
        std::optional<odonav::DatasetEvent> e = stream();
        if (e) tap(*e);
        return e;
      };
    // The fingerprint runs over every GNSS sample, then every odometer sample: the second pass
    // gives it the odometer samples.
    return [stream, &fingerprint]() {
      std::optional<odonav::DatasetEvent> e = stream();
      if (e && e->kind == odonav::DatasetStreamKind::kOdometer) fingerprint.add(e->odometer);
      return e;
    };
  };
  const odonav::offline::OfflineRunTotals totals =
      odonav::offline::run_offline(open, has_ins, params, to_files, to_coarse_file);
  output.finish();
  {
    // The rest of truth.csv through its reporting reader (all of it when the summary read none), so
    // every row is counted; before the files are complete, so a bad row under --on-bad-row=fail
    // leaves no output, as any other bad row.
    const odonav::offline::Source<odonav::TruthSample> rest =
        *truth_report ? [truth_report] { return (*truth_report)->next(); } : open_truth();
    while (rest()) {
    }
    for (const odonav::FileReadReport& f : truth_file_report.files) report.files.push_back(f);
    for (const odonav::BadRow& b : truth_file_report.bad_rows)
      if (report.bad_rows.size() < odonav::kMaxDetailedBadRows) report.bad_rows.push_back(b);
  }
  files.close();
  coarse.close();
  for (const auto& f : report.files)
    if (f.rows_bad) spdlog::warn("{}: skipped {} bad rows (kept {})", f.file, f.rows_bad, f.rows_read);
  const auto t_done = std::chrono::steady_clock::now();
  const double elapsed_s = std::chrono::duration<double>(t_done - t_start).count();
  spdlog::info("read and processed in {:.3f} s ({} odometer, {} GNSS, {} INS rows)", elapsed_s, tap.odometer, tap.gnss,
               tap.ins);

  summary.options().elapsed_s = elapsed_s;
  summary.options().coarse_k_origin = totals.coarse_k_origin;
  nlohmann::json summary_json = summary.finish();
  add_run_facts(summary_json, totals, report);
  const odonav::offline::RunDiagnosis result_diagnosis =
      diagnosis.finish(params, totals.builder_counters, totals.calibration_counters, totals.dr_counters,
                       totals.consistency, totals.gnss_jumps);
  odonav::offline::add_consistency(summary_json, totals.consistency);
  summary_json["warnings"] = nlohmann::json::array();
  for (const odonav::offline::RunWarning& w : result_diagnosis.warnings) {
    spdlog::warn("{}", w.message);
    summary_json["warnings"].push_back({{"code", w.code}, {"message", w.message}});
  }
  if (truth_refused)
    summary_json["warnings"].push_back(
        {{"code", "truth_refused"}, {"message", *truth_refused + "; evaluated against the GNSS fixes instead"}});
  odonav::write_file_atomically(out.file("summary.json"), summary_json.dump(2) + "\n");
  odonav::RunProvenance provenance;
  provenance.tool = "odonav-offline";
  provenance.vehicle_id = meta.vehicle_id;
  provenance.dataset_fingerprint = fingerprint.text();
  provenance.t_first_s = tap.first_s;
  provenance.t_last_s = tap.last_s;
  odonav::write_file_atomically(out.file(odonav::kProvenanceFile), odonav::provenance_json(provenance));
  odonav::offline::print_summary(summary_json, odonav::tool_output());
  spdlog::info("outputs in {}", out_dir);
  if (!result_diagnosis.usable) {
    spdlog::error("no usable result (exit status {}): see the warnings", odonav::offline::kExitNoUsableResult);
    return odonav::offline::kExitNoUsableResult;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  odonav::Options opts = make_options();
  if (const auto exit_code = parse_command_line(opts, argc, argv)) return *exit_code;
  const std::string dataset_dir = opts.get_string("dataset");
  const std::string out_dir = opts.get_string("out");
  if (out_dir.empty()) {
    spdlog::error("--out is required (the folder for the output files)");
    return 2;
  }
  odonav::offline::OfflineParams params;
  odonav::dead_reckoning::DeadReckoningFacts dr_facts;  // completed from the dataset below
  try {
    // Checked here (exit status 2 for a bad option); built again below with the dataset's facts.
    params.identification = odonav::identification::identification_params_for(opts, {});
    params.calibration = odonav::calibration::calibration_params_from(opts);
    dr_facts = odonav::dead_reckoning::dead_reckoning_facts_from(opts);
  } catch (const odonav::ConfigError& e) {
    spdlog::error("{}", e.what());
    return 2;
  }
  try {
    return run(opts, dataset_dir, out_dir, std::move(params), dr_facts);
  } catch (const odonav::DatasetError& e) {
    spdlog::error("{}", e.what());
    return 1;
  } catch (const odonav::StreamInputError& e) {
    spdlog::error("bad input: {}", e.what());
    return 1;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
}
