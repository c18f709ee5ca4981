// Over loopback DDS (domain 10, deploy/profiles/loopback.xml + qos.xml): every topic type
// round-trips with every field intact, the deadline callback is edge-detected, the health helper
// honours its rate, and configuration mistakes give errors that say what and where.
// Each test uses its own topic names so tests run in parallel (ctest -j) cannot hear each other.
#include <gtest/gtest.h>

#include <chrono>
#include <condition_variable>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "message_fields.hpp"
#include "error_of.hpp"
#include "odonav/dds/endpoints.hpp"
#include "odonav/dds/health.hpp"
#include "odonav/dds/participant.hpp"
#include "odonav/dds/time.hpp"
#include "odonav/topics.hpp"

using namespace std::chrono_literals;
using odonav::dds::Participant;
using odonav::dds::ParticipantOptions;
using odonav::dds::Reader;
using odonav::dds::Writer;
namespace topics = odonav::topics;
namespace msg = odonav::msg;
using odonav::test::error_of;

namespace {

constexpr int kDomain = 10;
constexpr auto kTimeout = 10s;  // generous: 2 shared cores; a hang becomes a failure, not a stall

std::string loopback_profile_file() { return std::string(ODONAV_SOURCE_DIR) + "/deploy/profiles/loopback.xml"; }

ParticipantOptions loopback_options(const std::string& name) {
  ParticipantOptions options;
  options.profiles_file = loopback_profile_file();
  options.participant_profile = topics::kLoopbackParticipantProfile;
  options.domain_id = kDomain;
  options.participant_name = name;
  return options;
}

void clean_shared_memory() {
  // Leftovers of crashed runs; safe while other processes run (docs/DDS.md §3).
  if (std::system("fastdds shm clean >/dev/null 2>&1") != 0) {
    std::fprintf(stderr, "note: 'fastdds shm clean' failed or is not installed\n");
  }
}

}  // namespace

class DdsTopics : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    clean_shared_memory();
    writer_side_ = std::make_unique<Participant>(loopback_options("odonav-test-writer"));
    reader_side_ = std::make_unique<Participant>(loopback_options("odonav-test-reader"));
  }
  static void TearDownTestSuite() {
    writer_side_.reset();
    reader_side_.reset();
    clean_shared_memory();
  }

  /// Publishes `sample` on `topic` (the spec's type name and profiles, under a test-private topic
  /// name) and returns what the reader received.
  template <class T>
  static std::optional<T> round_trip(const topics::TopicSpec& spec, const T& sample) {
    const std::string topic_name = std::string(spec.name) + "/roundtrip_test";
    Reader<T> reader(*reader_side_, topic_name, spec.reader_profile);
    Writer<T> writer(*writer_side_, topic_name, spec.writer_profile);
    EXPECT_EQ(reader.native().get_topicdescription()->get_type_name(), spec.dds_type_name);
    if (!writer.wait_for_matched(1, kTimeout) || !reader.wait_for_matched(1, kTimeout)) {
      ADD_FAILURE() << "writer and reader of " << topic_name << " did not match";
      return std::nullopt;
    }
    EXPECT_TRUE(writer.write(sample));
    if (!reader.wait_for_data(kTimeout)) {
      ADD_FAILURE() << "nothing received on " << topic_name;
      return std::nullopt;
    }
    std::vector<T> received = reader.take();
    if (received.size() != 1) {
      ADD_FAILURE() << received.size() << " samples received on " << topic_name << ", expected 1";
      return std::nullopt;
    }
    return received.front();
  }

  template <class T>
  static void expect_round_trip(const topics::TopicSpec& spec, const T& sample) {
    const auto received = round_trip(spec, sample);
    ASSERT_TRUE(received.has_value());
    EXPECT_EQ(odonav::test::fields(*received), odonav::test::fields(sample));
  }

  static std::unique_ptr<Participant> writer_side_;
  static std::unique_ptr<Participant> reader_side_;
};

std::unique_ptr<Participant> DdsTopics::writer_side_;
std::unique_ptr<Participant> DdsTopics::reader_side_;

