#pragma once
// odonav-gateway's DDS node: publishes one vehicle's odometer, INS attitude and GNSS fixes from a
// dataset (core/: the sources and the pacing clock), stamped with the sample (event) time, in time
// order, paced in real time, N times real time, or as fast as the readers acknowledge, through the
// gateway's one SensorPublisher (sensor_publisher.hpp: sample -> message, counters, Health).
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "odonav/gateway/candump_source.hpp"
#include "odonav/gateway/pacing.hpp"
#include "odonav/gateway/sensor_source.hpp"
#include "node/sensor_publisher.hpp"
#include "odonav/config.hpp"
#include "odonav/dataset.hpp"
#include "odonav/dds/component.hpp"

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
  /// A reliable reader lost before the data was complete (it left or was cut off while samples
  /// were still owed to it) ends the run with exit code 4 unless this is set: the producer could
  /// not deliver everything, and says to whom.
  bool tolerate_lost_readers = false;
  /// candump source: the odometer channels and their conversion into pulses (--can-*).
  CanOdometerConfig can;
  /// candump:<file> source: the dataset directory whose INS and GNSS are replayed with the CAN
  /// odometer ("" = odometer only).
  std::string candump_dataset;
};

/// Exit code of a run that ended with readers lost before everything reached them.
inline constexpr int kExitLostReaders = 4;

/// Declares --source, --seed, --duration-s, --on-bad-row, --speed, --wait-for-readers,
/// --wait-for-readers-timeout-s, --ack-interval-s, --ack-timeout-s, --tolerate-lost-readers, and
/// the CAN input's --can-odometer, --can-pulses-per-m, --can-gear-ratio, --can-sprocket-radius-m,
/// --can-etc1-pulses-per-rev, --candump-dataset, --ins-source.
void add_gateway_options(Options& options);
/// Reads them. Throws ConfigError naming the flag when a value is unusable.
GatewaySettings gateway_settings_from(const Options& options);

/// Publishes the dataset (see the file comment). Health at 1 Hz (wall clock): running while
/// publishing, "stopping" with "end of data at t=..." (or "interrupted at t=...") at the end.
class GatewayNode {
 public:
  /// source_health: counters of how the dataset was obtained (the CAN input's), shown in every
  /// Health after the replay's own.
  GatewayNode(dds::ComponentRuntime& runtime, const GatewaySettings& settings, Dataset dataset,
              SourceHealth source_health = {});

  /// Waits for the readers, publishes everything (or until SIGINT/SIGTERM), waits for the final
  /// acknowledgments, publishes Health "stopping". Returns the exit code: 0 on a completed or
  /// interrupted run, 1 when the expected readers never matched, kExitLostReaders (4) when a
  /// reliable reader was lost while publishing (unless tolerate_lost_readers).
  int run();

 private:
  bool wait_for_readers();
  void publish(const SensorEvent& e);
  /// The GNSS completeness declared with a sensor sample stamped sample_t_s (s): every GNSS of the
  /// file stamped at or before the result has been published.
  double gnss_declared_through_s(double sample_t_s) const;
  /// Publishes Health (force: at once). An unforced call is evaluated at most every
  /// 50 ms of wall time: the paced loop calls it after each of its ~100 sleeps
  /// per second, and each evaluation builds the counters and polls the peers' silences.
  void health(odonav::msg::HealthState state, const std::string& reason, bool force);
  enum class Outcome { kEndOfData, kInterrupted, kFailed };
  /// Publishes the events in order, paced by settings_.speed from wall_start_s (steady clock, s;
  /// flow control in "max" mode), until the end or a stop request. kFailed: a stamp a message
  /// cannot carry (logged, Health ERROR).
  Outcome publish_all(const std::vector<SensorEvent>& events, double wall_start_s,
                      std::chrono::milliseconds ack_timeout);
  /// Paced mode: sleeps until due_wall_s in short steps (SIGINT and Health stay responsive); false
  /// when a stop was requested.
  bool sleep_until(double due_wall_s);

  dds::ComponentRuntime& runtime_;
  GatewaySettings settings_;
  Dataset dataset_;
  std::size_t gnss_published_ = 0;  // GNSS of dataset_ published so far (in file order)
  double last_health_s_ = -1e300;   // steady clock (s) of the last health evaluation
  SourceHealth source_health_;      // of the loading (CAN counters), fixed
  SensorPublisher publisher_;
};

}  // namespace odonav::gateway
