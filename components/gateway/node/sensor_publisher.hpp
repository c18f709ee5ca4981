#pragma once
// odonav-gateway's sensor publisher: the one place where samples become messages on the three
// sensor topics, for every source (the replay/simulator loop, gateway_node.hpp; the live line and
// gpsd inputs, live_gateway.hpp). It counts what it wrote and publishes the gateway's Health with
// the counter list of core/sensor_health.hpp.
#include <array>
#include <chrono>
#include <cstddef>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "odonav/gateway/live_input.hpp"
#include "odonav/gateway/sensor_health.hpp"
#include "odonav/dataset.hpp"
#include "odonav/dds/component.hpp"
#include "odonav/msg/GnssFix.h"
#include "odonav/msg/InsAttitude.h"
#include "odonav/msg/Odometer.h"

namespace odonav::gateway {

// Sample -> message (frames, units: idl/README.md). Stamps: to_time_msg(t_s); a t_s outside its
// range (non-finite, beyond 2038) throws std::invalid_argument naming the value.

/// Odometer: raw counter, direction (-1, 0, +1), frame "odometer".
/// GNSS completeness (idl Odometer): every GNSS fix stamped <= gnss_complete_through_s has been
/// published, the last one stamped gnss_last_stamp_s (nullopt: none).
odonav::msg::Odometer odometer_message(const OdometerSample& s, const std::string& vehicle_id,
                                       double gnss_complete_through_s, std::optional<double> gnss_last_stamp_s);
/// INS attitude in radians, ENU velocity when the dataset has it (velocity_valid), valid, frame "body";
/// the GNSS completeness as for the odometer (the calibration reads INS and GNSS only).
odonav::msg::InsAttitude ins_message(const InsSample& s, const std::string& vehicle_id, double gnss_complete_through_s,
                                     std::optional<double> gnss_last_stamp_s);
/// GNSS fix: latitude/longitude in the degrees the dataset files hold (recorded_degrees), height,
/// ENU velocity, fix quality; accuracies -1 when unknown; valid = fix not 0, 6, 7 or 8 and every value
/// finite (a fix-0 row is published as an invalid fix, not dropped). Frame "wgs84".
odonav::msg::GnssFix gnss_message(const GnssSample& s, const std::string& vehicle_id);

/// Writers of rt/odonav/odometer, rt/odonav/ins/attitude and rt/odonav/gnss/fix for the
/// runtime's vehicle, with one data_writer profile (qos.xml). Every sample is written at once,
/// stamped with its own t. Thread-safe: with gpsd beside a line source, GNSS arrives on its own
/// thread. A refused write is counted (the first 10 logged), never fatal.
class SensorPublisher : public SampleSink {
 public:
  SensorPublisher(dds::ComponentRuntime& runtime, const std::string& writer_profile);

  /// Publishes with the GNSS completeness: every GNSS stamped <= the last one published (a live
  /// source knows no more).
  void odometer(const OdometerSample& s) override;
  /// Publishes declaring every GNSS stamped <= gnss_complete_through_s published (a replay, which
  /// knows the file order: the next GNSS of the file is stamped later).
  void odometer(const OdometerSample& s, double gnss_complete_through_s);
  void ins(const InsSample& s) override;
  /// INS with the completeness declared as for odometer(s, gnss_complete_through_s).
  void ins(const InsSample& s, double gnss_complete_through_s);
  void gnss(const GnssSample& s) override;

  /// Waits (each writer bounded by timeout) until every matched reader acknowledged everything
  /// written; counts every writer that timed out (ack_timeouts). True when all acknowledged.
  bool wait_for_acknowledgments(std::chrono::milliseconds timeout);

  PublishedCounts counts() const;
  std::uint64_t ack_timeouts() const;
  /// Matched readers of the odometer, INS and GNSS writers.
  std::array<std::size_t, 3> matched_readers() const;
  /// The reliable readers that went away since since_s (steady clock), before the data was
  /// complete: "odonav-identification (<guid>) on odometer, ins/attitude, gnss/fix", one per
  /// participant, in the order they were lost.
  std::vector<std::string> readers_lost_since(double since_s) const;
  /// The GNSS writer (every SINS/OD consumer reads it: what the replay waits for).
  const dds::Writer<odonav::msg::GnssFix>& gnss_writer() const { return gnss_; }

  /// Publishes the gateway's Health (gateway_health: the counts, then the source's counters) at
  /// most once a second unless forced: level WARN on a write failure or when the source says so.
  void publish_health(odonav::msg::HealthState state, const std::string& reason, const SourceHealth& source,
                      bool force);

 private:
  const std::string& vehicle() const { return runtime_.settings().vehicle_id; }
  void count(bool written, std::size_t stream, double t_s);  // with mutex_ held

  dds::ComponentRuntime& runtime_;
  dds::Writer<odonav::msg::Odometer> odometer_;
  dds::Writer<odonav::msg::InsAttitude> ins_;
  dds::Writer<odonav::msg::GnssFix> gnss_;
  mutable std::mutex mutex_;
  std::optional<double> last_gnss_t_s_;  // stamp of the last GNSS published
  PublishedCounts counts_;
  std::uint64_t ack_timeouts_ = 0;
};

}  // namespace odonav::gateway
