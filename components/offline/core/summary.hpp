#pragma once
// The summary of a run: what odonav-offline prints and writes to summary.json, and what the
// distributed pipeline's demo prints (from the files its recorder wrote). Computed from the output
// rows and the dataset, so both paths report the same figures for the same outputs.
#include <iosfwd>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "evaluation.hpp"
#include "odonav/dataset.hpp"
#include "odonav/results/output_files.hpp"

namespace odonav::offline {

struct SummaryOptions {
  std::string dataset_name;
  std::string coarse_k_origin;                  ///< where the coarse K came from.
  std::optional<double> elapsed_s;              ///< processing time, when measured.
  double dr_min_distance_m = 100.0;             ///< %D maxima ignore the first metres.
  KEvaluationParams k_evaluation;
};

/// Builds summary.json's content. Truth figures appear when the dataset has truth (K timeline from
/// meta.json's simulation.k_steps when present, else truth.csv's k_true; misalignment truth from
/// meta.json; positions from truth.csv, else valid GNSS fixes).
nlohmann::json make_summary(const Dataset& dataset, const results::OutputRows& rows, const SummaryOptions& options);

/// Prints the summary as a readable table.
void print_summary(const nlohmann::json& summary, std::ostream& out);

}  // namespace odonav::offline