TEST_F(DdsTopics, OdometerRoundTripsEveryField) { expect_round_trip(topics::kOdometer, odonav::test::make_odometer()); }
TEST_F(DdsTopics, InsAttitudeRoundTripsEveryField) {
  expect_round_trip(topics::kInsAttitude, odonav::test::make_ins_attitude());
}
TEST_F(DdsTopics, GnssFixRoundTripsEveryField) { expect_round_trip(topics::kGnssFix, odonav::test::make_gnss_fix()); }
TEST_F(DdsTopics, MisalignmentRoundTripsEveryField) {
  expect_round_trip(topics::kMisalignment, odonav::test::make_misalignment());
}
TEST_F(DdsTopics, ScaleFactorRoundTripsEveryField) {
  expect_round_trip(topics::kScaleFactor, odonav::test::make_scale_factor());
}
TEST_F(DdsTopics, DeadReckoningRoundTripsEveryField) {
  expect_round_trip(topics::kDeadReckoning, odonav::test::make_dead_reckoning());
}

TEST_F(DdsTopics, NavigationPositionRoundTripsEveryField) {
  expect_round_trip(topics::kNavigationPosition, odonav::test::make_navigation_position());
}
TEST_F(DdsTopics, HealthRoundTripsEveryField) {
  expect_round_trip(topics::kHealth, odonav::test::make_health_sample());
}
TEST_F(DdsTopics, CommandRoundTripsEveryField) { expect_round_trip(topics::kCommand, odonav::test::make_command()); }

TEST_F(DdsTopics, GroundBestEffortReaderReceivesFromAReliableSensorWriter) {
  const std::string topic_name = std::string(topics::kGnssFix.name) + "/ground_test";
  Reader<msg::GnssFix> reader(*reader_side_, topic_name, topics::kGroundBestEffortReaderProfile);
  Writer<msg::GnssFix> writer(*writer_side_, topic_name, topics::kGnssFix.writer_profile);
  ASSERT_TRUE(writer.wait_for_matched(1, kTimeout));
  ASSERT_TRUE(reader.wait_for_matched(1, kTimeout));
  const msg::GnssFix sample = odonav::test::make_gnss_fix();
  ASSERT_TRUE(writer.write(sample));
  ASSERT_TRUE(reader.wait_for_data(kTimeout));
  const auto received = reader.take();
  ASSERT_EQ(received.size(), 1u);
  EXPECT_EQ(odonav::test::fields(received.front()), odonav::test::fields(sample));
}

TEST_F(DdsTopics, CallbackReaderGetsEverySampleInOrderAndTakeStaysEmpty) {
  const std::string topic_name = std::string(topics::kOdometer.name) + "/callback_test";
  std::mutex mutex;
  std::condition_variable arrived;
  std::vector<std::uint32_t> pulses;
  Reader<msg::Odometer> reader(*reader_side_, topic_name, topics::kOdometer.reader_profile,
                               [&](const msg::Odometer& m) {
                                 std::lock_guard<std::mutex> lock(mutex);
                                 pulses.push_back(m.pulses());
                                 arrived.notify_all();
                               });
  Writer<msg::Odometer> writer(*writer_side_, topic_name, topics::kOdometer.writer_profile);
  ASSERT_TRUE(writer.wait_for_matched(1, kTimeout));
  ASSERT_TRUE(reader.wait_for_matched(1, kTimeout));
  // 150 samples across the 32-bit wrap, within the depth of 200: reliable, nothing lost.
  std::vector<std::uint32_t> sent;
  msg::Odometer m = odonav::test::make_odometer();
  for (int i = 0; i < 150; ++i) {
    m.pulses(4294967295u - 74u + static_cast<std::uint32_t>(i));  // wraps past 4294967295 at i = 75
    sent.push_back(m.pulses());
    ASSERT_TRUE(writer.write(m));
  }
  EXPECT_TRUE(writer.wait_for_acknowledgments(kTimeout));
  std::unique_lock<std::mutex> lock(mutex);
  ASSERT_TRUE(arrived.wait_for(lock, kTimeout, [&] { return pulses.size() >= sent.size(); }))
      << pulses.size() << " of " << sent.size() << " received";
  EXPECT_EQ(pulses, sent);
  lock.unlock();
  EXPECT_TRUE(reader.take().empty());
}

