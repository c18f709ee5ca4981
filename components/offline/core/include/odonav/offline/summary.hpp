#pragma once
// The summary of a run: what odonav-offline prints and writes to summary.json, and what the
// distributed pipeline's demo prints (from the files its recorder wrote). Computed from the output
// rows and the dataset, so both paths report the same figures for the same outputs.
#include <cstddef>
#include <iosfwd>
#include <memory>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "odonav/offline/evaluation.hpp"
#include "odonav/dataset.hpp"
#include "odonav/dead_reckoning/consistency_monitor.hpp"
#include "odonav/results/output_files.hpp"

namespace odonav::offline {

struct SummaryOptions {
  std::string dataset_name;
  std::string coarse_k_origin;       ///< where the coarse K came from.
  std::optional<double> elapsed_s;   ///< processing time, when measured.
  double dr_min_distance_m = 100.0;  ///< %D maxima ignore the first metres.
  KEvaluationParams k_evaluation;
};

/// What the summary reads of the dataset besides the output rows: meta.json, and the truth, GNSS and
/// INS files as sources (each opened as often as the evaluations need a cursor of their own; none
/// is held in memory). An empty factory is a file the dataset does not have.
struct SummaryInputs {
  DatasetMeta meta;
  SourceFactory<TruthSample> truth;
  SourceFactory<GnssSample> gnss;
  SourceFactory<InsSample> ins;
  SummaryOptions options;
};

/// The inputs of make_summary over a dataset in memory (which must outlive the accumulator).
SummaryInputs summary_inputs(const Dataset& dataset, const SummaryOptions& options);

/// summary.json's content computed as the outputs are produced, one row at a time, in memory that
/// does not grow with the drive's length (it grows with the simulator's K steps, the outages, and the
/// lag between the dead-reckoning and navigation-position rows, which are matched by time).
/// Feed each stream in time order; the streams may interleave in any way, except that the
/// navigation rows should be fed alongside the online dead-reckoning rows (not after all of them)
/// and each odometer time before the outputs at that time, else rows wait in memory.
class SummaryAccumulator {
 public:
  /// Reads meta.json's "simulation" object (throws DatasetError naming a malformed key) and opens the
  /// sources.
  explicit SummaryAccumulator(SummaryInputs inputs);
  ~SummaryAccumulator();
  SummaryAccumulator(const SummaryAccumulator&) = delete;
  SummaryAccumulator& operator=(const SummaryAccumulator&) = delete;

  /// The time (s) of each odometer sample: the drive's span and rate, and which of the simulator's
  /// K steps the drive reaches.
  void add_odometer(double t_s);
  void add(const results::MisalignmentRow& row);
  void add(const results::ScaleFactorRow& row);
  /// A dead_reckoning.csv row (the online K).
  void add_dead_reckoning(const results::DeadReckoningRow& row);
  /// A dead_reckoning_coarse.csv row (the coarse K); may come after every other row.
  void add_dead_reckoning_coarse(const results::DeadReckoningRow& row);
  void add(const results::NavigationPositionRow& row);
  /// The options, for a caller that learns some only at the end of the run (the processing time,
  /// the coarse K's origin): read by finish().
  SummaryOptions& options();
  /// summary.json's content (make_summary's); reads the rest of the sources. Call once.
  nlohmann::json finish();

  /// Sizes of the accumulator's buffers (items), to check that they do not grow with the drive.
  struct Footprint {
    std::size_t scale_factor_rows_waiting = 0;  ///< rows past a K step the odometer has not reached yet
    std::size_t navigation_rows_buffered = 0;   ///< navigation rows kept for matching by time
    std::size_t dead_reckoning_rows_buffered = 0;
    std::size_t outages = 0;
  };
  Footprint footprint() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Builds summary.json's content. Truth figures appear when the dataset has truth (K timeline from
/// meta.json's simulation.k_steps when present, else truth.csv's k_true; misalignment truth from
/// meta.json; positions from truth.csv, else valid GNSS fixes). A SummaryAccumulator fed the rows.
nlohmann::json make_summary(const Dataset& dataset, const results::OutputRows& rows, const SummaryOptions& options);

/// Prints the summary as a readable table.
void print_summary(const nlohmann::json& summary, std::ostream& out);

/// Adds the dead reckoning's consistency checks (OfflineRunTotals::consistency) to a summary as
/// "consistency", and withdraws "converged" (false, with "converged_withdrawn" naming the finding) of
/// the misalignment while a heading-rate or drift check is raised at the end, and of the scale
/// factor while an odometer-speed or drift check is.
void add_consistency(nlohmann::json& summary, const std::vector<dead_reckoning::ConsistencyState>& checks);

}  // namespace odonav::offline
