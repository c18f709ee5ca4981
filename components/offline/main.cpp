// odonav-offline: runs calibration -> identification -> dead reckoning over a dataset directory
// without DDS, writes the output files and summary.json, prints a summary. See README.md.

#include <chrono>
#include <optional>

#include "odonav/calibration/calibration_options.hpp"
#include "odonav/config.hpp"
#include "odonav/dataset.hpp"
#include "odonav/dead_reckoning/dead_reckoning_options.hpp"
#include "odonav/identification/identification_options.hpp"
#include "odonav/logging.hpp"
#include "odonav/run_provenance.hpp"
#include "odonav/safe_output.hpp"
#include "odonav/stream_buffers.hpp"
#include "odonav/tool_output.hpp"
#include "offline_runner.hpp"
#include "run_diagnosis.hpp"
#include "summary.hpp"

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
  opts.add_string("out", "", "output directory (created if missing; an existing one must be empty or an odonav "
                  "output directory, see --force); required");
  opts.add_bool("force", false, "write into an existing non-empty directory that is not an odonav output directory");
  opts.add_choice("on-bad-row", "fail", {"fail", "skip"}, "a bad input row stops the run (fail) or is skipped and counted");
  opts.add_double("coarse-k", 0.0, "K for the coarse DR run (m/pulse); 0 = see --coarse-k-from", 0.0, 10.0);
  opts.add_string("coarse-k-from", "",
                  "dataset whose coarse S/N calibration gives the coarse K (e.g. a 'straight' run); empty = this "
                  "dataset's own coarse S/N estimate");
  opts.add_string("log-level", "", "trace, debug, info, warn, error, critical, off (default: $ODONAV_LOG_LEVEL or info)");
  odonav::add_identification_options(opts);
  odonav::add_calibration_options(opts);
  odonav::add_dead_reckoning_options(opts);
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

/// The dataset, with its skipped bad rows logged (warn) and counted in `report`.
odonav::Dataset read_input(const std::string& dataset_dir, const odonav::Options& opts,
                           odonav::DatasetReadReport& report) {
  odonav::Dataset dataset =
      odonav::read_dataset(dataset_dir, odonav::parse_bad_row_policy(opts.get_string("on-bad-row")), &report);
  if (report.total_bad() > 0) {
    for (const auto& f : report.files)
      if (f.rows_bad) spdlog::warn("{}: skipped {} bad rows (kept {})", f.file, f.rows_bad, f.rows_read);
  }
  if (!dataset.has_ins()) spdlog::warn("{}: no ins.csv: degraded mode (no misalignment; DR on the GNSS course)", dataset_dir);
  return dataset;
}

/// What the flags leave open, from the dataset's meta.json: the GNSS lever arm (body frame, m) and
/// the nominal K (m/pulse: the flag, else meta.json, else 0.0125, dead_reckoner_params); then the identification
/// parameters from the flags and these vehicle facts.
void apply_dataset_defaults(const odonav::Dataset& dataset, const odonav::Options& opts,
                            odonav::DeadReckoningFacts dr_facts, odonav::offline::OfflineParams& params) {
  if (!dr_facts.lever_arm_body_m && dataset.meta.gnss_lever_arm_m) {
    const Eigen::Vector3d& l = *dataset.meta.gnss_lever_arm_m;
    spdlog::info("GNSS lever arm from meta.json: ({}, {}, {}) m (forward, left, up)", l.x(), l.y(), l.z());
    dr_facts.lever_arm_body_m = l;
    params.calibration.lever_arm_body_m = l;
  }
  dr_facts.use_ins = dataset.has_ins();
  dr_facts.dataset_nominal_k_m_per_pulse = dataset.meta.k_nominal_m_per_pulse;
  params.dead_reckoning = odonav::dead_reckoner_params(dr_facts);  // as odonav-dead-reckoning's
  params.anchored = odonav::anchored_position_params(dr_facts);    // likewise
  // The same function as odonav-identification, with the same vehicle facts the launcher gives
  // it as flags (deploy/launch): INS present, lever arm, nominal K (the pulse-jump gate's K).
  odonav::IdentificationVehicleFacts vehicle;
  vehicle.use_ins = dataset.has_ins();
  vehicle.lever_arm_body_m = params.dead_reckoning.lever_arm_body_m;
  vehicle.nominal_k_m_per_pulse = params.dead_reckoning.nominal_k_m_per_pulse;
  vehicle.run_all_estimators = true;  // every estimator side by side
  params.identification = odonav::identification_params_for(opts, vehicle);
}

/// The coarse K of --coarse-k or --coarse-k-from (neither: run_offline takes this dataset's own).
/// False (logged) when the --coarse-k-from dataset has no straight run long enough.
bool apply_coarse_k(const odonav::Options& opts, odonav::offline::OfflineParams& params) {
  if (opts.get_double("coarse-k") > 0.0) {
    params.coarse_k_m_per_pulse = opts.get_double("coarse-k");
    params.coarse_k_origin = "--coarse-k";
  } else if (!opts.get_string("coarse-k-from").empty()) {
    const std::string from = opts.get_string("coarse-k-from");
    const odonav::Dataset calibration_run = odonav::read_dataset(from, odonav::BadRowPolicy::kFail);
    const auto k = odonav::offline::coarse_k_of(calibration_run, params);
    if (!k) {
      spdlog::error("{}: no straight run long enough for a coarse S/N calibration", from);
      return false;
    }
    params.coarse_k_m_per_pulse = *k;
    params.coarse_k_origin = "coarse S/N of " + base_name(from);
  }
  return true;
}

