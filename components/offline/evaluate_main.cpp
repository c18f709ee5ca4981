// odonav-evaluate: the summary of a folder of output files (from odonav-offline or from the
// distributed pipeline's recorder) against its dataset, printed and written to summary.json.
#include <fstream>

#include "odonav/config.hpp"
#include "odonav/dataset.hpp"
#include "odonav/logging.hpp"
#include "odonav/tool_output.hpp"
#include "odonav/results/output_files.hpp"
#include "summary.hpp"

int main(int argc, char** argv) {
  odonav::Options opts("odonav-evaluate",
                       "Evaluates a folder of odonav output files (misalignment.csv, scale_factor.csv, "
                       "dead_reckoning.csv, optional dead_reckoning_coarse.csv) against the dataset they came "
                       "from: prints the summary and writes summary.json into the folder.");
  opts.add_positional("dataset", "dataset directory the outputs were computed from");
  opts.add_positional("results", "folder with the output files");
  opts.add_string("coarse-k-origin", "", "where the coarse K came from, for the summary");
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
    const odonav::Dataset dataset = odonav::read_dataset(opts.get_string("dataset"), odonav::BadRowPolicy::kSkip);
    const odonav::results::OutputRows rows = odonav::results::read_output_rows(results);
    odonav::offline::SummaryOptions o;
    o.dataset_name = opts.get_string("dataset");
    o.coarse_k_origin = opts.get_string("coarse-k-origin");
    const nlohmann::json summary = odonav::offline::make_summary(dataset, rows, o);
    std::ofstream(results + "/summary.json") << summary.dump(2) << "\n";
    odonav::offline::print_summary(summary, odonav::tool_output());
    return 0;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
}
