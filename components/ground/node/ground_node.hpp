#pragma once
// odonav-ground's DDS side: the fleet monitor's subscriptions, the MCAP recorder's subscriptions,
// and the command sender. The logic without DDS is in core/ (fleet_state, mcap_writer,
// ros2msg_schema, recording).
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <variant>
#include <vector>

#include "odonav/ground/fleet_state.hpp"
#include "odonav/ground/mcap_writer.hpp"
#include "odonav/dds/endpoints.hpp"
#include "odonav/dds/participant.hpp"
#include "odonav/msg/Command.h"
#include "odonav/msg/DeadReckoning.h"
#include "odonav/msg/GnssFix.h"
#include "odonav/msg/Health.h"
#include "odonav/msg/InsAttitude.h"
#include "odonav/msg/Misalignment.h"
#include "odonav/msg/NavigationPosition.h"
#include "odonav/msg/Odometer.h"
#include "odonav/msg/ScaleFactor.h"
#include "odonav/topics.hpp"

namespace odonav::ground {

/// One received sample of any topic of the contract (valid during the callback only).
using AnySample =
    std::variant<const odonav::msg::Odometer*, const odonav::msg::InsAttitude*, const odonav::msg::GnssFix*,
                 const odonav::msg::Misalignment*, const odonav::msg::ScaleFactor*, const odonav::msg::DeadReckoning*,
                 const odonav::msg::Health*, const odonav::msg::Command*, const odonav::msg::NavigationPosition*>;
/// Sees every sample the monitor's readers receive (from the listener threads, after the FleetState).
using SampleTap = std::function<void(topics::TopicId topic, AnySample sample)>;

/// The plain views of the messages (fleet_state.hpp); a bad stamp becomes NaN.
HealthView view_of(const odonav::msg::Health& h);
ScaleFactorView view_of(const odonav::msg::ScaleFactor& s);
MisalignmentView view_of(const odonav::msg::Misalignment& m);
DeadReckoningView view_of(const odonav::msg::DeadReckoning& d);
NavigationPositionView view_of(const odonav::msg::NavigationPosition& n);
GnssView view_of(const odonav::msg::GnssFix& g);
/// A header's stamp in seconds; NaN for a stamp the DDS layer refuses.
double stamp_of(const std_msgs::msg::Header& h);

/// Subscribes to every vehicle topic of the contract and feeds a FleetState (from listener threads).
/// QoS: Health with odonav_health_reader (transient local: every component's latest Health at once;
/// deadline 3 s), Misalignment and ScaleFactor with odonav_estimate_reader (latest estimate at once;
/// deadline 1 s), the 10-100 Hz streams (odometer, INS, GNSS, dead reckoning) with
/// odonav_ground_reader_best_effort (never makes a vehicle's writer resend). Deadline misses mark the
/// instance silent in the FleetState (edge-detected by the DDS layer). With a tap (odonav-ground
/// serve), every sample is also handed to it, and Command is read too (best effort, like the streams).
/// These are the ground station's only readers of the live topics: their QoS is chosen here.
class FleetMonitor {
 public:
  /// clock: the steady clock in seconds given to the FleetState. Throws std::runtime_error (from the
  /// DDS layer) when a reader cannot be created.
  FleetMonitor(const dds::Participant& participant, FleetState& state, std::function<double()> clock,
               SampleTap tap = {});
  ~FleetMonitor();
  FleetMonitor(const FleetMonitor&) = delete;
  FleetMonitor& operator=(const FleetMonitor&) = delete;

 private:
  std::vector<std::unique_ptr<dds::detail::ReaderBase>> readers_;
};

/// Records topics into an MCAP file: one ros2msg schema per type (from the embedded .msg twins),
/// one channel per topic ("/odonav/...", message encoding "cdr", QoS metadata), and each received
/// sample serialized again with its generated PubSubType (CDR encapsulation header included), which
/// gives the bytes Fast DDS carries. log_time and publish_time are the UNIX receive time (ns).
class TopicRecorder {
 public:
  /// Each topic is read with recording_reader_profile(topic, best_effort): reliable (and deep for
  /// the estimates: a complete recording on a good link), or best effort for weak links. Throws
  /// std::runtime_error when a schema or a reader cannot be made.
  TopicRecorder(const dds::Participant& participant, McapWriter& writer,
                const std::vector<topics::TopicSpec>& topic_list, bool best_effort = false);
  /// Closes the readers: no callback writes to the MCAP writer afterwards.
  ~TopicRecorder();
  TopicRecorder(const TopicRecorder&) = delete;
  TopicRecorder& operator=(const TopicRecorder&) = delete;

  /// Readers matched to at least one writer, out of topic_count().
  std::size_t matched_topics() const;
  std::size_t topic_count() const { return readers_.size(); }
  /// Samples that could not be serialized or written (logged once each).
  std::uint64_t failures() const { return failures_; }
  /// Closes the readers now (idempotent).
  void stop();
  /// Writes one DiagnosticArray per vehicle heard on Health (/odonav/<vehicle>/diagnostics; call
  /// periodically). NavSatFix channels (/odonav/<vehicle>/navsat/...) are written as DeadReckoning
  /// and GnssFix samples arrive, when those topics are recorded.
  void write_diagnostics();
  /// Messages written on the standard channels so far.
  std::uint64_t standard_messages() const;

 private:
  class Standard;
  std::unique_ptr<Standard> standard_;  // before readers_: stop() closes the readers first
  std::vector<std::unique_ptr<dds::detail::ReaderBase>> readers_;
  std::atomic<std::uint64_t> failures_{0};
};

/// What `odonav-ground command` asks.
struct CommandRequest {
  std::string vehicle_id;
  std::string component;  ///< target_component, e.g. "odonav-identification"
  odonav::msg::CommandKind kind = odonav::msg::COMMAND_RESET_ESTIMATION;
  double value = 0.0;      ///< K [m/pulse] for COMMAND_SET_K, else 0
  double timeout_s = 5.0;  ///< whole exchange: discovery, delivery and acknowledgement (s, > 0)
};

enum class CommandOutcome { kAccepted, kRejected, kTimeout };

struct CommandReply {
  CommandOutcome outcome = CommandOutcome::kTimeout;
  std::uint32_t command_id = 0;
  std::string detail;  ///< the component's last_command_detail, or why it timed out
};

/// Parses the CLI names "reset", "set-k", "freeze", "unfreeze", "release-k" (Command.idl). Throws
/// std::invalid_argument listing them; the former "reset-calibration" is refused naming "reset" and
/// "release-k".
odonav::msg::CommandKind parse_command_kind(const std::string& name);
/// The CLI name of a kind ("command<N>" for a value outside the enum).
std::string command_kind_name(odonav::msg::CommandKind kind);

/// Sends one Command and waits for its acknowledgement in the target's Health (last_command_id equal
/// to the command's id): first until the target's Health is seen and a command reader is matched,
/// then writes, then until the acknowledgement, all within request.timeout_s. The command id is
/// random (never 0), so an older acknowledgement cannot be taken for this one.
CommandReply send_command(const dds::Participant& participant, const CommandRequest& request);

}  // namespace odonav::ground
