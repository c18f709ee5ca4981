#pragma once
// The distributed pipeline's processing components in one process, for odonav-offline: the
// calibration (MisalignmentCalibrator), the identification (IdentificationCore) and dead reckoning
// (DeadReckoningComponent), the same classes the DDS nodes run, connected by an in-process
// event-time transport instead of DDS topics.
//
// Input: the sensor samples of a dataset in event-time order (odometer, INS, GNSS interleaved by
// stamp; equal stamps in any order). Each component's outputs go to the components that subscribe
// to them, converted by the functions their nodes publish from (published_misalignment,
// published_scale_factor), and to the sink, as they are made.
//
// When a component processes: as its DDS node does. Each consumer has its own EventTimeAligner over
// the inputs its core declares (identification_inputs, dead_reckoning_inputs: the list its node
// subscribes, with the same pacing and hold-off), fed every sample it receives; the
// sensor streams are declared complete up to the last stamp passed (the dataset is read in time
// order, as the gateway's completeness declaration says on the bus), and the aligner's watermark
// decides how far the component's process_until may go. An estimate therefore reaches its consumer
// before any output that depends on it is computed, whatever the processing schedule, so the
// outputs are those of the pipeline (and of a run over whole vectors), and memory stays bounded by
// the hold-off and the components' own windows, not by the drive.
#include <memory>
#include <optional>
#include <string>

#include "odonav/calibration/misalignment_calibrator.hpp"
#include "odonav/dead_reckoning/dead_reckoning_component.hpp"
#include "odonav/event_time_aligner.hpp"
#include "odonav/identification/identification_core.hpp"

namespace odonav::offline {

/// Receives the pipeline's outputs as they are made, each kind in event-time order.
class PipelineSink {
 public:
  virtual ~PipelineSink() = default;
  virtual void on_misalignment(const calibration::MisalignmentOutput& /*output*/) {}
  virtual void on_scale_factor(const identification::IdentificationOutput& /*output*/) {}
  // By value: a forwarding sink moves the step on.
  virtual void on_dead_reckoning(dead_reckoning::DeadReckoningStep /*step*/) {
  }  // NOLINT(performance-unnecessary-value-param)
};

/// Which components run, with their parameters.
struct PipelineConfig {
  calibration::MisalignmentCalibratorParams calibration;
  /// Unset: no identification (dead reckoning keeps its nominal K and a zero GNSS latency).
  std::optional<identification::IdentificationParams> identification;
  /// Unset: no dead reckoning.
  std::optional<dead_reckoning::DeadReckonerParams> dead_reckoning;
  dead_reckoning::AnchoredPositionParams anchored;
  /// Compute the GNSS-anchored navigation position of each dead-reckoning output (off: a run whose
  /// positions nobody reads, e.g. the coarse-K pass).
  bool navigation = true;
  /// The identification instance's name, as a node publishes it in ScaleFactor.source.
  std::string identification_source = "identification";
};

class OfflinePipeline {
 public:
  /// Throws std::invalid_argument naming a parameter out of range. `sink` must outlive this.
  OfflinePipeline(const PipelineConfig& config, PipelineSink& sink);
  ~OfflinePipeline();
  OfflinePipeline(const OfflinePipeline&) = delete;
  OfflinePipeline& operator=(const OfflinePipeline&) = delete;

  /// Sensor samples in event-time order across the three kinds (stamps, s, non-decreasing). Each
  /// stamp is taken as the pipeline's nodes read it from the gateway's message (wire_time_s: rounded
  /// to the nanosecond), so samples that share a stamp on the bus share it here.
  /// StreamInputError from a component on bad input (as the cores throw it).
  void add_odometer(const OdometerSample& sample);
  void add_gnss(const GnssSample& sample);
  void add_ins(const InsSample& sample);  ///< ignored by the components whose params say use_ins = false
  /// End of data: every component finishes in pipeline order and every remaining output is delivered.
  void finish();

  const calibration::MisalignmentCalibrator& calibration() const { return calibration_; }
  /// nullptr when not configured.
  const identification::IdentificationCore* identification() const { return identification_.get(); }
  const dead_reckoning::DeadReckoningComponent* dead_reckoning() const { return dead_reckoning_.get(); }

 private:
  struct Consumer;  // a component's aligner and its input streams
  void advance_to(double t_s);
  /// A sensor sample as the nodes receive it (its stamp as the gateway's message carries it), after
  /// advance_to its stamp.
  template <class Sample>
  Sample arrive(const Sample& sample);
  void process(double complete_through_s);
  void deliver_misalignments(const std::vector<calibration::MisalignmentOutput>& outputs);
  void deliver_scale_factors(const std::vector<identification::IdentificationOutput>& outputs);
  void deliver_dead_reckoning(std::vector<dead_reckoning::DeadReckoningOutput> outputs);

  PipelineConfig config_;
  PipelineSink& sink_;
  calibration::MisalignmentCalibrator calibration_;
  std::unique_ptr<identification::IdentificationCore> identification_;
  std::unique_ptr<dead_reckoning::DeadReckoningComponent> dead_reckoning_;
  std::unique_ptr<Consumer> identification_inputs_;
  std::unique_ptr<Consumer> dead_reckoning_inputs_;
  std::optional<double> pending_t_s_;  ///< stamp of the samples passed since the last processing
  std::optional<double> last_gnss_t_s_;
  bool finished_ = false;
};

}  // namespace odonav::offline
