#pragma once
// odonav-calibration's DDS node: GNSS fixes and INS attitude in, one Misalignment per GNSS epoch
// out (README.md beside this folder: topics, QoS, parameters, health, event-time rules).
// The core is MisalignmentCalibrator, fed exactly as odonav-offline feeds it, so both publish the
// same numbers for the same data.
#include <memory>
#include <utility>
#include <vector>

#include "odonav/calibration/calibration_lifecycle.hpp"
#include "odonav/calibration/misalignment_calibrator.hpp"
#include "odonav/config.hpp"
#include "odonav/dds/event_time_node.hpp"
#include "odonav/msg/Misalignment.h"

namespace odonav::calibration {

/// The calibrator's options (add_calibration_options), --lever-arm, --use-ins, --state-dir and
/// --checkpoint-every-s.
void add_calibration_node_options(Options& options);
/// Reads them. Throws ConfigError naming the option when a value or combination is invalid.
MisalignmentCalibratorParams calibration_node_params_from(const Options& options);

/// Misalignment message of one calibrator output: stamp = output t_s (s -> builtin Time, exact to
/// the ns below 2^22 s), frame "body", angles in rad, one-sigmas in rad (-1 when not finite).
odonav::msg::Misalignment misalignment_message(const MisalignmentOutput& output, const std::string& vehicle_id);

class CalibrationNode : public dds::EventTimeNode {
 public:
  /// Creates the core (params checked: ConfigError naming the parameter), the Misalignment writer
  /// and the GNSS / INS readers of runtime's participant.
  /// With a state directory: restores the checkpoint before any input is read (or moves an unusable
  /// one aside and starts from nothing) and publishes the restored misalignment at once, stamped with
  /// the checkpoint's epoch. After a restore the sensor readers are TRANSIENT_LOCAL
  /// (odonav_sensor_replay_reader): the producers hand over their history (30 s), the data of the
  /// downtime is processed from the checkpoint on and its misalignments published late (catch-up,
  /// counted and named in the health). ConfigError when the state directory cannot be created or the
  /// vehicle id cannot name a file.
  CalibrationNode(dds::ComponentRuntime& runtime, const MisalignmentCalibratorParams& params,
                  const CheckpointSettings& checkpoint = {});
  ~CalibrationNode() override;

 private:
  void process_until(double watermark_s) override;
  void finish() override;
  void close_inputs() override;
  std::vector<dds::detail::WriterBase*> output_writers() override;
  Status node_status(double now_s) override;
  void append_counters(dds::HealthCounters& counters) override;
  void on_tick(double now_s) override { misalignment_.heartbeat_if_due(now_s); }

  void publish(const std::vector<MisalignmentOutput>& outputs);
  /// After a restore, GNSS waits until the first INS sample of the handed-over history is known
  /// (epochs older than it cannot be processed: lost); then the held ones are fed.
  bool gnss_may_pass() const;
  /// After a restore: the live edge, from the INS stamps as they arrive (GNSS without INS).
  void note_live_sample(const builtin_interfaces::msg::Time& stamp);
  void flush_pending_gnss();
  dds::CommandAck on_command(const odonav::msg::Command& command);

  MisalignmentCalibratorParams params_;
  MisalignmentCalibrator core_;
  CalibrationLifecycle lifecycle_;
  std::vector<std::pair<double, GnssSample>> pending_gnss_;  // after a restore, event time (s) + sample
  std::optional<MisalignmentOutput> last_output_;
  dds::NodeInput& gnss_;
  dds::NodeInput* ins_ = nullptr;
  dds::EstimatePublisher<odonav::msg::Misalignment> misalignment_;
  // Last members: destroyed first, so no callback reaches a half-destroyed node.
  std::unique_ptr<dds::Reader<odonav::msg::GnssFix>> gnss_reader_;
  std::unique_ptr<dds::Reader<odonav::msg::InsAttitude>> ins_reader_;
};

}  // namespace odonav::calibration
