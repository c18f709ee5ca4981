#pragma once
// The odonav topic contract in one place: topic names, DDS type names and the QoS profile names
// (defined in deploy/profiles/qos.xml) of every topic. idl/README.md shows the same table with
// producers, consumers and rates. Plain constants, no DDS headers, so any code may include it.
#include <array>

namespace odonav::topics {

/// One topic of the contract.
struct TopicSpec {
  const char* name;            ///< DDS topic name ("rt/" prefix: ROS 2 tools see "/odonav/...").
  const char* dds_type_name;   ///< Registered type name (fastddsgen -typeros2).
  const char* ros_type_name;   ///< ROS 2 interface name, for ros2msg schemas (idl/<pkg>/msg/*.msg).
  const char* writer_profile;  ///< data_writer profile in qos.xml for the producer.
  const char* reader_profile;  ///< data_reader profile in qos.xml for the vehicle's consumers.
};

// QoS profile names (deploy/profiles/qos.xml). See idl/README.md for what each one means.
inline constexpr const char* kSensorWriterProfile = "odonav_sensor_writer";
inline constexpr const char* kSensorReaderProfile = "odonav_sensor_reader";
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

/// EXCLUSIVE-ownership variants for the estimate topics (misalignment, scale factor), whose writers
/// are EXCLUSIVE (hot standby of the identification): a reader must have the same ownership kind.
/// Dead reckoning's scale-factor reader: a 300 ms deadline, so it follows the standby that fast.
inline constexpr const char* kScaleFactorReaderProfile = "odonav_scale_factor_reader";
/// The ground station's best-effort reader of the estimate topics.
inline constexpr const char* kEstimateGroundBestEffortReaderProfile = "odonav_estimate_ground_reader_best_effort";
/// Recorders (odonav-recorder, odonav-ground record): every estimate, KEEP_LAST 1000 per vehicle.
inline constexpr const char* kMisalignmentRecorderReaderProfile = "odonav_misalignment_recorder_reader";
inline constexpr const char* kScaleFactorRecorderReaderProfile = "odonav_scale_factor_recorder_reader";
/// The participant profile of deploy/profiles/loopback.xml (tests, demo: all traffic on lo).
inline constexpr const char* kLoopbackParticipantProfile = "loopback_only";

inline constexpr TopicSpec kOdometer{"rt/odonav/odometer", "odonav::msg::dds_::Odometer_",
                                     "odonav/msg/Odometer", kSensorWriterProfile, kSensorReaderProfile};
inline constexpr TopicSpec kInsAttitude{"rt/odonav/ins/attitude", "odonav::msg::dds_::InsAttitude_",
                                        "odonav/msg/InsAttitude", kSensorWriterProfile,
                                        kSensorReaderProfile};
inline constexpr TopicSpec kGnssFix{"rt/odonav/gnss/fix", "odonav::msg::dds_::GnssFix_",
                                    "odonav/msg/GnssFix", kSensorWriterProfile, kSensorReaderProfile};
inline constexpr TopicSpec kMisalignment{"rt/odonav/misalignment", "odonav::msg::dds_::Misalignment_",
                                         "odonav/msg/Misalignment", kEstimateWriterProfile,
                                         kEstimateReaderProfile};
inline constexpr TopicSpec kScaleFactor{"rt/odonav/scale_factor", "odonav::msg::dds_::ScaleFactor_",
                                        "odonav/msg/ScaleFactor", kEstimateWriterProfile,
                                        kEstimateReaderProfile};
inline constexpr TopicSpec kDeadReckoning{"rt/odonav/dead_reckoning",
                                          "odonav::msg::dds_::DeadReckoning_", "odonav/msg/DeadReckoning",
                                          kDeadReckoningWriterProfile, kDeadReckoningReaderProfile};
inline constexpr TopicSpec kHealth{"rt/odonav/health", "odonav::msg::dds_::Health_", "odonav/msg/Health",
                                   kHealthWriterProfile, kHealthReaderProfile};
inline constexpr TopicSpec kCommand{"rt/odonav/command", "odonav::msg::dds_::Command_",
                                    "odonav/msg/Command", kCommandWriterProfile, kCommandReaderProfile};

/// Every topic, in the order of idl/README.md.
inline constexpr std::array<TopicSpec, 8> kAllTopics{kOdometer,     kInsAttitude,   kGnssFix,
                                                     kMisalignment, kScaleFactor,   kDeadReckoning,
                                                     kHealth,       kCommand};

}  // namespace odonav::topics
