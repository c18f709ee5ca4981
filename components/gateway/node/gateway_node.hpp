#pragma once
// odonav-gateway's DDS node: publishes one vehicle's odometer, INS attitude and GNSS fixes from a
// dataset (core/: the sources and the pacing clock), stamped with the sample (event) time, in time
// order, paced in real time, N times real time, or as fast as the readers acknowledge.
#include <cstddef>
#include <cstdint>
#include <string>

#include "core/pacing.hpp"
#include "core/sensor_source.hpp"
#include "odonav/config.hpp"
#include "odonav/dataset.hpp"
#include "odonav/dds/component.hpp"
#include "odonav/msg/GnssFix.h"
#include "odonav/msg/InsAttitude.h"
#include "odonav/msg/Odometer.h"

namespace odonav::gateway {

/// What the gateway's own flags say.
struct GatewaySettings {
  SourceSpec source;
  SimulatorSettings simulator;
  BadRowPolicy on_bad_row = BadRowPolicy::kFail;
  Speed speed;
  /// Consumers to wait for before the first sample (matched readers of the GNSS writer, which
  /// every SINS/OD consumer reads); 0 = start at once.
  int wait_for_readers = 0;
  double wait_for_readers_timeout_s = 60.0;  ///< then give up: exit 1 naming the counts.
  double ack_timeout_s = 30.0;               ///< one acknowledgment wait in "max" mode, and at the end.
  /// "max" mode: data time between acknowledgment waits, s, (0, 1] (half the writers' 2 s history).
  double ack_interval_s = 0.5;
};

/// Declares --source, --seed, --duration-s, --on-bad-row, --speed, --wait-for-readers,
/// --wait-for-readers-timeout-s, --ack-interval-s, --ack-timeout-s.
void add_gateway_options(Options& options);
/// Reads them. Throws ConfigError naming the flag when a value is unusable.
GatewaySettings gateway_settings_from(const Options& options);

// Sample -> message (frames, units: idl/README.md). Stamps: to_time_msg(t_s); a t_s outside its
// range (non-finite, beyond 2038) throws std::invalid_argument naming the value.

/// Odometer: raw counter, direction (-1, 0, +1), frame "odometer".
odonav::msg::Odometer odometer_message(const OdometerSample& s, const std::string& vehicle_id);
/// INS attitude in radians, ENU velocity when the dataset has it (velocity_valid), valid, frame "body".
odonav::msg::InsAttitude ins_message(const InsSample& s, const std::string& vehicle_id);
/// GNSS fix: latitude/longitude in the degrees the dataset files hold (recorded_degrees), height,
/// ENU velocity, fix quality; accuracies -1 when unknown; valid = fix not 0 or 6 and every value
/// finite (a fix-0 row is published as an invalid fix, not dropped). Frame "wgs84".
odonav::msg::GnssFix gnss_message(const GnssSample& s, const std::string& vehicle_id);

/// Publishes the dataset (see the file comment). Health at 1 Hz (wall clock): running while
/// publishing, "stopping" with "end of data at t=..." (or "interrupted at t=...") at the end.
class GatewayNode {
 public:
  GatewayNode(dds::ComponentRuntime& runtime, const GatewaySettings& settings, Dataset dataset);

  /// Waits for the readers, publishes everything (or until SIGINT/SIGTERM), waits for the final
  /// acknowledgments, publishes Health "stopping". Returns the exit code: 0 on a completed or
  /// interrupted run, 1 when the expected readers never matched.
  int run();

 private:
  bool wait_for_readers();
  void publish(const SensorEvent& e);
  bool wait_for_acknowledgments(std::chrono::milliseconds timeout);
  void health(odonav::msg::HealthState state, const std::string& reason, bool force);

  dds::ComponentRuntime& runtime_;
  GatewaySettings settings_;
  Dataset dataset_;
  dds::Writer<odonav::msg::Odometer> odometer_;
  dds::Writer<odonav::msg::InsAttitude> ins_;
  dds::Writer<odonav::msg::GnssFix> gnss_;
  std::uint64_t published_[3] = {0, 0, 0};  // per SensorEvent::Stream
  std::uint64_t gnss_invalid_ = 0;
  std::uint64_t write_failures_ = 0;
  std::uint64_t ack_timeouts_ = 0;
  double last_t_s_ = 0.0;
};

}  // namespace odonav::gateway
