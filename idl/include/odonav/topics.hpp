#pragma once
// The odonav topic contract in one place: topic names, DDS type names and the QoS profile names
// (defined in deploy/profiles/qos.xml) of every topic. idl/README.md shows the same table with
// producers, consumers and rates. Plain constants, no DDS headers, so any code may include it.
#include <array>
#include <cstddef>

namespace odonav::topics {

/// One topic of the contract.
struct TopicSpec {
  const char* name;            ///< DDS topic name ("rt/" prefix: ROS 2 tools see "/odonav/...").
  const char* dds_type_name;   ///< Registered type name (fastddsgen -typeros2).
  const char* ros_type_name;   ///< ROS 2 interface name, for ros2msg schemas (idl/<pkg>/msg/*.msg).
  const char* writer_profile;  ///< data_writer profile in qos.xml for the producer.
  const char* reader_profile;  ///< data_reader profile in qos.xml for the vehicle's consumers.
};

/// The same topic (name, type, writer profile) read with another reader profile.
constexpr TopicSpec with_reader_profile(TopicSpec spec, const char* reader_profile) {
  spec.reader_profile = reader_profile;
  return spec;
}

// QoS profile names (deploy/profiles/qos.xml). See idl/README.md for what each one means. Every
// profile is SHARED ownership (the default), as ROS 2 readers and other vendors' default-QoS readers
// are: every topic is readable by them. Redundant estimate producers (hot standby) are told apart by
// ScaleFactor.source / source_priority, and consumers wanting one stream arbitrate them in event
// time (odonav/source_arbiter.hpp).
inline constexpr const char* kSensorWriterProfile = "odonav_sensor_writer";
inline constexpr const char* kSensorReaderProfile = "odonav_sensor_reader";
/// odonav_sensor_reader with TRANSIENT_LOCAL durability: the sensor writers (TRANSIENT_LOCAL, 30 s
/// of history) hand such a reader their history when it matches. A restarted identification or
/// calibration reads with it to process the data of its downtime from its checkpoint on.
inline constexpr const char* kSensorReplayReaderProfile = "odonav_sensor_replay_reader";
/// The gateway's sensor writers when replaying as fast as possible: odonav_sensor_writer with a
/// 5 ms heartbeat, so each acknowledgment wait of its flow control takes milliseconds.
inline constexpr const char* kGatewayFastAckSensorWriterProfile = "odonav_gateway_sensor_writer_fast_ack";
inline constexpr const char* kEstimateWriterProfile = "odonav_estimate_writer";
inline constexpr const char* kEstimateReaderProfile = "odonav_estimate_reader";
inline constexpr const char* kDeadReckoningWriterProfile = "odonav_dead_reckoning_writer";
inline constexpr const char* kDeadReckoningReaderProfile = "odonav_dead_reckoning_reader";
inline constexpr const char* kHealthWriterProfile = "odonav_health_writer";
inline constexpr const char* kHealthReaderProfile = "odonav_health_reader";
inline constexpr const char* kCommandWriterProfile = "odonav_command_writer";
inline constexpr const char* kCommandReaderProfile = "odonav_command_reader";
/// Best-effort, volatile reader for the ground station: watches any topic without slowing the
/// vehicle's writers down (a reliable reader on a weak link would make them resend).
inline constexpr const char* kGroundBestEffortReaderProfile = "odonav_ground_reader_best_effort";
/// The ground station's K and misalignment readers: odonav_estimate_reader sized for up to 1024
/// vehicles (one instance each; a reader keeps 10 by default).
inline constexpr const char* kGroundEstimateReaderProfile = "odonav_ground_estimate_reader";

/// Recorders (odonav-recorder, odonav-ground record): every estimate, KEEP_LAST 1000 per vehicle.
inline constexpr const char* kMisalignmentRecorderReaderProfile = "odonav_misalignment_recorder_reader";
inline constexpr const char* kScaleFactorRecorderReaderProfile = "odonav_scale_factor_recorder_reader";
/// odonav-recorder's dead-reckoning and navigation-position readers: odonav_dead_reckoning_reader
/// with TRANSIENT_LOCAL durability, so a restarted recorder gets the writers' 30 s of history.
inline constexpr const char* kDeadReckoningRecorderReaderProfile = "odonav_dead_reckoning_recorder_reader";
/// The participant profile of deploy/profiles/loopback.xml (tests, demo: all traffic on lo).
inline constexpr const char* kLoopbackParticipantProfile = "loopback_only";

inline constexpr TopicSpec kOdometer{"rt/odonav/odometer", "odonav::msg::dds_::Odometer_", "odonav/msg/Odometer",
                                     kSensorWriterProfile, kSensorReaderProfile};
inline constexpr TopicSpec kInsAttitude{"rt/odonav/ins/attitude", "odonav::msg::dds_::InsAttitude_",
                                        "odonav/msg/InsAttitude", kSensorWriterProfile, kSensorReaderProfile};
inline constexpr TopicSpec kGnssFix{"rt/odonav/gnss/fix", "odonav::msg::dds_::GnssFix_", "odonav/msg/GnssFix",
                                    kSensorWriterProfile, kSensorReaderProfile};
inline constexpr TopicSpec kMisalignment{"rt/odonav/misalignment", "odonav::msg::dds_::Misalignment_",
                                         "odonav/msg/Misalignment", kEstimateWriterProfile, kEstimateReaderProfile};
/// Every instance of odonav-identification (primary, hot standby) writes here; consumers that want
/// one stream put each vehicle's samples through an odonav::SourceArbiter (source, source_priority).
inline constexpr TopicSpec kScaleFactor{"rt/odonav/scale_factor", "odonav::msg::dds_::ScaleFactor_",
                                        "odonav/msg/ScaleFactor", kEstimateWriterProfile, kEstimateReaderProfile};
inline constexpr TopicSpec kDeadReckoning{"rt/odonav/dead_reckoning", "odonav::msg::dds_::DeadReckoning_",
                                          "odonav/msg/DeadReckoning", kDeadReckoningWriterProfile,
                                          kDeadReckoningReaderProfile};
/// The GNSS-anchored navigation position, one per DeadReckoning; the DR profiles (same rate and use).
inline constexpr TopicSpec kNavigationPosition{
    "rt/odonav/navigation_position", "odonav::msg::dds_::NavigationPosition_", "odonav/msg/NavigationPosition",
    kDeadReckoningWriterProfile, kDeadReckoningReaderProfile};
inline constexpr TopicSpec kHealth{"rt/odonav/health", "odonav::msg::dds_::Health_", "odonav/msg/Health",
                                   kHealthWriterProfile, kHealthReaderProfile};
inline constexpr TopicSpec kCommand{"rt/odonav/command", "odonav::msg::dds_::Command_", "odonav/msg/Command",
                                    kCommandWriterProfile, kCommandReaderProfile};

/// Every topic, in the order of idl/README.md (the navigation position last: TopicIds stay stable).
inline constexpr std::array<TopicSpec, 9> kAllTopics{kOdometer,     kInsAttitude, kGnssFix,
                                                     kMisalignment, kScaleFactor, kDeadReckoning,
                                                     kHealth,       kCommand,     kNavigationPosition};

/// Every topic of the contract as an enumerator, in the order of kAllTopics (checked below). Code
/// that handles topics by type (odonav-ground's recorder) defines the message type per TopicId, so a
/// topic added to kAllTopics must be added here, and then does not compile until it is handled.
enum class TopicId : std::size_t {
  kOdometer,
  kInsAttitude,
  kGnssFix,
  kMisalignment,
  kScaleFactor,
  kDeadReckoning,
  kHealth,
  kCommand,
  kNavigationPosition,
};

/// The TopicId of each entry of kAllTopics, same order and size.
inline constexpr std::array<TopicId, kAllTopics.size()> kAllTopicIds{
    TopicId::kOdometer,     TopicId::kInsAttitude, TopicId::kGnssFix,
    TopicId::kMisalignment, TopicId::kScaleFactor, TopicId::kDeadReckoning,
    TopicId::kHealth,       TopicId::kCommand,     TopicId::kNavigationPosition};

/// The contract entry of a topic.
constexpr const TopicSpec& spec_of(TopicId id) { return kAllTopics[static_cast<std::size_t>(id)]; }

namespace detail {
constexpr bool same_text(const char* a, const char* b) {
  while (*a != '\0' && *a == *b) ++a, ++b;
  return *a == *b;
}
// kAllTopicIds[i] is the i-th enumerator and names the topic kAllTopics[i] holds: a topic added to
// kAllTopics without its TopicId (kAllTopicIds then ends in a value-initialised kOdometer) fails here.
constexpr bool ids_match_topics() {
  constexpr const TopicSpec* by_id[] = {&kOdometer,      &kInsAttitude, &kGnssFix, &kMisalignment,      &kScaleFactor,
                                        &kDeadReckoning, &kHealth,      &kCommand, &kNavigationPosition};
  if (sizeof by_id / sizeof by_id[0] != kAllTopics.size()) return false;
  for (std::size_t i = 0; i < kAllTopics.size(); ++i) {
    if (static_cast<std::size_t>(kAllTopicIds[i]) != i) return false;
    if (!same_text(kAllTopics[i].name, by_id[i]->name)) return false;
  }
  return true;
}
}  // namespace detail
static_assert(detail::ids_match_topics(), "kAllTopicIds must list one TopicId per kAllTopics entry, in order");

}  // namespace odonav::topics
