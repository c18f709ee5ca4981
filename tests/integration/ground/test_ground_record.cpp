// odonav-ground record on loopback DDS (domains 64, 65): the MCAP file is read back with the npm
// packages Foxglove itself uses (@mcap/core, @foxglove/rosmsg, @foxglove/rosmsg2-serialization),
// installed once into the build tree, and every decoded field must equal what this test published.
// A recording killed with SIGKILL must still yield every message flushed before its last second.
#include <gtest/gtest.h>

#include <set>

#include <nlohmann/json.hpp>

#include "shm_clean_test.hpp"
#include "ground_test_support.hpp"
#include "odonav/dds/endpoints.hpp"
#include "odonav/dds/health.hpp"
#include "odonav/dds/time.hpp"
#include "odonav/dds/types.hpp"

using namespace odonav::test;
using odonav::dds::Participant;
using odonav::dds::Writer;

namespace {

// ---- known samples, and the same values as the ROS 2 decoder shows them ----

json header_json(double t, const std::string& frame) {
  const auto stamp = odonav::dds::to_time_msg(t);
  return {{"stamp", {{"sec", stamp.sec()}, {"nanosec", stamp.nanosec()}}}, {"frame_id", frame}};
}

struct Sample {
  std::string topic;  // MCAP channel topic
  json expected;      // decoded fields
};

/// Publishes `n` samples (index i) of every topic with writers of the given participant, and returns
/// what the decoder must show for them, per topic in publication order.
class KnownPublisher {
 public:
  explicit KnownPublisher(const Participant& p)
      : odometer_(p, topics::kOdometer.name, topics::kOdometer.writer_profile),
        ins_(p, topics::kInsAttitude.name, topics::kInsAttitude.writer_profile),
        gnss_(p, topics::kGnssFix.name, topics::kGnssFix.writer_profile),
        misalignment_(p, topics::kMisalignment.name, topics::kMisalignment.writer_profile),
        scale_factor_(p, topics::kScaleFactor.name, topics::kScaleFactor.writer_profile),
        dead_reckoning_(p, topics::kDeadReckoning.name, topics::kDeadReckoning.writer_profile),
        navigation_(p, topics::kNavigationPosition.name, topics::kNavigationPosition.writer_profile),
        health_(p, topics::kHealth.name, topics::kHealth.writer_profile),
        command_(p, topics::kCommand.name, topics::kCommand.writer_profile) {}

  std::vector<odonav::dds::detail::WriterBase*> writers() {
    return {&odometer_,       &ins_,    &gnss_,    &misalignment_, &scale_factor_,
            &dead_reckoning_, &health_, &command_, &navigation_};
  }
  bool wait_matched(std::chrono::milliseconds timeout) {
    for (auto* w : writers())
      if (!w->wait_for_matched(1, timeout)) return false;
    return true;
  }
  bool wait_acknowledged(std::chrono::milliseconds timeout) {
    for (auto* w : writers())
      if (!w->wait_for_acknowledgments(timeout)) return false;
    return true;
  }

