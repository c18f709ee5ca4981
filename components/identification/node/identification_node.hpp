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
#include "odonav/identification/instance.hpp"
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

/// Who this identification is among hot-standby instances, and how it publishes.
struct InstanceSettings {
  /// ScaleFactor.source and the name of its state files (instance.hpp); "identification" by default,
  /// e.g. "identification/standby" for a standby.
  std::string instance = kDefaultIdentificationInstance;
  /// OWNERSHIP_STRENGTH of the scale-factor writer (0..1e6): readers follow the strongest live
  /// instance; give the primary the higher value (e.g. 20) and the standby a lower one (10).
  uint32_t ownership_strength = 10;
  /// Reference K [m/pulse] (> 0) a set_k command is checked against: [0.1, 10] x this.
  double nominal_k_m_per_pulse = 0.0125;
  /// The last ScaleFactor is republished (same stamp) when nothing was written for this long
  /// (wall clock, s, > 0): well inside the 300 ms deadline, even in a GNSS outage.
  double heartbeat_period_s = 0.1;
};
/// Reads --instance, --ownership-strength and --nominal-k. Throws ConfigError naming the option.
InstanceSettings instance_settings_from(const Options& options);

/// ScaleFactor message of one output: stamp = output t_s, frame "odometer", the main estimator's
/// K (m/pulse; 0 while it has no value: consumers take k > 0 as "valid"), sigma (m/pulse, -1 when
/// unknown), lambda, window fill, estimator name, converged, sample counts, frozen.
/// source = the publishing instance (InstanceSettings::instance).
odonav::msg::ScaleFactor scale_factor_message(const IdentificationOutput& output, const std::string& estimator,
                                              const std::string& vehicle_id,
                                              const std::string& source = kDefaultIdentificationInstance);

class IdentificationNode : public dds::EventTimeNode {
 public:
  /// Creates the core (ConfigError naming a bad parameter), the ScaleFactor writer and the readers.
  /// With a state directory: restores the checkpoint before any input is read (or moves a bad one
  /// aside and starts from nominal) and publishes the restored K at once, stamped with the
  /// checkpoint's time, so a late reader gets it before any new sample. ConfigError when the state
  /// directory cannot be created or the vehicle id cannot name a file.
  /// With a state directory the scale-factor writer is also TRANSIENT (Fast DDS SQLite persistence in
  /// `<state-dir>/<vehicle>-<instance>.db`, fixed GUID persistence_guid(vehicle, instance)): a reader
  /// joining after a restart gets the last K even before the restored one is published. Without
  /// one it is TRANSIENT_LOCAL (the profile's).
  IdentificationNode(dds::ComponentRuntime& runtime, const IdentificationParams& params,
                     const CheckpointSettings& checkpoint = {}, const InstanceSettings& instance = {});
  ~IdentificationNode() override;

 private:
  void process_until(double watermark_s) override;
  void finish() override;
  void close_inputs() override;
  std::vector<dds::detail::WriterBase*> output_writers() override;
  Status node_status(double now_s) override;
  void append_counters(dds::HealthCounters& counters) override;
  void on_tick(double now_s) override;

  void publish(const std::vector<IdentificationOutput>& outputs);
  /// Writes one ScaleFactor (counted, a refusal logged) and remembers it for the heartbeat.
  void write_scale_factor(const IdentificationOutput& output, double now_s);
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
  InstanceSettings instance_;
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
  /// The SQLite file of the TRANSIENT writer existed at start: the writer serves the last estimate
  /// of the previous run itself, so the (older or equal) restored K is not published again.
  bool persisted_history_ = false;
  /// Created after the checkpoint is restored (what the persistence database may serve depends on it).
  std::unique_ptr<dds::Writer<odonav::msg::ScaleFactor>> scale_factor_;
  std::optional<odonav::msg::ScaleFactor> last_scale_factor_;  ///< for the heartbeat
  double last_scale_factor_write_s_ = 0.0;                   ///< steady clock (s)
  uint64_t scale_factors_written_ = 0;
  uint64_t heartbeats_ = 0;
  uint64_t write_failures_ = 0;
  uint64_t k_commands_ = 0;
  // Last members: destroyed first, so no callback reaches a half-destroyed node.
  std::unique_ptr<dds::Reader<odonav::msg::Odometer>> odometer_reader_;
  std::unique_ptr<dds::Reader<odonav::msg::GnssFix>> gnss_reader_;
  std::unique_ptr<dds::Reader<odonav::msg::InsAttitude>> ins_reader_;
  std::unique_ptr<dds::Reader<odonav::msg::Misalignment>> misalignment_reader_;
};

}  // namespace odonav::nodes
