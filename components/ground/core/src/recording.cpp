#include "odonav/ground/recording.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace odonav::ground {

std::string topic_short_name(const topics::TopicSpec& spec) {
  const std::string name = spec.name;
  const std::string prefix = "rt/odonav/";
  return name.rfind(prefix, 0) == 0 ? name.substr(prefix.size()) : name;
}

const char* recording_reader_profile(const topics::TopicSpec& spec, bool best_effort) {
  const std::string name = spec.name;
  const bool misalignment = name == topics::kMisalignment.name;
  const bool scale_factor = name == topics::kScaleFactor.name;
  if (best_effort) return topics::kGroundBestEffortReaderProfile;
  if (misalignment) return kMisalignmentRecorderReaderProfile;
  if (scale_factor) return kScaleFactorRecorderReaderProfile;
  return spec.reader_profile;
}

std::vector<topics::TopicSpec> select_topics(const std::string& list) {
  std::vector<topics::TopicSpec> chosen;
  auto add = [&](const topics::TopicSpec& spec) {
    for (const auto& c : chosen)
      if (std::string(c.name) == spec.name) return;
    chosen.push_back(spec);
  };
  std::istringstream items(list);
  std::string item;
  bool any = false;
  while (std::getline(items, item, ',')) {
    const auto b = item.find_first_not_of(' ');
    const auto e = item.find_last_not_of(' ');
    item = b == std::string::npos ? "" : item.substr(b, e - b + 1);
    if (item.empty()) continue;
    any = true;
    if (item == "all") {
      for (const auto& spec : topics::kAllTopics) add(spec);
      continue;
    }
    bool found = false;
    for (const auto& spec : topics::kAllTopics) {
      const std::string dds = spec.name;
      if (item == dds || item == dds.substr(2) || item == topic_short_name(spec)) {
        add(spec);
        found = true;
      }
    }
    if (!found) {
      std::string valid;
      for (const auto& spec : topics::kAllTopics) valid += (valid.empty() ? "" : ", ") + topic_short_name(spec);
      throw std::invalid_argument("--topics: unknown topic '" + item + "' (valid: " + valid +
                                  ", or their full names rt/odonav/... / /odonav/...)");
    }
  }
  if (!any)
    for (const auto& spec : topics::kAllTopics) add(spec);
  return chosen;
}

std::string offered_qos_profiles_yaml(const OfferedQos& q) {
  std::ostringstream y;
  auto duration = [&](const char* key, std::optional<double> s) {
    y << "  " << key << ":\n";
    if (!s) {
      y << "    sec: 2147483647\n    nsec: 4294967295\n";
    } else {
      const double whole = std::floor(*s);
      y << "    sec: " << static_cast<long long>(whole)
        << "\n    nsec: " << static_cast<long long>(std::llround((*s - whole) * 1e9)) << "\n";
    }
  };
  y << "- history: " << (q.keep_all ? 2 : 1) << "\n";
  y << "  depth: " << q.depth << "\n";
  y << "  reliability: " << (q.reliable ? 1 : 2) << "\n";
  y << "  durability: " << (q.transient_local ? 1 : 2) << "\n";
  duration("deadline", q.deadline_s);
  duration("lifespan", std::nullopt);
  y << "  liveliness: 1\n";
  duration("liveliness_lease_duration", std::nullopt);
  y << "  avoid_ros_namespace_conventions: false";
  return y.str();
}

std::map<std::string, std::string> channel_metadata(const topics::TopicSpec& spec, const OfferedQos& qos,
                                                    const std::string& recorder_profile) {
  return {{"offered_qos_profiles", offered_qos_profiles_yaml(qos)},
          {"odonav_writer_qos_profile", spec.writer_profile},
          {"odonav_recorder_qos_profile", recorder_profile},
          {"dds_topic", spec.name},
          {"dds_type", spec.dds_type_name}};
}

}  // namespace odonav::ground
