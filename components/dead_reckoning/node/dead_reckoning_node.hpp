#pragma once
// odonav-dead-reckoning's DDS node: odometer, INS attitude, GNSS, misalignment and scale factor in,
// one DeadReckoning per odometer sample out (README.md beside this folder). The core is
// DeadReckoner, fed exactly as odonav-offline feeds it (estimates applied by consumer_rules.hpp), so
// both publish the same numbers for the same data.
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "odonav/config.hpp"
#include "odonav/dds/event_time_node.hpp"
#include "odonav/dead_reckoning/dead_reckoner.hpp"
#include "odonav/dead_reckoning/dead_reckoning_component.hpp"
#include "odonav/dead_reckoning/dead_reckoning_lifecycle.hpp"
#include "odonav/dead_reckoning/scale_factor_selection.hpp"
#include "odonav/msg/DeadReckoning.h"
#include "odonav/msg/Misalignment.h"
#include "odonav/msg/NavigationPosition.h"
#include "odonav/msg/ScaleFactor.h"
#include "odonav/source_arbiter.hpp"
#include "odonav/stream_buffers.hpp"
#include "odonav/topics.hpp"

namespace odonav::dead_reckoning {

/// --nominal-k, --dr-mode (add_dead_reckoning_options), --lever-arm, --use-ins, --state-dir and
/// --checkpoint-every-s.
void add_dead_reckoning_node_options(Options& options);
/// Reads them through dead_reckoner_params() (dead_reckoning_options.hpp), as odonav-offline does;
/// --nominal-k 0 means kDefaultNominalK_m_per_pulse (0.0125 m/pulse). Throws ConfigError naming the
/// option when a value is invalid.
DeadReckonerParams dead_reckoning_node_params_from(const Options& options);
/// The anchored position's parameters from the same facts, through anchored_position_params()
/// (dead_reckoning_options.hpp), as odonav-offline does.
AnchoredPositionParams anchored_position_node_params_from(const Options& options);

/// DeadReckoning message of one output: stamp = output t_s, frame "wgs84", degrees for latitude
/// and longitude, metres, radians; origin = the DR origin; misalignment = the one applied at t_s;
/// horizontal_error_m and error_percent_distance -1 without a GNSS reference.
odonav::msg::DeadReckoning dead_reckoning_message(const DeadReckoningOutput& output, const Geodetic& origin,
                                                  const Misalignment& misalignment, const std::string& vehicle_id);

/// NavigationPosition message of one anchored position: stamp = its t_s, frame "wgs84", degrees for
/// latitude and longitude; covariance diagonal (type 2) or -1 with type 0 while not started; last fix
/// stamp and distance since it -1 before the first fix.
odonav::msg::NavigationPosition navigation_position_message(const AnchoredPosition& position,
                                                            const std::string& vehicle_id);

class DeadReckoningNode : public dds::EventTimeNode {
 public:
  /// Creates the core (ConfigError naming a bad parameter), the DeadReckoning writer and the readers.
  /// With a state directory: restores the checkpoint before any input is read (or moves an unusable
  /// one aside and starts at the next fix). After a restore the sensor readers are TRANSIENT_LOCAL
  /// (odonav_sensor_replay_reader): the producers hand over their history (30 s), the samples the
  /// checkpoint holds are skipped, the downtime is processed and its outputs published late
  /// (catch-up, counted and named in the health). ConfigError when the state directory cannot be
  /// created or the vehicle id cannot name a file.
  DeadReckoningNode(dds::ComponentRuntime& runtime, const DeadReckonerParams& params,
                    const AnchoredPositionParams& anchored = {}, const CheckpointSettings& checkpoint = {});
  ~DeadReckoningNode() override;

 private:
  void process_until(double watermark_s) override;
  void finish() override;
  void close_inputs() override;
  std::vector<dds::detail::WriterBase*> output_writers() override;
  Status node_status(double now_s) override;
  void append_counters(dds::HealthCounters& counters) override;

  void publish(std::vector<DeadReckoningOutput> outputs);
  void note_live_sample(const builtin_interfaces::msg::Time& stamp);
  dds::CommandAck on_command(const odonav::msg::Command& command);

  DeadReckonerParams params_;
  /// Every rule of dead reckoning (the DR, the anchored position, the estimates applied, the K in
  /// force), as odonav-offline runs it.
  DeadReckoningComponent component_;
  DeadReckoningLifecycle lifecycle_;
  CountChangeTime pulse_jumps_;  ///< when the pulse-jump total last changed (health WARN window)
  CountChangeTime held_k_outputs_, held_misalignment_outputs_;  ///< when the last held output was made
  dds::BurstThrottle throttle_;
  std::optional<DeadReckoningOutput> last_output_;
  dds::NodeInput& odometer_;
  dds::NodeInput& gnss_;
  dds::NodeInput* ins_ = nullptr;
  dds::NodeInput& misalignment_;
  dds::NodeInput& scale_factor_;
  dds::Writer<odonav::msg::DeadReckoning> writer_;
  dds::Writer<odonav::msg::NavigationPosition> navigation_writer_;
  /// One K stream out of the identification instances (hot standby): the highest-priority live one,
  /// each stamp once; on a switch the new source's estimates from the stamp after the last one on.
  SourceArbiter<odonav::msg::ScaleFactor> k_arbiter_;
  // Last members: destroyed first, so no callback reaches a half-destroyed node.
  std::unique_ptr<dds::Reader<odonav::msg::Odometer>> odometer_reader_;
  std::unique_ptr<dds::Reader<odonav::msg::GnssFix>> gnss_reader_;
  std::unique_ptr<dds::Reader<odonav::msg::InsAttitude>> ins_reader_;
  std::unique_ptr<dds::Reader<odonav::msg::Misalignment>> misalignment_reader_;
  std::unique_ptr<dds::Reader<odonav::msg::ScaleFactor>> scale_factor_reader_;
};

}  // namespace odonav::dead_reckoning