TEST_F(DdsTopics, DeadlineCallbackFiresOnceWhenSilentAndOnceWhenDataReturns) {
  // The estimate profiles request a 1 s deadline. Fast DDS reports a miss every period; the
  // reader must turn that into two edges.
  const std::string topic_name = std::string(topics::kMisalignment.name) + "/deadline_test";
  std::mutex mutex;
  std::condition_variable changed;
  std::vector<std::pair<bool, std::string>> edges;  // (silent, vehicle_id of the last sample)
  Reader<msg::Misalignment> reader(
      *reader_side_, topic_name, topics::kMisalignment.reader_profile, [](const msg::Misalignment&) {},
      [&](const msg::Misalignment& last, bool silent) {
        std::lock_guard<std::mutex> lock(mutex);
        edges.emplace_back(silent, last.vehicle_id());
        changed.notify_all();
      });
  Writer<msg::Misalignment> writer(*writer_side_, topic_name, topics::kMisalignment.writer_profile);
  ASSERT_TRUE(writer.wait_for_matched(1, kTimeout));
  ASSERT_TRUE(reader.wait_for_matched(1, kTimeout));

  msg::Misalignment m = odonav::test::make_misalignment();
  for (int i = 0; i < 5; ++i) {  // 10 Hz for half a second: well within the deadline
    m.samples_used(static_cast<std::uint32_t>(i));
    ASSERT_TRUE(writer.write(m));
    std::this_thread::sleep_for(100ms);
  }
  {
    std::unique_lock<std::mutex> lock(mutex);
    ASSERT_TRUE(changed.wait_for(lock, kTimeout, [&] { return !edges.empty(); })) << "never went silent";
  }
  // Stay silent for more than three further deadline periods.
  std::this_thread::sleep_for(3500ms);
  eprosima::fastdds::dds::RequestedDeadlineMissedStatus status;
  reader.native().get_requested_deadline_missed_status(status);
  EXPECT_GE(status.total_count, 3) << "Fast DDS itself reports a miss every period";
  {
    std::lock_guard<std::mutex> lock(mutex);
    ASSERT_EQ(edges.size(), 1u) << "one event per silence, not one per period";
    EXPECT_TRUE(edges[0].first);
    EXPECT_EQ(edges[0].second, "vehicle-mis-7");
  }
  ASSERT_TRUE(writer.write(m));
  std::unique_lock<std::mutex> lock(mutex);
  ASSERT_TRUE(changed.wait_for(lock, kTimeout, [&] { return edges.size() >= 2; })) << "return not reported";
  EXPECT_FALSE(edges[1].first);
  EXPECT_EQ(edges[1].second, "vehicle-mis-7");
  EXPECT_EQ(edges.size(), 2u);
}

