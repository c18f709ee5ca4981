// Every odonav topic is readable by another vendor's default-QoS reader, which is how ROS 2 tools
// read (their QoS has no ownership field: SHARED): Fast DDS writers of all eight topics, each with
// its contract writer profile (deploy/profiles/qos.xml), two scale-factor writers among them as a
// primary and a hot standby; a C reader on Eclipse Cyclone DDS (cyclone_reader.c, types from idl/ by
// Cyclone's idlc, ROS 2 type names, no QoS given) in its own process on loopback (domain 190).
// Asserted: every writer matches the foreign reader (an incompatible QoS never would), every topic
// delivers samples, and the scale factor of both instances arrives with the values written (K,
// source, priority, stamp), as does every other topic's vehicle and stamp.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "../topics/message_fields.hpp"
#include "child_process.hpp"
#include "odonav/dds/endpoints.hpp"
#include "odonav/dds/participant.hpp"
#include "odonav/dds/time.hpp"
#include "odonav/topics.hpp"

namespace {

namespace topics = odonav::topics;
namespace msg = odonav::msg;
using odonav::dds::Writer;
using odonav::test::ChildProcess;
using std::chrono::milliseconds;
using std::chrono::seconds;

constexpr int kDomain = 190;
constexpr const char* kVehicle = "interop-vehicle";
constexpr long kMinPerTopic = 10;

// Cyclone DDS on loopback only: no multicast, unicast discovery to 127.0.0.1 on the ports of
// participant indices 0..40 (Fast DDS's loopback profile probes 32 of them the other way).
constexpr const char* kCycloneConfig =
    "<CycloneDDS><Domain id=\"any\"><General><Interfaces><NetworkInterface name=\"lo\"/></Interfaces>"
    "<AllowMulticast>false</AllowMulticast></General><Discovery><ParticipantIndex>auto</ParticipantIndex>"
    "<MaxAutoParticipantIndex>40</MaxAutoParticipantIndex><Peers><Peer address=\"127.0.0.1\"/></Peers>"
    "</Discovery></Domain></CycloneDDS>";

odonav::dds::ParticipantOptions participant_options() {
  odonav::dds::ParticipantOptions p;
  p.profiles_file = std::string(ODONAV_SOURCE_DIR) + "/deploy/profiles/loopback.xml";
  p.domain_id = kDomain;
  p.participant_name = "odonav-interop-test";
  return p;
}

double stamp_of(int i) { return 5000.0 + 0.1 * i; }

/// The K the instance `priority` writes at step i: distinct per instance and step, exact in %.17g.
double k_of(std::uint32_t priority, int i) { return 0.0125 + 1e-7 * i + 1e-9 * priority; }

template <class T>
T stamped(T m, int i) {
  m.header().stamp(odonav::dds::to_time_msg(stamp_of(i)));
  m.vehicle_id(kVehicle);
  return m;
}

/// One "sample <topic> <vehicle> <stamp> ..." line of the Cyclone reader.
struct Line {
  std::string topic, vehicle;
  double stamp_s = 0.0;
  std::map<std::string, std::string> fields;  // key=value words after the stamp
};

std::vector<Line> parse(const std::string& text, std::map<std::string, long>& counts) {
  std::vector<Line> lines;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream words(line);
    std::string kind;
    words >> kind;
    if (kind == "count") {
      std::string topic;
      long n = 0;
      words >> topic >> n;
      counts[topic] = n;
    } else if (kind == "sample") {
      Line l;
      words >> l.topic >> l.vehicle >> l.stamp_s;
      std::string kv;
      while (words >> kv) {
        const auto eq = kv.find('=');
        if (eq != std::string::npos) l.fields[kv.substr(0, eq)] = kv.substr(eq + 1);
      }
      lines.push_back(l);
    }
  }
  return lines;
}

