#pragma once
// odonav-identification's DDS node: odometer, GNSS, INS attitude and misalignment in, one
// ScaleFactor per GNSS epoch out (README.md beside this folder). The core is IdentificationCore,
// fed exactly as odonav-offline feeds it (misalignments applied by consumer_rules.hpp), so both
// publish the same numbers for the same data.
#include <memory>
#include <string>
#include <vector>

#include "odonav/config.hpp"
#include "odonav/dds/event_time_node.hpp"
#include "odonav/identification/identification_core.hpp"
#include "odonav/msg/Misalignment.h"
#include "odonav/msg/ScaleFactor.h"

namespace odonav::nodes {

/// The identification options (add_identification_options) and --use-ins.
void add_identification_node_options(Options& options);
/// Reads them. Throws ConfigError naming the option when a value or combination is invalid.
IdentificationParams identification_node_params_from(const Options& options);

/// ScaleFactor message of one output: stamp = output t_s, frame "odometer", the main estimator's
/// K (m/pulse; 0 while it has no value: consumers take k > 0 as "valid"), sigma (m/pulse, -1 when
/// unknown), lambda, window fill, estimator name, converged, sample counts, frozen.
odonav::msg::ScaleFactor scale_factor_message(const IdentificationOutput& output, const std::string& estimator,
                                              const std::string& vehicle_id);

class IdentificationNode : public dds::EventTimeNode {
 public:
  /// Creates the core (ConfigError naming a bad parameter), the ScaleFactor writer and the readers.
  IdentificationNode(dds::ComponentRuntime& runtime, const IdentificationParams& params);
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

  IdentificationParams params_;
  IdentificationCore core_;
  std::optional<IdentificationOutput> last_output_;
  uint64_t misalignments_applied_ = 0;
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