/// summary.json: make_summary plus the identification gates' counts and the skipped bad rows.
nlohmann::json offline_summary(const odonav::Dataset& dataset, const std::string& dataset_dir,
                               const odonav::offline::OfflineResult& result, const odonav::results::OutputRows& rows,
                               const odonav::DatasetReadReport& report, double elapsed_s) {
  odonav::offline::SummaryOptions summary_options;
  summary_options.dataset_name = base_name(dataset_dir);
  summary_options.coarse_k_origin = result.coarse_k_origin;
  summary_options.elapsed_s = elapsed_s;
  nlohmann::json summary = odonav::offline::make_summary(dataset, rows, summary_options);
  summary["gates"] = {{"epochs", result.builder_counters.epochs},
                      {"accepted", result.builder_counters.accepted},
                      {"invalid_fix", result.builder_counters.invalid_fix},
                      {"speed_jump", result.builder_counters.speed_jump},
                      {"min_speed", result.builder_counters.min_speed},
                      {"yaw_rate", result.builder_counters.yaw_rate},
                      {"gap", result.builder_counters.gap},
                      {"innovation", result.builder_counters.innovation},
                      {"cross_track", result.builder_counters.cross_track},
                      {"reversing", result.builder_counters.reversing},
                      {"reversing_accepted", result.builder_counters.reversing_accepted}};
  summary["bad_rows_skipped"] = report.total_bad();
  if (!result.identification.empty() && summary.contains("scale_factor")) {
    const odonav::TurnSlipEstimate& slip = result.identification.back().turn_slip;
    summary["scale_factor"]["turn_slip_samples"] = slip.samples;
    summary["scale_factor"]["turn_slip_outliers"] = slip.outliers;
    summary["scale_factor"]["turn_slip_reason"] = slip.reason;  // why it is not applied; "" when it is
  }
  return summary;
}

/// Reads, runs, writes the files and prints the summary. Exit code 0, 1 (an error, logged) or
/// kExitNoUsableResult (no K or no dead reckoning: the warnings say why).
int run(const odonav::Options& opts, const std::string& dataset_dir, const std::string& out_dir,
        odonav::offline::OfflineParams params, const odonav::DeadReckoningFacts& dr_facts) {
  const auto t_start = std::chrono::steady_clock::now();
  // Checked before any work: a user's directory (or the dataset itself) is never written into.
  odonav::OutputPolicy policy;
  policy.force = opts.get_bool("force");
  policy.inputs = {dataset_dir, opts.get_string("coarse-k-from")};
  const odonav::OutputDirectory out(out_dir, policy);
  odonav::DatasetReadReport report;
  const odonav::Dataset dataset = read_input(dataset_dir, opts, report);
  apply_dataset_defaults(dataset, opts, dr_facts, params);
  if (!apply_coarse_k(opts, params)) return 1;

  const auto t_read = std::chrono::steady_clock::now();
  const odonav::offline::OfflineResult result = odonav::offline::run_offline(dataset, params);
  const odonav::results::OutputRows rows = odonav::offline::to_output_rows(result, params.identification.estimator_name);
  const auto t_done = std::chrono::steady_clock::now();
  const double elapsed_s = std::chrono::duration<double>(t_done - t_start).count();
  spdlog::info("read {:.3f} s, processed {:.3f} s ({} odometer, {} GNSS, {} INS rows)",
               std::chrono::duration<double>(t_read - t_start).count(),
               std::chrono::duration<double>(t_done - t_read).count(), dataset.odometer.size(), dataset.gnss.size(),
               dataset.ins.size());

  odonav::results::write_output_rows(out.path(), rows);
  nlohmann::json summary = offline_summary(dataset, dataset_dir, result, rows, report, elapsed_s);
  const odonav::offline::RunDiagnosis diagnosis = odonav::offline::diagnose_run(dataset, params, result);
  summary["warnings"] = nlohmann::json::array();
  for (const odonav::offline::RunWarning& w : diagnosis.warnings) {
    spdlog::warn("{}", w.message);
    summary["warnings"].push_back({{"code", w.code}, {"message", w.message}});
  }
  odonav::write_file_atomically(out.file("summary.json"), summary.dump(2) + "\n");
  odonav::write_file_atomically(out.file(odonav::kProvenanceFile),
                                odonav::provenance_json(odonav::provenance_of(dataset, "odonav-offline")));
  odonav::offline::print_summary(summary, odonav::tool_output());
  spdlog::info("outputs in {}", out_dir);
  if (!diagnosis.usable) {
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
  odonav::DeadReckoningFacts dr_facts;  // completed from the dataset below
  try {
    // Checked here (exit status 2 for a bad option); built again below with the dataset's facts.
    params.identification = odonav::identification_params_for(opts, {});
    params.calibration = odonav::calibration_params_from(opts);
    dr_facts = odonav::dead_reckoning_facts_from(opts);
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
