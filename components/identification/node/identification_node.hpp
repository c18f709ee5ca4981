#pragma once
// odonav-identification's DDS node: odometer, GNSS, INS attitude and misalignment in, one
// ScaleFactor per GNSS epoch out (README.md beside this folder). The core is IdentificationCore,
// fed exactly as odonav-offline feeds it (misalignments applied by consumer_rules.hpp), so both
// publish the same numbers for the same data. The restart policy (checkpoint, persistence,
// skipped samples, health) is IdentificationLifecycle's; this node only subscribes, converts,
// calls the two and publishes.
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "odonav/defaults.hpp"
#include "odonav/config.hpp"
#include "odonav/dds/event_time_node.hpp"
#include "odonav/identification/identification_core.hpp"
#include "odonav/identification/identification_lifecycle.hpp"
#include "odonav/identification/instance.hpp"
#include "odonav/msg/Misalignment.h"
#include "odonav/msg/ScaleFactor.h"

namespace odonav::identification {

/// The identification options (add_identification_options), --use-ins, --lever-arm, --state-dir and
/// --checkpoint-every-s.
void add_identification_node_options(Options& options);
/// Reads them: identification_params_for(options, {--use-ins, --lever-arm, --nominal-k, main
/// estimator only}), the function odonav-offline calls too. Throws ConfigError naming the option
/// when a value or combination is invalid.
IdentificationParams identification_node_params_from(const Options& options);

/// Where and how often the node checkpoints its estimator (identification_lifecycle.hpp).
using odonav::CheckpointSettings;
/// Reads --state-dir and --checkpoint-every-s and hashes the configuration.
CheckpointSettings checkpoint_settings_from(const Options& options);

/// Who this identification is among hot-standby instances, and how it publishes.
struct InstanceSettings {
  /// ScaleFactor.source and the name of its state files (instance.hpp); "identification" by default,
  /// e.g. "identification/standby" for a standby.
  std::string instance = kDefaultIdentificationInstance;
  /// This instance's priority (0..1e6), published as ScaleFactor.source_priority: consumers follow
  /// the highest-priority live instance (odonav/source_arbiter.hpp); give the primary the higher
  /// value (e.g. 20) and the standby a lower one (10). The flag keeps its historical name
  /// (--ownership-strength); the writer's OWNERSHIP_STRENGTH QoS is set to it too, which the SHARED
  /// topic ignores.
  uint32_t ownership_strength = 10;
  /// Reference K [m/pulse] (> 0) a set_k command is checked against: [0.1, 10] x this.
  double nominal_k_m_per_pulse = kDefaultNominalK_m_per_pulse;
  /// The last ScaleFactor is republished (same stamp) when nothing was written for this long
  /// (wall clock, s, > 0): well inside the writer's offered 300 ms deadline, even in a GNSS outage.
  double heartbeat_period_s = 0.1;
};
/// Reads --instance, --ownership-strength and --nominal-k. Throws ConfigError naming the option.
InstanceSettings instance_settings_from(const Options& options);

/// ScaleFactor message of one output: stamp = output t_s, frame "odometer", the main estimator's
/// K (m/pulse; 0 while it has no value: consumers take k > 0 as "valid"), sigma (m/pulse, -1 when
/// unknown), lambda, window fill, estimator name, converged, sample counts, frozen.
/// source = the publishing instance (InstanceSettings::instance), source_priority its priority.
odonav::msg::ScaleFactor scale_factor_message(const IdentificationOutput& output, const std::string& estimator,
                                              const std::string& vehicle_id,
                                              const std::string& source = kDefaultIdentificationInstance,
                                              uint32_t source_priority = InstanceSettings{}.ownership_strength);

class IdentificationNode : public dds::EventTimeNode {
 public:
  /// Creates the core (ConfigError naming a bad parameter), the ScaleFactor writer and the readers.
  /// With a state directory: restores the checkpoint before any input is read (or moves a bad one
  /// aside and starts from nominal) and publishes the restored K at once, stamped with the
  /// checkpoint's time, so a late reader gets it before any new sample. ConfigError when the state
  /// directory cannot be created or the vehicle id cannot name a file.
  /// The scale-factor writer is TRANSIENT_LOCAL (the profile's): a reader joining after a restart
  /// gets the restored K and what followed. After a restore the sensor readers are TRANSIENT_LOCAL
  /// (odonav_sensor_replay_reader): the producers hand over their history (30 s), and the data of
  /// the downtime is processed from the checkpoint on, its estimates published late (catch-up,
  /// counted and named in the health).
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
  /// Writes one ScaleFactor (EstimatePublisher: counted, a refusal logged, kept for the heartbeat).
  void write_scale_factor(const IdentificationOutput& output, double now_s);
  /// Logs when the turn slip starts (info) or stops (warn, with why) being applied.
  void log_turn_slip_change(const IdentificationOutput& output);
  void on_misalignment(const odonav::msg::Misalignment& m, double t_s);
  /// After a restore: the first odometer (and INS, when used) sample of the handed-over history seen.
  bool sensor_history_start_known() const;
  /// Feeds the GNSS samples held until then (those older than the sensor histories are lost).
  void flush_pending_gnss();
  dds::CommandAck on_command(const odonav::msg::Command& command);

  IdentificationParams params_;
  InstanceSettings instance_;
  IdentificationCore core_;
  IdentificationLifecycle lifecycle_;
  std::vector<std::pair<double, GnssSample>> pending_gnss_;  // after a restore, event time (s) + sample
  dds::NodeInput& odometer_;
  dds::NodeInput& gnss_;
  dds::NodeInput* ins_ = nullptr;
  dds::NodeInput& misalignment_;
  /// Created after the checkpoint is restored (what the persistence database may serve depends on it).
  std::unique_ptr<dds::EstimatePublisher<odonav::msg::ScaleFactor>> scale_factor_;
  uint64_t k_commands_ = 0;
  std::optional<bool> turn_slip_applies_;  ///< as last published (nothing before the first output)
  // Last members: destroyed first, so no callback reaches a half-destroyed node.
  std::unique_ptr<dds::Reader<odonav::msg::Odometer>> odometer_reader_;
  std::unique_ptr<dds::Reader<odonav::msg::GnssFix>> gnss_reader_;
  std::unique_ptr<dds::Reader<odonav::msg::InsAttitude>> ins_reader_;
  std::unique_ptr<dds::Reader<odonav::msg::Misalignment>> misalignment_reader_;
};

}  // namespace odonav::identification
