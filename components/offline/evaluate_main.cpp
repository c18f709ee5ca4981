// odonav-evaluate: the summary of a folder of output files (from odonav-offline or from the
// distributed pipeline's recorder) against its dataset, printed and written to summary.json.
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <string>

#include "odonav/config.hpp"
#include "odonav/dataset.hpp"
#include "odonav/logging.hpp"
#include "odonav/tool_output.hpp"
#include "odonav/results/output_files.hpp"
#include "odonav/run_provenance.hpp"
#include "odonav/safe_output.hpp"
#include "odonav/offline/evaluation.hpp"
#include "odonav/offline/summary.hpp"

namespace {

namespace results = odonav::results;

// The event-time span of every row of the results files (s); NaN when there is none. Read row by row.
std::pair<double, double> rows_span_s(const std::string& dir) {
  double first = std::numeric_limits<double>::infinity(), last = -first;
  const auto extend = [&](const std::string& file, auto row, bool optional) {
    if (optional && !results::output_file_exists(dir + "/" + file)) return;
    results::OutputFileReader reader(dir + "/" + file);
    bool any = false;
    while (reader.next(row)) {
      if (!any) first = std::min(first, row.t_s);
      any = true;
    }
    if (any) last = std::max(last, row.t_s);
  };
  extend("misalignment.csv", results::MisalignmentRow{}, false);
  extend("scale_factor.csv", results::ScaleFactorRow{}, false);
  extend("dead_reckoning.csv", results::DeadReckoningRow{}, false);
  extend("dead_reckoning_coarse.csv", results::DeadReckoningRow{}, true);
  if (!std::isfinite(first)) return {std::nan(""), std::nan("")};
  return {first, last};
}

// The summary of the results files against the dataset, the files read row by row into the
// accumulator (the DR and navigation rows interleaved by time, as a run produces them).
nlohmann::json summarize(const odonav::Dataset& dataset, const std::string& dir,
                         const odonav::offline::SummaryOptions& options) {
  odonav::offline::SummaryAccumulator acc(odonav::offline::summary_inputs(dataset, options));
  for (const odonav::OdometerSample& o : dataset.odometer) acc.add_odometer(o.t_s);
  {
    results::OutputFileReader reader(dir + "/misalignment.csv");
    for (results::MisalignmentRow r; reader.next(r);) acc.add(r);
  }
  {
    results::OutputFileReader reader(dir + "/scale_factor.csv");
    for (results::ScaleFactorRow r; reader.next(r);) acc.add(r);
  }
  {
    results::OutputFileReader dr_reader(dir + "/dead_reckoning.csv");
    std::optional<results::OutputFileReader> nav_reader;
    if (results::output_file_exists(dir + "/navigation_position.csv"))
      nav_reader.emplace(dir + "/navigation_position.csv");
    results::DeadReckoningRow dr;
    results::NavigationPositionRow nav;
    bool have_dr = dr_reader.next(dr), have_nav = nav_reader && nav_reader->next(nav);
    while (have_dr || have_nav) {
      if (!have_nav || (have_dr && dr.t_s <= nav.t_s)) {
        acc.add_dead_reckoning(dr);
        have_dr = dr_reader.next(dr);
      } else {
        acc.add(nav);
        have_nav = nav_reader->next(nav);
      }
    }
  }
  if (results::output_file_exists(dir + "/dead_reckoning_coarse.csv")) {
    results::OutputFileReader reader(dir + "/dead_reckoning_coarse.csv");
    for (results::DeadReckoningRow r; reader.next(r);) acc.add_dead_reckoning_coarse(r);
  }
  return acc.finish();
}

}  // namespace

int main(int argc, char** argv) {
  odonav::Options opts("odonav-evaluate",
                       "Evaluates a folder of odonav output files (misalignment.csv, scale_factor.csv, "
                       "dead_reckoning.csv, optional dead_reckoning_coarse.csv) against the dataset they came "
                       "from: prints the summary and writes summary.json into the folder.");
  opts.add_positional("dataset", "dataset directory the outputs were computed from");
  opts.add_positional("results", "folder with the output files");
  opts.add_string("coarse-k-origin", "", "where the coarse K came from, for the summary");
  opts.add_bool("force", false,
                "evaluate even when the results do not seem to belong to the dataset (other vehicle, other "
                "recording, rows outside its time span)");
  opts.add_string("log-level", "", "log level (default: $ODONAV_LOG_LEVEL or info)");
  try {
    if (opts.parse(argc, argv) == odonav::ParseResult::kHelp) return 0;
    odonav::setup_logging("evaluate", opts.get_string("log-level"));
  } catch (const odonav::ConfigError& e) {
    odonav::setup_logging("evaluate", "info");
    spdlog::error("{}", e.what());
    return 2;
  }
  try {
    const std::string results = opts.get_string("results");
    const std::string dataset_dir = opts.get_string("dataset");
    odonav::Dataset dataset = odonav::read_dataset(dataset_dir, odonav::BadRowPolicy::kSkip);
    // A truth file of another drive: refused, the results evaluated against the GNSS fixes instead.
    const std::optional<std::string> truth_refused =
        dataset.truth.empty() ? std::nullopt
                              : odonav::offline::truth_mismatch(odonav::offline::vector_source(dataset.gnss)(),
                                                                odonav::offline::vector_source(dataset.truth)());
    if (truth_refused) {
      spdlog::warn("{}: {}; evaluating against the GNSS fixes instead", dataset_dir, *truth_refused);
      dataset.truth.clear();
    }
    // Results of another drive would be scored as if they were this one's (a 287 %D that means nothing).
    const auto [t_first_s, t_last_s] = rows_span_s(results);
    const std::vector<std::string> mismatches =
        odonav::provenance_mismatches(odonav::read_provenance(results), t_first_s, t_last_s, dataset);
    for (const std::string& m : mismatches) spdlog::error("{} does not belong to {}: {}", results, dataset_dir, m);
    if (!mismatches.empty()) {
      if (!opts.get_bool("force")) {
        spdlog::error("nothing evaluated (--force evaluates anyway)");
        return 1;
      }
      spdlog::warn("evaluating anyway (--force)");
    }
    odonav::offline::SummaryOptions o;
    o.dataset_name = opts.get_string("dataset");
    o.coarse_k_origin = opts.get_string("coarse-k-origin");
    nlohmann::json summary = summarize(dataset, results, o);
    if (!mismatches.empty() || truth_refused) {
      summary["warnings"] = nlohmann::json::array();
      for (const std::string& m : mismatches)
        summary["warnings"].push_back({{"code", "results_not_of_this_dataset"}, {"message", m}});
      if (truth_refused)
        summary["warnings"].push_back(
            {{"code", "truth_refused"}, {"message", *truth_refused + "; evaluated against the GNSS fixes instead"}});
    }
    odonav::write_file_atomically(results + "/summary.json", summary.dump(2) + "\n", {dataset_dir});
    odonav::offline::print_summary(summary, odonav::tool_output());
    return 0;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
}
