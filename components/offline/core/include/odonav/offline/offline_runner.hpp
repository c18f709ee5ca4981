#pragma once
// odonav-offline's run: the distributed pipeline's components (calibration, identification, dead
// reckoning) wired in one process by OfflinePipeline (offline_pipeline.hpp), over a dataset read as
// one time-ordered stream, in two passes: the pipeline itself, then dead reckoning with the coarse K
// (the identification's final coarse S/N estimate, known only at the end of the first pass). Each
// output goes to a sink as it is made, so memory does not grow with the drive.
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "odonav/calibration/misalignment_calibrator.hpp"
#include "odonav/dataset.hpp"
#include "odonav/dataset_stream.hpp"
#include "odonav/dead_reckoning/dead_reckoner.hpp"
#include "odonav/identification/identification_core.hpp"
#include "odonav/offline/offline_pipeline.hpp"

namespace odonav::offline {

struct OfflineParams {
  calibration::MisalignmentCalibratorParams calibration;
  identification::IdentificationParams identification;
  dead_reckoning::DeadReckonerParams dead_reckoning;  ///< nominal_k is the K before identification converges.
  dead_reckoning::AnchoredPositionParams anchored;    ///< the navigation position anchored on GNSS (online DR).
  /// K for the "coarse" DR run (m/pulse). Unset: the coarse S/N estimate of this dataset (its final
  /// value, as a calibration run done before the drive would give), or the nominal K without one.
  std::optional<double> coarse_k_m_per_pulse;
  std::string coarse_k_origin;  ///< where coarse_k_m_per_pulse came from, for the summary.
};

/// A dataset's sensor samples in event-time order, one per call; nullopt at the end.
using SampleStream = std::function<std::optional<DatasetEvent>()>;
/// Opens a fresh SampleStream over the same dataset (once per pass).
using OpenSampleStream = std::function<SampleStream()>;

/// A stream over an in-memory dataset (the order DatasetStream gives: by t_s; equal t_s GNSS, INS,
/// odometer). `dataset` must outlive the stream.
SampleStream samples_of(const Dataset& dataset);

/// What a streaming run leaves besides the outputs it delivered.
struct OfflineRunTotals {
  std::vector<std::string> estimator_names;  ///< order of IdentificationOutput::all.
  std::optional<identification::IdentificationOutput>
      last_identification;  ///< the final estimate (none without GNSS epochs)
  double coarse_k_m_per_pulse = 0.0;
  std::string coarse_k_origin;
  SampleBuilderCounters builder_counters;
  calibration::MisalignmentCounters calibration_counters;
  dead_reckoning::DeadReckonerCounters dr_counters;
  dead_reckoning::AnchoredPositionCounters anchored_counters;
  /// The online dead reckoning's consistency checks at the end (consistency_monitor.hpp), by
  /// ConsistencyCheck.
  std::vector<dead_reckoning::ConsistencyState> consistency;
  dead_reckoning::GnssJumpCounters gnss_jumps;  ///< GNSS position jumps (consistency_monitor.hpp)
};

/// A run over an in-memory dataset with every output kept (tests, benchmarks).
struct OfflineResult : OfflineRunTotals {
  std::vector<calibration::MisalignmentOutput> misalignment;          ///< one per GNSS epoch.
  std::vector<identification::IdentificationOutput> identification;   ///< one per GNSS epoch.
  std::vector<dead_reckoning::DeadReckoningOutput> dr_online;         ///< DR with the identified K.
  std::vector<dead_reckoning::AnchoredPosition> navigation_position;  ///< dr_online anchored on GNSS, one per output.
  std::vector<dead_reckoning::DeadReckoningOutput> dr_coarse;         ///< DR with the coarse K.
};

/// Runs the pipeline over open()'s samples, delivering every output to `sink` as it is made, then
/// the coarse dead reckoning over a second stream, delivering its outputs to `coarse_sink`
/// (on_dead_reckoning only; the calibration runs again there, and its outputs, identical, are not
/// delivered). has_ins: the dataset has INS (false: degraded mode for every component). Throws
/// StreamInputError / std::invalid_argument on bad input or params, and what open()'s stream throws.
OfflineRunTotals run_offline(const OpenSampleStream& open, bool has_ins, const OfflineParams& params,
                             PipelineSink& sink, PipelineSink& coarse_sink);

/// run_offline over an in-memory dataset, every output kept.
OfflineResult run_offline(const Dataset& dataset, const OfflineParams& params);

/// The coarse S/N K of a dataset (its final coarse estimate), or nullopt if it has no usable
/// straight run. Runs calibration and identification as run_offline does.
std::optional<double> coarse_k_of(const OpenSampleStream& open, bool has_ins, const OfflineParams& params);
std::optional<double> coarse_k_of(const Dataset& dataset, const OfflineParams& params);

}  // namespace odonav::offline

#include "odonav/results/output_files.hpp"

namespace odonav::offline {

/// The output rows of a run (what the files hold), each made by its component's output_row, the
/// function its DDS node publishes from.
results::OutputRows to_output_rows(const OfflineResult& result, const std::string& main_estimator);

}  // namespace odonav::offline