TEST_F(DdsTopics, HealthPublisherWritesAtMostOncePerPeriodOfTheCallersClock) {
  const std::string topic_name = std::string(topics::kHealth.name) + "/publisher_test";
  std::mutex mutex;
  std::condition_variable arrived;
  std::vector<msg::Health> received;
  Reader<msg::Health> reader(*reader_side_, topic_name, topics::kHealth.reader_profile, [&](const msg::Health& h) {
    std::lock_guard<std::mutex> lock(mutex);
    received.push_back(h);
    arrived.notify_all();
  });
  odonav::dds::HealthPublisher publisher(*writer_side_, "vehicle-03", "odonav-gateway", 1.0,
                                         topics::kHealthWriterProfile, topic_name);
  ASSERT_TRUE(publisher.writer().wait_for_matched(1, kTimeout));
  ASSERT_TRUE(reader.wait_for_matched(1, kTimeout));
  publisher.acknowledge(17, msg::COMMAND_RESULT_ACCEPTED, "K set");

  // The caller's clock (dataset seconds). At 1 Hz only 100.0, 101.0 and 102.5 are due.
  const std::vector<double> clock_s{100.0, 100.3, 100.999, 101.0, 101.2, 101.9, 102.5, 102.6};
  std::vector<double> written_s;
  for (double now_s : clock_s) {
    const double counter = now_s * 10.0;
    if (publisher.publish_if_due(now_s, msg::HEALTH_STATE_RUNNING, msg::HEALTH_LEVEL_WARN, "GNSS degraded",
                                 {{"epochs", counter}, {"bad_rows", 2.0}})) {
      written_s.push_back(now_s);
      // Keep-last-1 history: let each sample arrive before the next one replaces it.
      std::unique_lock<std::mutex> lock(mutex);
      ASSERT_TRUE(arrived.wait_for(lock, kTimeout, [&] { return received.size() == written_s.size(); }));
    }
  }
  EXPECT_EQ(written_s, (std::vector<double>{100.0, 101.0, 102.5}));
  std::lock_guard<std::mutex> lock(mutex);
  ASSERT_EQ(received.size(), 3u);
  for (std::size_t i = 0; i < received.size(); ++i) {
    const msg::Health& h = received[i];
    EXPECT_DOUBLE_EQ(odonav::dds::to_seconds(h.header().stamp()), written_s[i]);
    EXPECT_EQ(h.vehicle_id(), "vehicle-03");
    EXPECT_EQ(h.component(), "odonav-gateway");
    EXPECT_EQ(h.state(), msg::HEALTH_STATE_RUNNING);
    EXPECT_EQ(h.level(), msg::HEALTH_LEVEL_WARN);
    EXPECT_EQ(h.reason(), "GNSS degraded");
    ASSERT_EQ(h.counters().size(), 2u);
    EXPECT_EQ(h.counters()[0].name(), "epochs");
    EXPECT_DOUBLE_EQ(h.counters()[0].value(), written_s[i] * 10.0);
    EXPECT_EQ(h.counters()[1].name(), "bad_rows");
    EXPECT_EQ(h.last_command_id(), 17u);
    EXPECT_EQ(h.last_command_result(), msg::COMMAND_RESULT_ACCEPTED);
    EXPECT_EQ(h.last_command_detail(), "K set");
  }
}

// ---- errors ----

TEST_F(DdsTopics, UnknownWriterOrReaderProfileNamesProfileAndTopic) {
  const std::string w = error_of(
      [] { Writer<msg::Odometer> writer(*writer_side_, "rt/odonav/odometer/error_test", "no_such_writer_profile"); });
  EXPECT_NE(w.find("no data_writer QoS profile named 'no_such_writer_profile'"), std::string::npos) << w;
  EXPECT_NE(w.find("rt/odonav/odometer/error_test"), std::string::npos) << w;
  EXPECT_NE(w.find("qos.xml"), std::string::npos) << w;
  const std::string r = error_of(
      [] { Reader<msg::Odometer> reader(*reader_side_, "rt/odonav/odometer/error_test", "no_such_reader_profile"); });
  EXPECT_NE(r.find("no data_reader QoS profile named 'no_such_reader_profile'"), std::string::npos) << r;
  EXPECT_NE(r.find("rt/odonav/odometer/error_test"), std::string::npos) << r;
}

TEST_F(DdsTopics, TopicReusedWithAnotherTypeIsAClearError) {
  const std::string topic_name = "rt/odonav/type_clash_test";
  Writer<msg::Odometer> writer(*writer_side_, topic_name, topics::kSensorWriterProfile);
  const std::string e =
      error_of([&] { Writer<msg::GnssFix> other(*writer_side_, topic_name, topics::kSensorWriterProfile); });
  EXPECT_NE(e.find("'" + topic_name + "' already exists with type 'odonav::msg::dds_::Odometer_'"), std::string::npos)
      << e;
  EXPECT_NE(e.find("odonav::msg::dds_::GnssFix_"), std::string::npos) << e;
}

