#pragma once
// odonav-identification's DDS node: odometer, GNSS, INS attitude and misalignment in, one
// ScaleFactor per GNSS epoch out (README.md beside this folder). The core is IdentificationCore,
// fed exactly as odonav-offline feeds it (misalignments applied by consumer_rules.hpp), so both
// publish the same numbers for the same data.
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "odonav/config.hpp"
#include "odonav/dds/event_time_node.hpp"
#include "odonav/identification/identification_core.hpp"
#include "odonav/msg/Misalignment.h"
#include "odonav/msg/ScaleFactor.h"

namespace odonav::nodes {

/// The identification options (add_identification_options), --use-ins, --lever-arm, --state-dir and
/// --checkpoint-every-s.
void add_identification_node_options(Options& options);
/// Reads them. Throws ConfigError naming the option when a value or combination is invalid.
IdentificationParams identification_node_params_from(const Options& options);

/// Where and how often the node checkpoints its estimator (checkpoint.hpp).
struct CheckpointSettings {
  /// Folder of `identification-<vehicle>.ckpt`; empty = no checkpoint (nothing read or written).
  std::string state_dir;
  /// A checkpoint is written once the event time of the processed epochs has advanced by this much
  /// (s, > 0) since the last one, and at shutdown. Event time, not wall time: a replay writes the
  /// same checkpoints whatever its speed.
  double every_s = 5.0;
  /// config_hash_of(Options::values_as_text()): a checkpoint of another configuration is refused.
  std::string config_hash;
};
/// Reads --state-dir and --checkpoint-every-s and hashes the configuration.
CheckpointSettings checkpoint_settings_from(const Options& options);

/// ScaleFactor message of one output: stamp = output t_s, frame "odometer", the main estimator's
/// K (m/pulse; 0 while it has no value: consumers take k > 0 as "valid"), sigma (m/pulse, -1 when
/// unknown), lambda, window fill, estimator name, converged, sample counts, frozen.
odonav::msg::ScaleFactor scale_factor_message(const IdentificationOutput& output, const std::string& estimator,
                                              const std::string& vehicle_id);

class IdentificationNode : public dds::EventTimeNode {
 public:
  /// Creates the core (ConfigError naming a bad parameter), the ScaleFactor writer and the readers.
  /// With a state directory: restores the checkpoint before any input is read (or moves a bad one
  /// aside and starts from nominal) and publishes the restored K at once, stamped with the
  /// checkpoint's time, so a late reader gets it before any new sample. ConfigError when the state
  /// directory cannot be created or the vehicle id cannot name a file.
  IdentificationNode(dds::ComponentRuntime& runtime, const IdentificationParams& params,
                     const CheckpointSettings& checkpoint = {});
  ~IdentificationNode() override;

 private:
  void process_until(double watermark_s) override;
  void finish() override;
  void close_inputs() override;
  std::vector<dds::detail::WriterBase*> output_writers() override;
  Status node_status(double now_s) override;
  void append_counters(dds::HealthCounters& counters) override;
  void on_tick(double now_s) override { scale_factor_.heartbeat_if_due(now_s); }

  void publish(const std::vector<IdentificationOutput>& outputs);
  void on_misalignment(const odonav::msg::Misalignment& m, double t_s);
  dds::CommandAck on_command(const odonav::msg::Command& command);
  void restore_checkpoint();
  /// Writes the checkpoint (estimator state after the epoch at t_s). Errors are logged and counted:
  /// a full disk must not stop the identification.
  void write_checkpoint(double t_s);
  /// True (and counted) when a sample stamped t_s predates the restored checkpoint by more than
  /// margin_s: it was processed before the restart and must not reach the core again.
  bool before_checkpoint(double t_s, double margin_s);

  IdentificationParams params_;
  IdentificationCore core_;
  std::optional<IdentificationOutput> last_output_;
  uint64_t misalignments_applied_ = 0;
  // Checkpoint / restore (checkpoint.hpp).
  CheckpointSettings checkpoint_;
  std::string checkpoint_file_;
  std::optional<double> restored_t_s_;      ///< last epoch of the restored checkpoint (event time, s)
  uint64_t restored_accepted_ = 0;          ///< counters carried over from the checkpoint
  uint64_t restored_rejected_ = 0;
  std::string restore_note_;                ///< health reason part about the restore
  bool restore_warn_ = false;               ///< the checkpoint was bad (health WARN while the note shows)
  double restore_note_until_s_ = 0.0;       ///< steady time until which the note is in the health reason
  std::optional<double> last_checkpoint_t_s_;
  std::optional<double> last_processed_t_s_;
  uint64_t checkpoints_written_ = 0;
  uint64_t checkpoint_errors_ = 0;
  uint64_t skipped_before_checkpoint_ = 0;
  bool checkpoint_moved_aside_ = false;
  dds::NodeInput& odometer_;
  dds::NodeInput& gnss_;
  dds::NodeInput* ins_ = nullptr;
  dds::NodeInput& misalignment_;
  dds::EstimatePublisher<odonav::msg::ScaleFactor> scale_factor_;
  // Last members: destroyed first, so no callback reaches a half-destroyed node.
  std::unique_ptr<dds::Reader<odonav::msg::Odometer>> odometer_reader_;
  std::unique_ptr<dds::Reader<odonav::msg::GnssFix>> gnss_reader_;
  std::unique_ptr<dds::Reader<odonav::msg::InsAttitude>> ins_reader_;
  std::unique_ptr<dds::Reader<odonav::msg::Misalignment>> misalignment_reader_;
};

}  // namespace odonav::nodes