  /// Publishes sample i of every topic; appends the expectations.
  void publish(int i, std::map<std::string, std::vector<json>>& expected) {
    const double t = 1000.0 + 0.1 * i + 1e-9 * i;  // nanoseconds exercised too
    const std::string veh = "veh-rec";
    {
      msg::Odometer m;
      m.header(odonav::dds::make_header(t, "odometer"));
      m.vehicle_id(veh);
      m.pulses(4294967290u + static_cast<uint32_t>(i));  // wraps past 2^32 - 1 within the run
      m.direction(static_cast<int8_t>(i % 3 - 1));
      m.gnss_complete_known(i > 0);
      m.gnss_complete_through_s(i > 0 ? t - 0.05 : 0.0);
      m.gnss_last_stamp_s(i > 0 ? t - 0.05 : -1.0);
      EXPECT_TRUE(odometer_.write(m));
      expected["/odonav/odometer"].push_back({{"header", header_json(t, "odometer")},
                                              {"vehicle_id", veh},
                                              {"pulses", m.pulses()},
                                              {"direction", m.direction()},
                                              {"gnss_complete_known", m.gnss_complete_known()},
                                              {"gnss_complete_through_s", m.gnss_complete_through_s()},
                                              {"gnss_last_stamp_s", m.gnss_last_stamp_s()}});
    }
    {
      msg::InsAttitude m;
      m.header(odonav::dds::make_header(t, "body"));
      m.vehicle_id(veh);
      m.heading_rad(0.1 * i + 1.0 / 3.0);
      m.pitch_rad(-0.02);
      m.roll_rad(0.003 * i);
      m.velocity_east_mps(1.5);
      m.velocity_north_mps(-2.25);
      m.velocity_up_mps(0.125);
      m.velocity_valid(i % 2 == 0);
      m.valid(true);
      m.gnss_complete_known(i > 0);
      m.gnss_complete_through_s(i > 0 ? t - 0.05 : 0.0);
      m.gnss_last_stamp_s(i > 0 ? t - 0.05 : -1.0);
      EXPECT_TRUE(ins_.write(m));
      expected["/odonav/ins/attitude"].push_back({{"header", header_json(t, "body")},
                                                  {"vehicle_id", veh},
                                                  {"heading_rad", m.heading_rad()},
                                                  {"pitch_rad", m.pitch_rad()},
                                                  {"roll_rad", m.roll_rad()},
                                                  {"velocity_east_mps", 1.5},
                                                  {"velocity_north_mps", -2.25},
                                                  {"velocity_up_mps", 0.125},
                                                  {"velocity_valid", i % 2 == 0},
                                                  {"valid", true},
                                                  {"gnss_complete_known", m.gnss_complete_known()},
                                                  {"gnss_complete_through_s", m.gnss_complete_through_s()},
                                                  {"gnss_last_stamp_s", m.gnss_last_stamp_s()}});
    }
    {
      msg::GnssFix m;
      m.header(odonav::dds::make_header(t, "wgs84"));
      m.vehicle_id(veh);
      m.latitude_deg(52.5 + 1e-7 * i);
      m.longitude_deg(13.4 - 1e-7 * i);
      m.height_m(80.25);
      m.velocity_east_mps(0.1 * i);
      m.velocity_north_mps(10.0);
      m.velocity_up_mps(-0.01);
      m.fix_quality(static_cast<uint8_t>(i % 2 ? 4 : 1));
      m.position_std_m(-1.0);
      m.velocity_std_mps(0.05);
      m.valid(i % 5 != 4);
      EXPECT_TRUE(gnss_.write(m));
      expected["/odonav/gnss/fix"].push_back({{"header", header_json(t, "wgs84")},
                                              {"vehicle_id", veh},
                                              {"latitude_deg", m.latitude_deg()},
                                              {"longitude_deg", m.longitude_deg()},
                                              {"height_m", 80.25},
                                              {"velocity_east_mps", m.velocity_east_mps()},
                                              {"velocity_north_mps", 10.0},
                                              {"velocity_up_mps", -0.01},
                                              {"fix_quality", m.fix_quality()},
                                              {"position_std_m", -1.0},
                                              {"velocity_std_mps", 0.05},
                                              {"valid", m.valid()}});
    }
    {
      msg::Misalignment m;
      m.header(odonav::dds::make_header(t, "body"));
      m.vehicle_id(veh);
      m.heading_rad(0.0139626 + 1e-6 * i);
      m.pitch_rad(-0.00872665);
      m.heading_std_rad(1.7e-4);
      m.pitch_std_rad(-1.0);
      m.samples_used(static_cast<uint32_t>(100 * i));
      m.converged(i > 2);
      m.state(i > 2 ? msg::MISALIGNMENT_CONVERGED : msg::MISALIGNMENT_CALIBRATING);
      EXPECT_TRUE(misalignment_.write(m));
      expected["/odonav/misalignment"].push_back({{"header", header_json(t, "body")},
                                                  {"vehicle_id", veh},
                                                  {"heading_rad", m.heading_rad()},
                                                  {"pitch_rad", m.pitch_rad()},
                                                  {"heading_std_rad", 1.7e-4},
                                                  {"pitch_std_rad", -1.0},
                                                  {"samples_used", m.samples_used()},
                                                  {"converged", m.converged()},
                                                  {"state", static_cast<uint32_t>(m.state())}});
    }
    {
      msg::ScaleFactor m;
      m.header(odonav::dds::make_header(t, "odometer"));
      m.vehicle_id(veh);
      m.k_m_per_pulse(0.0126875 + 1e-7 * i);
      m.sigma_m_per_pulse(3.5e-6);
      m.forgetting_factor(0.97 + 0.001 * i);
      m.window_fill(0.1 * i);
      m.estimator("vff_lm_rls");
      m.converged(i > 1);
      m.samples_accepted(static_cast<uint32_t>(10 * i));
      m.samples_rejected(static_cast<uint32_t>(i));
      m.frozen(i == 3);
      // One instance: the recording follows one source per vehicle (SourceArbiter), which is then
      // every sample as written.
      m.source("identification/standby");
      m.source_priority(10);
      m.gnss_latency_s(0.001 * i);
      m.gnss_latency_sigma_s(i == 0 ? -1.0 : 0.0005);
      m.turn_slip_s_per_rad(0.01 * i);
      m.turn_slip_sigma_s_per_rad(i == 0 ? -1.0 : 0.002);
      m.turn_slip_threshold_radps(0.0523598775598);
      m.turn_slip_applies(i > 2);
      EXPECT_TRUE(scale_factor_.write(m));
      expected["/odonav/scale_factor"].push_back({{"header", header_json(t, "odometer")},
                                                  {"vehicle_id", veh},
                                                  {"k_m_per_pulse", m.k_m_per_pulse()},
                                                  {"sigma_m_per_pulse", 3.5e-6},
                                                  {"forgetting_factor", m.forgetting_factor()},
                                                  {"window_fill", m.window_fill()},
                                                  {"estimator", "vff_lm_rls"},
                                                  {"converged", m.converged()},
                                                  {"samples_accepted", m.samples_accepted()},
                                                  {"samples_rejected", m.samples_rejected()},
                                                  {"frozen", m.frozen()},
                                                  {"source", m.source()},
                                                  {"source_priority", 10},
                                                  {"gnss_latency_s", m.gnss_latency_s()},
                                                  {"gnss_latency_sigma_s", m.gnss_latency_sigma_s()},
                                                  {"turn_slip_s_per_rad", m.turn_slip_s_per_rad()},
                                                  {"turn_slip_sigma_s_per_rad", m.turn_slip_sigma_s_per_rad()},
                                                  {"turn_slip_threshold_radps", m.turn_slip_threshold_radps()},
                                                  {"turn_slip_applies", m.turn_slip_applies()}});
    }
    {
      msg::DeadReckoning m;
      m.header(odonav::dds::make_header(t, "wgs84"));
      m.vehicle_id(veh);
      m.latitude_deg(52.5001 + 1e-8 * i);
      m.longitude_deg(13.4002);
      m.height_m(79.5);
      m.enu_east_m(1.25 * i);
      m.enu_north_m(-0.5 * i);
      m.enu_up_m(0.0);
      m.origin_latitude_deg(52.5);
      m.origin_longitude_deg(13.4);
      m.origin_height_m(80.0);
      m.heading_rad(2.5);
      m.distance_m(12.5 * i);
      m.k_m_per_pulse(0.0127);
      m.k_source(i > 2 ? msg::K_SOURCE_IDENTIFIED : msg::K_SOURCE_NOMINAL);
      m.misalignment_heading_rad(0.014);
      m.misalignment_pitch_rad(-0.0087);
      m.gnss_valid(true);
      m.horizontal_error_m(0.75 + i);
      m.error_percent_distance(i == 0 ? -1.0 : 0.12);
      m.error_t_s(i == 0 ? -1.0 : t - 0.3);
      EXPECT_TRUE(dead_reckoning_.write(m));
      expected["/odonav/dead_reckoning"].push_back({{"header", header_json(t, "wgs84")},
                                                    {"vehicle_id", veh},
                                                    {"latitude_deg", m.latitude_deg()},
                                                    {"longitude_deg", 13.4002},
                                                    {"height_m", 79.5},
                                                    {"enu_east_m", m.enu_east_m()},
                                                    {"enu_north_m", m.enu_north_m()},
                                                    {"enu_up_m", 0.0},
                                                    {"origin_latitude_deg", 52.5},
                                                    {"origin_longitude_deg", 13.4},
                                                    {"origin_height_m", 80.0},
                                                    {"heading_rad", 2.5},
                                                    {"distance_m", m.distance_m()},
                                                    {"k_m_per_pulse", 0.0127},
                                                    {"k_source", static_cast<uint32_t>(m.k_source())},
                                                    {"misalignment_heading_rad", 0.014},
                                                    {"misalignment_pitch_rad", -0.0087},
                                                    {"gnss_valid", true},
                                                    {"horizontal_error_m", m.horizontal_error_m()},
                                                    {"error_percent_distance", m.error_percent_distance()},
                                                    {"error_t_s", m.error_t_s()}});
    }
    {
      msg::NavigationPosition m;
      m.header(odonav::dds::make_header(t, "wgs84"));
      m.vehicle_id(veh);
      m.latitude_deg(52.5002 + 1e-8 * i);
      m.longitude_deg(13.4001);
      m.height_m(80.5);
      m.enu_east_m(1.5 * i);
      m.enu_north_m(-0.25 * i);
      m.enu_up_m(0.5);
      const double var = i == 0 ? -1.0 : 0.5 + 0.01 * i;
      m.position_covariance_east_m2(var);
      m.position_covariance_north_m2(var);
      m.position_covariance_up_m2(i == 0 ? -1.0 : 1.125);
      m.position_covariance_type(i == 0 ? 0 : 2);
      m.status(i == 0       ? msg::NAVIGATION_STATUS_NOT_STARTED
               : i % 4 == 3 ? msg::NAVIGATION_STATUS_DEAD_RECKONING
                            : msg::NAVIGATION_STATUS_ANCHORED);
      m.last_fix_stamp_s(i == 0 ? -1.0 : t - 0.1);
      m.distance_since_fix_m(i == 0 ? -1.0 : 1.25);
      EXPECT_TRUE(navigation_.write(m));
      expected["/odonav/navigation_position"].push_back({{"header", header_json(t, "wgs84")},
                                                         {"vehicle_id", veh},
                                                         {"latitude_deg", m.latitude_deg()},
                                                         {"longitude_deg", 13.4001},
                                                         {"height_m", 80.5},
                                                         {"enu_east_m", m.enu_east_m()},
                                                         {"enu_north_m", m.enu_north_m()},
                                                         {"enu_up_m", 0.5},
                                                         {"position_covariance_east_m2", var},
                                                         {"position_covariance_north_m2", var},
                                                         {"position_covariance_up_m2", m.position_covariance_up_m2()},
                                                         {"position_covariance_type", m.position_covariance_type()},
                                                         {"status", static_cast<uint32_t>(m.status())},
                                                         {"last_fix_stamp_s", m.last_fix_stamp_s()},
                                                         {"distance_since_fix_m", m.distance_since_fix_m()}});
    }
    {
      const odonav::dds::HealthCounters counters{{"queue_depth", static_cast<double>(i)}, {"odometer_in", 1e6 + i}};
      odonav::dds::CommandAck ack{static_cast<uint32_t>(70000 + i), msg::COMMAND_RESULT_REJECTED,
                                  "nope " + std::to_string(i)};
      const msg::Health m =
          odonav::dds::make_health(veh, "odonav-comp-" + std::to_string(i), t, msg::HEALTH_STATE_DEGRADED,
                                   msg::HEALTH_LEVEL_WARN, "no gnss for " + std::to_string(i) + " s", counters, ack);
      EXPECT_TRUE(health_.write(m));
      json c = json::array();
      for (const auto& [name, value] : counters) c.push_back({{"name", name}, {"value", value}});
      expected["/odonav/health"].push_back({{"header", header_json(t, "")},
                                            {"vehicle_id", veh},
                                            {"component", "odonav-comp-" + std::to_string(i)},
                                            {"state", 2},
                                            {"level", 1},
                                            {"reason", "no gnss for " + std::to_string(i) + " s"},
                                            {"counters", c},
                                            {"last_command_id", 70000 + i},
                                            {"last_command_result", 2},
                                            {"last_command_detail", "nope " + std::to_string(i)}});
    }
    {
      msg::Command m;
      m.header(odonav::dds::make_header(t, ""));
      m.vehicle_id(veh);
      m.target_component("odonav-identification");
      m.command(msg::COMMAND_SET_K);
      m.value(0.0125 + 1e-6 * i);
      m.command_id(static_cast<uint32_t>(i + 1));
      EXPECT_TRUE(command_.write(m));
      expected["/odonav/command"].push_back({{"header", header_json(t, "")},
                                             {"vehicle_id", veh},
                                             {"target_component", "odonav-identification"},
                                             {"command", 1},
                                             {"value", m.value()},
                                             {"command_id", i + 1}});
    }
  }

