#pragma once
// Recording choices without DDS: which topics (--topics), and the channel metadata describing the
// QoS the vehicle's writers offer, in the form rosbag2 writes ("offered_qos_profiles" YAML), so
// ros2 bag and Foxglove show it.
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "odonav/topics.hpp"

namespace odonav::ground {

/// Picks topics of the contract from a comma-separated list. Each item may be the DDS name
/// ("rt/odonav/gnss/fix"), the ROS name ("/odonav/gnss/fix") or the short name ("gnss/fix",
/// "odometer"). Empty list or "all": every topic of topics::kAllTopics, in its order. Duplicates
/// are kept once. Throws std::invalid_argument naming an unknown item and listing the valid ones.
std::vector<topics::TopicSpec> select_topics(const std::string& comma_separated);

/// The recorders' reader profiles are in topics.hpp: kMisalignmentRecorderReaderProfile and
/// kScaleFactorRecorderReaderProfile (deep: KEEP_LAST 1000 per vehicle, so a replay at maximum speed
/// loses no sample); on weak links topics::kGroundBestEffortReaderProfile, as for every topic.
using topics::kMisalignmentRecorderReaderProfile;
using topics::kScaleFactorRecorderReaderProfile;

/// The data_reader profile a recording reads a topic with. Reliable (default): the recorder
/// profiles above for Misalignment and ScaleFactor, the topic's own reader profile (topics.hpp)
/// for the others. best_effort (--best-effort, weak links): topics::kGroundBestEffortReaderProfile.
const char* recording_reader_profile(const topics::TopicSpec& spec, bool best_effort = false);

/// The short name of a topic: "rt/odonav/gnss/fix" -> "gnss/fix".
std::string topic_short_name(const topics::TopicSpec& spec);

/// The QoS a writer offers, as far as the recording describes it.
struct OfferedQos {
  bool reliable = true;
  bool transient_local = false;
  bool keep_all = false;
  int depth = 1;                     ///< history depth (KEEP_LAST)
  std::optional<double> deadline_s;  ///< none: infinite
};

/// rosbag2's offered_qos_profiles YAML of one writer (rmw enum numbers: history KEEP_LAST 1 /
/// KEEP_ALL 2, reliability RELIABLE 1 / BEST_EFFORT 2, durability TRANSIENT_LOCAL 1 / VOLATILE 2,
/// liveliness AUTOMATIC 1; infinite durations as sec 2147483647, nsec 4294967295).
std::string offered_qos_profiles_yaml(const OfferedQos& qos);

/// Channel metadata of a recorded topic: "offered_qos_profiles" plus odonav's own keys
/// ("odonav_writer_qos_profile", "odonav_recorder_qos_profile", "dds_topic", "dds_type").
std::map<std::string, std::string> channel_metadata(const topics::TopicSpec& spec, const OfferedQos& qos,
                                                    const std::string& recorder_profile);

}  // namespace odonav::ground