TEST(Interop, EveryTopicIsReadByACycloneDdsReaderWithDefaultQosAndRosTypeNames) {
  odonav::test::shm_clean();
  const auto dir = odonav::test::fresh_dir("test-interop", "cyclone");
  ::setenv("CYCLONEDDS_URI", kCycloneConfig, 1);  // the child inherits it
  ChildProcess reader(ODONAV_CYCLONE_READER, {std::to_string(kDomain), "60", std::to_string(kMinPerTopic)},
                      dir / "reader.out", dir / "reader.err");
  ASSERT_TRUE(reader.started());

  odonav::dds::Participant participant(participant_options());
  Writer<msg::Odometer> odometer(participant, topics::kOdometer.name, topics::kOdometer.writer_profile);
  Writer<msg::InsAttitude> ins(participant, topics::kInsAttitude.name, topics::kInsAttitude.writer_profile);
  Writer<msg::GnssFix> gnss(participant, topics::kGnssFix.name, topics::kGnssFix.writer_profile);
  Writer<msg::Misalignment> misalignment(participant, topics::kMisalignment.name, topics::kMisalignment.writer_profile);
  // Primary and hot standby, as odonav-identification writes them (priority 20 and 10).
  odonav::dds::WriterSettings strong, weak;
  strong.ownership_strength = 20;
  weak.ownership_strength = 10;
  Writer<msg::ScaleFactor> primary(participant, topics::kScaleFactor.name, topics::kScaleFactor.writer_profile, strong);
  Writer<msg::ScaleFactor> standby(participant, topics::kScaleFactor.name, topics::kScaleFactor.writer_profile, weak);
  Writer<msg::DeadReckoning> dead_reckoning(participant, topics::kDeadReckoning.name,
                                            topics::kDeadReckoning.writer_profile);
  Writer<msg::NavigationPosition> navigation(participant, topics::kNavigationPosition.name,
                                             topics::kNavigationPosition.writer_profile);
  Writer<msg::Health> health(participant, topics::kHealth.name, topics::kHealth.writer_profile);
  Writer<msg::Command> command(participant, topics::kCommand.name, topics::kCommand.writer_profile);

  const std::vector<std::pair<const char*, odonav::dds::detail::WriterBase*>> writers{
      {"odometer", &odometer},
      {"ins", &ins},
      {"gnss", &gnss},
      {"misalignment", &misalignment},
      {"primary", &primary},
      {"standby", &standby},
      {"dead_reckoning", &dead_reckoning},
      {"health", &health},
      {"command", &command},
      {"navigation_position", &navigation}};
  // Matching is where an incompatible QoS (EXCLUSIVE against the reader's SHARED) shows.
  for (const auto& [name, w] : writers)
    EXPECT_TRUE(w->wait_for_matched(1, seconds(30))) << name << " writer never matched the Cyclone DDS reader\n"
                                                     << reader.err();
  if (HasFailure()) return;

  // 10 Hz until the reader has enough of every topic (it exits then), at most 20 s.
  // (The 2 x 50 ms pauses between the two scale-factor writes make the 100 ms step.)
  int steps = 0;
  for (; steps < 200 && reader.running(); ++steps) {
    odometer.write(stamped(odonav::test::make_odometer(), steps));
    ins.write(stamped(odonav::test::make_ins_attitude(), steps));
    gnss.write(stamped(odonav::test::make_gnss_fix(), steps));
    misalignment.write(stamped(odonav::test::make_misalignment(), steps));
    for (const auto& [w, prio, source] :
         {std::make_tuple(&primary, 20u, "identification"), std::make_tuple(&standby, 10u, "identification/standby")}) {
      msg::ScaleFactor k = stamped(odonav::test::make_scale_factor(), steps);
      k.k_m_per_pulse(k_of(prio, steps));
      k.source(source);
      k.source_priority(prio);
      w->write(k);
      // The default reader keeps the last sample per instance (one vehicle: one instance), and it
      // polls every 20 ms: let it take the primary's before the standby's replaces it.
      std::this_thread::sleep_for(milliseconds(50));
    }
    dead_reckoning.write(stamped(odonav::test::make_dead_reckoning(), steps));
    navigation.write(stamped(odonav::test::make_navigation_position(), steps));
    msg::Health h = stamped(odonav::test::make_health_sample(), steps);
    h.component("odonav-identification");
    health.write(h);
    command.write(stamped(odonav::test::make_command(), steps));
  }
  ASSERT_TRUE(reader.wait_exit(seconds(70)));
  EXPECT_EQ(reader.exit_code(), 0) << reader.err();

  std::map<std::string, long> counts;
  const std::vector<Line> lines = parse(reader.out(), counts);
  std::cerr << "Cyclone DDS reader, " << steps << " steps written:";
  for (const auto& spec : topics::kAllTopics) std::cerr << " " << spec.name << "=" << counts[spec.name];
  std::cerr << "\n";
  for (const auto& spec : topics::kAllTopics) EXPECT_GE(counts[spec.name], kMinPerTopic) << spec.name;

  // What arrived is what was written: vehicle and a stamp of a step, for every topic; for the
  // scale factor also K, source and priority, of both instances.
  std::set<std::string> sources;
  for (const Line& l : lines) {
    SCOPED_TRACE(l.topic);
    EXPECT_EQ(l.vehicle, kVehicle);
    const int i = static_cast<int>(std::lround((l.stamp_s - stamp_of(0)) / 0.1));
    ASSERT_GE(i, 0);
    ASSERT_LT(i, steps);
    EXPECT_NEAR(l.stamp_s, stamp_of(i), 1e-6);
    if (l.topic == topics::kScaleFactor.name) {
      const std::uint32_t prio = static_cast<std::uint32_t>(std::stoul(l.fields.at("priority")));
      const std::string source = l.fields.at("source");
      EXPECT_EQ(source, prio == 20u ? "identification" : "identification/standby");
      EXPECT_EQ(std::stod(l.fields.at("k")), k_of(prio, i)) << "t=" << l.stamp_s;
      sources.insert(source);
    }
    if (l.topic == topics::kHealth.name) {
      EXPECT_EQ(l.fields.at("component"), "odonav-identification");
    }
  }
  EXPECT_EQ(sources, (std::set<std::string>{"identification", "identification/standby"}))
      << "a SHARED reader sees every instance";
  odonav::test::shm_clean();
}

}  // namespace