 private:
  Writer<msg::Odometer> odometer_;
  Writer<msg::InsAttitude> ins_;
  Writer<msg::GnssFix> gnss_;
  Writer<msg::Misalignment> misalignment_;
  Writer<msg::ScaleFactor> scale_factor_;
  Writer<msg::DeadReckoning> dead_reckoning_;
  Writer<msg::NavigationPosition> navigation_;
  Writer<msg::Health> health_;
  Writer<msg::Command> command_;
};

/// Decoded messages of a read, by topic, in file order.
std::map<std::string, std::vector<json>> by_topic(const json& doc) {
  std::map<std::string, std::vector<json>> m;
  for (const auto& message : doc.at("messages")) m[message.at("topic")].push_back(message.at("data"));
  return m;
}

class GroundRecord : public odonav::test::ShmCleanTest {};

}  // namespace

TEST_F(GroundRecord, McapOfEveryTopicDecodesToThePublishedValues) {
  constexpr int kDomain = 64;
  const auto dir = scratch_dir("record");
  const fs::path file = dir / "all.mcap";
  ASSERT_TRUE(npm_reader_modules().has_value());  // before the clock starts: the install may take a while

  Participant participant(participant_options(kDomain, "known-publisher"));
  KnownPublisher publisher(participant);
  ChildProcess recorder(binary("odonav-ground"), ground_args("record", kDomain, {"--out", file.string()}),
                        dir / "record.out", dir / "record.err");
  ASSERT_TRUE(recorder.started());
  ASSERT_TRUE(publisher.wait_matched(20s)) << "the recorder's readers did not match: " << recorder.err();
  // Our writers matched the recorder's readers; give the recorder's side of the handshake a moment
  // too (an estimate written before it completes is replaced in the KEEP_LAST 1 history).
  std::this_thread::sleep_for(1s);
  std::map<std::string, std::vector<json>> expected;
  constexpr int kSamples = 6;
  // One sample of every topic each 100 ms, the estimates' nominal rate (one per 10 Hz GNSS epoch):
  // their reader profile keeps the last sample only, as every consumer on the vehicle does.
  for (int i = 0; i < kSamples; ++i) {
    publisher.publish(i, expected);
    std::this_thread::sleep_for(100ms);
  }
  ASSERT_TRUE(publisher.wait_acknowledged(10s));  // every sample is in the recorder (reliable readers)
  recorder.signal(SIGINT);
  ASSERT_TRUE(recorder.wait_exit(20s));
  ASSERT_EQ(recorder.exit_code(), 0) << recorder.err();
  EXPECT_NE(recorder.out().find("recorded " + std::to_string(9 * kSamples) + " messages on 9 topics"),
            std::string::npos)
      << recorder.out();

  const McapRead read = read_mcap(file, "indexed");
  ASSERT_EQ(read.exit_code, 0) << read.err;
  const json& doc = read.doc;
  EXPECT_TRUE(doc.at("complete").get<bool>());
  EXPECT_EQ(doc.at("bytes_left"), 0);
  // The standard channels of the one vehicle (components/ground/README.md, "record"): three NavSatFix
  // (navigation, dead reckoning, GNSS) and one DiagnosticArray, two more schemas.
  const std::string prefix = "/odonav/veh-rec/";
  const std::set<std::string> standard{prefix + "navsat/navigation", prefix + "navsat/dead_reckoning",
                                       prefix + "navsat/gnss", prefix + "diagnostics"};
  const auto decoded = by_topic(doc);
  std::size_t standard_messages = 0;
  for (const auto& t : standard) standard_messages += decoded.count(t) ? decoded.at(t).size() : 0;
  // Summary: statistics and the schema/channel records, as indexed readers use them.
  EXPECT_EQ(doc.at("statistics").at("message_count"), std::to_string(9 * kSamples + standard_messages));
  EXPECT_EQ(doc.at("statistics").at("channel_count"), 9 + 4);
  EXPECT_EQ(doc.at("statistics").at("schema_count"), 9 + 2);
  EXPECT_NE(doc.at("footer").at("summary_crc"), 0);  // computed, and @mcap/core checked it
  ASSERT_EQ(doc.at("channels").size(), 13u);
  for (const auto& channel : doc.at("channels")) {
    SCOPED_TRACE(channel.dump());
    EXPECT_EQ(channel.at("message_encoding"), "cdr");
    if (standard.count(channel.at("topic"))) {
      EXPECT_EQ(channel.at("metadata").at("odonav_vehicle_id"), "veh-rec");
      continue;
    }
    EXPECT_EQ(channel.at("metadata").at("offered_qos_profiles").get<std::string>().rfind("- history: 1\n  depth: ", 0),
              0u);
    EXPECT_EQ(doc.at("statistics").at("channel_message_counts").at(std::to_string(channel.at("id").get<int>())),
              std::to_string(kSamples));
  }
  for (const auto& schema : doc.at("schemas")) {
    EXPECT_EQ(schema.at("encoding"), "ros2msg");
    EXPECT_EQ(schema.at("name").get<std::string>().find("/msg/") != std::string::npos, true);
  }
  // NavSatFix: the published dead reckoning and GNSS positions, sample for sample (decoded by
  // @foxglove/rosmsg2-serialization from the sensor_msgs schema).
  for (const auto& [navsat, source] :
       {std::pair<std::string, std::string>{prefix + "navsat/dead_reckoning", "/odonav/dead_reckoning"},
        {prefix + "navsat/navigation", "/odonav/navigation_position"},
        {prefix + "navsat/gnss", "/odonav/gnss/fix"}}) {
    SCOPED_TRACE(navsat);
    ASSERT_EQ(decoded.count(navsat), 1u);
    const auto& fixes = decoded.at(navsat);
    const auto& published = expected.at(source);
    ASSERT_EQ(fixes.size(), published.size());
    for (std::size_t i = 0; i < fixes.size(); ++i) {
      EXPECT_EQ(fixes[i].at("latitude"), published[i].at("latitude_deg"));
      EXPECT_EQ(fixes[i].at("longitude"), published[i].at("longitude_deg"));
      EXPECT_EQ(fixes[i].at("altitude"), published[i].at("height_m"));
      EXPECT_EQ(fixes[i].at("header").at("stamp"), published[i].at("header").at("stamp"));
    }
  }
  // DiagnosticArray: every component that sent Health, with its level.
  ASSERT_EQ(decoded.count(prefix + "diagnostics"), 1u);
  const json& last = decoded.at(prefix + "diagnostics").back();
  std::set<std::string> names;
  for (const auto& st : last.at("status")) names.insert(st.at("name").get<std::string>());
  for (const auto& h : expected.at("/odonav/health")) {
    EXPECT_TRUE(names.count("veh-rec/" + h.at("component").get<std::string>())) << last.dump();
  }
  // The health QoS metadata says what the vehicle offers: reliable (1), transient local (1), deadline 3 s.
  for (const auto& channel : doc.at("channels")) {
    if (channel.at("topic") != "/odonav/health") continue;
    const std::string qos = channel.at("metadata").at("offered_qos_profiles");
    EXPECT_NE(qos.find("reliability: 1\n  durability: 1\n  deadline:\n    sec: 3\n    nsec: 0"), std::string::npos)
        << qos;
  }

  ASSERT_EQ(decoded.size(), expected.size() + standard.size());
  for (const auto& [topic, samples] : expected) {
    SCOPED_TRACE(topic);
    ASSERT_EQ(decoded.count(topic), 1u);
    const auto& got = decoded.at(topic);
    ASSERT_EQ(got.size(), samples.size());
    // Health instances differ by component: order across instances is not guaranteed; match by key.
    for (std::size_t i = 0; i < samples.size(); ++i) {
      if (topic == "/odonav/health") {
        const auto it = std::find_if(got.begin(), got.end(),
                                     [&](const json& g) { return g.at("component") == samples[i].at("component"); });
        ASSERT_NE(it, got.end());
        EXPECT_EQ(*it, samples[i]);
      } else {
        EXPECT_EQ(got[i], samples[i]) << "sample " << i;
      }
    }
  }
}