TEST(DdsParticipantErrors, MissingProfilesFileIsNamed) {
  ParticipantOptions options = loopback_options("missing-file");
  options.profiles_file = "/nonexistent/odonav/profiles.xml";
  const std::string e = error_of([&] { Participant p(options); });
  EXPECT_NE(e.find("cannot read the participant profiles file '/nonexistent/odonav/profiles.xml'"), std::string::npos)
      << e;
}

TEST(DdsParticipantErrors, MissingQosFileIsNamed) {
  ParticipantOptions options = loopback_options("missing-qos");
  options.qos_file = "/nonexistent/odonav/qos.xml";
  const std::string e = error_of([&] { Participant p(options); });
  EXPECT_NE(e.find("cannot read the QoS profiles file '/nonexistent/odonav/qos.xml'"), std::string::npos) << e;
}

TEST(DdsParticipantErrors, UnknownParticipantProfileNamesProfileAndFile) {
  ParticipantOptions options = loopback_options("unknown-profile");
  options.participant_profile = "no_such_participant_profile";
  const std::string e = error_of([&] { Participant p(options); });
  EXPECT_NE(e.find("no participant profile named 'no_such_participant_profile'"), std::string::npos) << e;
  EXPECT_NE(e.find(loopback_profile_file()), std::string::npos) << e;
}

TEST(DdsParticipantErrors, MalformedXmlIsRejectedWithItsPath) {
  const std::string path = std::string(ODONAV_BINARY_DIR) + "/odonav_topics_test_malformed.xml";
  std::ofstream(path) << "<dds><profiles><participant profile_name=\"broken\">\n";  // never closed
  ParticipantOptions options = loopback_options("malformed");
  options.profiles_file = path;
  options.participant_profile = "broken";
  const std::string e = error_of([&] { Participant p(options); });
  EXPECT_NE(e.find("Fast DDS rejected the participant profiles file '" + path + "'"), std::string::npos) << e;
  std::remove(path.c_str());
}

TEST(DdsParticipantErrors, DomainIdOutOfRangeIsNamed) {
  ParticipantOptions options = loopback_options("bad-domain");
  options.domain_id = 233;
  const std::string e = error_of([&] { Participant p(options); });
  EXPECT_NE(e.find("domain id 233 is outside 0..232"), std::string::npos) << e;
}

TEST(DdsParticipantErrors, NoFileAndNoEnvironmentVariableIsNamed) {
  const char* saved = std::getenv("FASTRTPS_DEFAULT_PROFILES_FILE");
  const std::string saved_value = saved != nullptr ? saved : "";
  unsetenv("FASTRTPS_DEFAULT_PROFILES_FILE");
  ParticipantOptions options = loopback_options("no-file");
  options.profiles_file.clear();
  const std::string e = error_of([&] { Participant p(options); });
  EXPECT_NE(e.find("FASTRTPS_DEFAULT_PROFILES_FILE is not set"), std::string::npos) << e;
  if (saved != nullptr) setenv("FASTRTPS_DEFAULT_PROFILES_FILE", saved_value.c_str(), 1);
}

TEST(DdsParticipant, EmptyProfilesFileFallsBackToTheEnvironmentAndQosBesideIt) {
  const char* saved = std::getenv("FASTRTPS_DEFAULT_PROFILES_FILE");
  const std::string saved_value = saved != nullptr ? saved : "";
  setenv("FASTRTPS_DEFAULT_PROFILES_FILE", loopback_profile_file().c_str(), 1);
  ParticipantOptions options = loopback_options("from-env");
  options.profiles_file.clear();
  {
    Participant p(options);
    EXPECT_EQ(p.profiles_file(), loopback_profile_file());
    EXPECT_EQ(p.qos_file(), std::string(ODONAV_SOURCE_DIR) + "/deploy/profiles/qos.xml");
    EXPECT_EQ(p.domain_id(), kDomain);
    EXPECT_EQ(p.native().get_qos().name().to_string(), "from-env");
  }
  if (saved != nullptr) {
    setenv("FASTRTPS_DEFAULT_PROFILES_FILE", saved_value.c_str(), 1);
  } else {
    unsetenv("FASTRTPS_DEFAULT_PROFILES_FILE");
  }
}