TEST_F(GroundRecord, RecordingKilledBySigkillKeepsEverythingBeforeItsLastSecond) {
  constexpr int kDomain = 65;
  const auto dir = scratch_dir("record_kill");
  const fs::path file = dir / "killed.mcap";
  ASSERT_TRUE(npm_reader_modules().has_value());

  Participant participant(participant_options(kDomain, "known-publisher"));
  KnownPublisher publisher(participant);
  ChildProcess recorder(binary("odonav-ground"), ground_args("record", kDomain, {"--out", file.string()}),
                        dir / "record.out", dir / "record.err");
  ASSERT_TRUE(recorder.started());
  ASSERT_TRUE(publisher.wait_matched(20s)) << recorder.err();
  std::this_thread::sleep_for(1s);
  std::map<std::string, std::vector<json>> early, late;
  constexpr int kEarly = 5;
  for (int i = 0; i < kEarly; ++i) {
    publisher.publish(i, early);
    std::this_thread::sleep_for(100ms);
  }
  ASSERT_TRUE(publisher.wait_acknowledged(10s));
  // More than the 1 s flush period (plus its 50 ms polling): the early samples must be in the file.
  std::this_thread::sleep_for(2500ms);
  for (int i = kEarly; i < kEarly + 5; ++i) publisher.publish(i, late);
  recorder.signal(SIGKILL);
  ASSERT_TRUE(recorder.wait_exit(10s));
  EXPECT_EQ(recorder.exit_code(), 128 + SIGKILL);

  // Not a complete MCAP file: no summary, no footer, so the indexed reader refuses it ...
  const McapRead indexed = read_mcap(file, "indexed");
  EXPECT_NE(indexed.exit_code, 0);
  // ... but a stream reader recovers every record up to the cut, which is a record boundary.
  const McapRead stream = read_mcap(file, "stream");
  ASSERT_EQ(stream.exit_code, 0) << stream.err;
  EXPECT_FALSE(stream.doc.at("complete").get<bool>());
  EXPECT_EQ(stream.doc.at("bytes_left"), 0);
  EXPECT_EQ(stream.doc.at("channels").size(), 9u + 4u);  // the topics and the standard channels of the vehicle
  const auto decoded = by_topic(stream.doc);
  for (const auto& [topic, samples] : early) {
    SCOPED_TRACE(topic);
    ASSERT_EQ(decoded.count(topic), 1u);
    const auto& got = decoded.at(topic);
    // Every early sample; late ones may or may not have been flushed.
    ASSERT_GE(got.size(), samples.size());
    ASSERT_LE(got.size(), samples.size() + late.at(topic).size());
    if (topic == "/odonav/health") continue;  // order across instances not guaranteed (checked above)
    for (std::size_t i = 0; i < samples.size(); ++i) EXPECT_EQ(got[i], samples[i]) << "sample " << i;
  }
}
