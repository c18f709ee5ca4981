// The DDS layer's participant event log (odonav/dds/participant.hpp): what it logs about other
// participants, that a refused participant is warned about once, that with DDS Security the
// set-up of two participants discovered together on two receive threads is spaced (the Fast DDS
// 2.9 race it works around is described there), and that a flood of participants without
// credentials is neither held nor logged one by one. The callbacks are driven directly with the
// data Fast DDS passes.
#include <gtest/gtest.h>

#include <fastdds/rtps/attributes/RTPSParticipantAllocationAttributes.hpp>
#include <fastdds/rtps/builtin/data/ParticipantProxyData.h>
#include <fastdds/rtps/participant/ParticipantDiscoveryInfo.h>
#include <spdlog/sinks/ringbuffer_sink.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <cstdlib>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "odonav/dds/participant.hpp"

namespace {

using eprosima::fastrtps::rtps::ParticipantAuthenticationInfo;
using eprosima::fastrtps::rtps::ParticipantDiscoveryInfo;
using eprosima::fastrtps::rtps::ParticipantProxyData;
using eprosima::fastrtps::rtps::RTPSParticipantAllocationAttributes;
using odonav::dds::detail::ParticipantEventLog;

/// Captures what the layer logs (debug and above) while alive.
class LogCapture {
 public:
  LogCapture() : sink_(std::make_shared<spdlog::sinks::ringbuffer_sink_mt>(100)), previous_(spdlog::default_logger()) {
    auto logger = std::make_shared<spdlog::logger>("capture", sink_);
    logger->set_level(spdlog::level::debug);
    logger->set_pattern("%l %v");
    spdlog::set_default_logger(logger);
  }
  ~LogCapture() { spdlog::set_default_logger(previous_); }
  /// The formatted lines, without their end of line.
  std::vector<std::string> lines() const {
    std::vector<std::string> out = sink_->last_formatted();
    for (auto& l : out)
      while (!l.empty() && (l.back() == '\n' || l.back() == '\r')) l.pop_back();
    return out;
  }
  int count(const std::string& text) const {
    int n = 0;
    for (const auto& l : lines()) n += l.find(text) != std::string::npos ? 1 : 0;
    return n;
  }

 private:
  std::shared_ptr<spdlog::sinks::ringbuffer_sink_mt> sink_;
  std::shared_ptr<spdlog::logger> previous_;
};

/// A remote participant as discovery reports it: with DDS Security credentials (the identity
/// token class a Fast DDS PKI-DH participant announces) or without (a participant without DDS
/// Security, which Fast DDS refuses before any handshake set-up).
struct Remote {
  explicit Remote(const std::string& name, unsigned char id, bool credentials = true)
      : data(RTPSParticipantAllocationAttributes()) {
    data.m_participantName = name;
    for (auto& b : data.m_guid.guidPrefix.value) b = id;
    if (credentials) data.identity_token_.class_id("DDS:Auth:PKI-DH:1.0");
  }
  Remote(const std::string& name, unsigned id, bool credentials)
      : Remote(name, static_cast<unsigned char>(0), credentials) {
    for (int i = 0; i < 4; ++i) data.m_guid.guidPrefix.value[8 + i] = static_cast<unsigned char>(id >> (8 * i));
  }
  ParticipantProxyData data;
};

void discover(ParticipantEventLog& log, const Remote& r, ParticipantDiscoveryInfo::DISCOVERY_STATUS status) {
  ParticipantDiscoveryInfo info(r.data);
  info.status = status;
  log.on_participant_discovery(nullptr, std::move(info));
}

void authenticate(ParticipantEventLog& log, const Remote& r,
                  ParticipantAuthenticationInfo::AUTHENTICATION_STATUS status) {
  ParticipantAuthenticationInfo info;
  info.status = status;
  info.guid = r.data.m_guid;
  log.onParticipantAuthentication(nullptr, std::move(info));
}

TEST(ParticipantEvents, DiscoveryLeavingAndLossAreLoggedWithNameAndGuid) {
  LogCapture capture;
  ParticipantEventLog log("odonav-recorder", false);
  const Remote dr("odonav-dead-reckoning", 0x0a);
  discover(log, dr, ParticipantDiscoveryInfo::DISCOVERED_PARTICIPANT);
  discover(log, dr, ParticipantDiscoveryInfo::DROPPED_PARTICIPANT);
  discover(log, dr, ParticipantDiscoveryInfo::REMOVED_PARTICIPANT);
  const auto lines = capture.lines();
  ASSERT_EQ(lines.size(), 3u);
  EXPECT_EQ(lines[0],
            "info odonav::dds: odonav-recorder discovered participant 'odonav-dead-reckoning' "
            "(0a.0a.0a.0a.0a.0a.0a.0a.0a.0a.0a.0a)");
  EXPECT_EQ(lines[1].rfind("warning odonav::dds: odonav-recorder: participant 'odonav-dead-reckoning' "
                           "(0a.0a.0a.0a.0a.0a.0a.0a.0a.0a.0a.0a) lost: its lease expired",
                           0),
            0u)
      << lines[1];
  EXPECT_EQ(lines[2],
            "info odonav::dds: odonav-recorder: participant 'odonav-dead-reckoning' "
            "(0a.0a.0a.0a.0a.0a.0a.0a.0a.0a.0a.0a) left");
}

TEST(ParticipantEvents, ARefusedParticipantIsWarnedAboutOnceUntilItLeaves) {
  LogCapture capture;
  ParticipantEventLog log("odonav-dead-reckoning", true);
  const Remote intruder("odonav-identification", 0x66);
  const Remote legit("odonav-calibration", 0x22);
  for (int i = 0; i < 5; ++i) authenticate(log, intruder, ParticipantAuthenticationInfo::UNAUTHORIZED_PARTICIPANT);
  authenticate(log, legit, ParticipantAuthenticationInfo::AUTHORIZED_PARTICIPANT);
  EXPECT_EQ(capture.count("warning odonav::dds: odonav-dead-reckoning: participant 66.66.66.66.66.66.66.66.66.66.66.66 "
                          "failed DDS Security authentication"),
            1);
  EXPECT_EQ(capture.count("debug odonav::dds: odonav-dead-reckoning: participant 66.66.66.66.66.66.66.66.66.66.66.66 "
                          "refused again (5 times)"),
            1);
  EXPECT_EQ(capture.count("info odonav::dds: odonav-dead-reckoning authenticated participant "
                          "22.22.22.22.22.22.22.22.22.22.22.22"),
            1);
  // Once it has left, a new attempt under the same GUID is news again.
  discover(log, intruder, ParticipantDiscoveryInfo::REMOVED_PARTICIPANT);
  authenticate(log, intruder, ParticipantAuthenticationInfo::UNAUTHORIZED_PARTICIPANT);
  EXPECT_EQ(capture.count("failed DDS Security authentication"), 2);
}

TEST(ParticipantEvents, RefusedAndIncompleteHandshakesAreListedUntilTheParticipantLeaves) {
  LogCapture capture;  // keeps the test's output clean
  const std::chrono::seconds now{0};
  ParticipantEventLog log("odonav-recorder", true);
  const Remote dr("odonav-dead-reckoning", 0x0b), cal("odonav-calibration", 0x0c), rogue("odonav-rogue", 0x0d),
      gone("odonav-gateway", 0x0e);
  for (const Remote* r : {&dr, &cal, &rogue, &gone})
    discover(log, *r, ParticipantDiscoveryInfo::DISCOVERED_PARTICIPANT);
  authenticate(log, dr, ParticipantAuthenticationInfo::AUTHORIZED_PARTICIPANT);
  authenticate(log, rogue, ParticipantAuthenticationInfo::UNAUTHORIZED_PARTICIPANT);
  discover(log, gone, ParticipantDiscoveryInfo::DROPPED_PARTICIPANT);
  // Discovered first, the calibration (still pending) comes before the rogue (refused).
  auto strangers = log.unauthenticated(now);
  ASSERT_EQ(strangers.size(), 2u);
  EXPECT_EQ(strangers[0].name, "odonav-calibration");
  EXPECT_EQ(strangers[0].guid, "0c.0c.0c.0c.0c.0c.0c.0c.0c.0c.0c.0c");
  EXPECT_FALSE(strangers[0].refused);
  EXPECT_EQ(strangers[1].name, "odonav-rogue");
  EXPECT_TRUE(strangers[1].refused);
  EXPECT_GE(strangers[0].age_s, strangers[1].age_s);
  // A pending handshake counts only once it is old enough (discovered well under an hour ago);
  // a refusal at once.
  strangers = log.unauthenticated(std::chrono::hours(1));
  ASSERT_EQ(strangers.size(), 1u);
  EXPECT_EQ(strangers[0].name, "odonav-rogue");
  // The handshake completes; the rogue leaves.
  authenticate(log, cal, ParticipantAuthenticationInfo::AUTHORIZED_PARTICIPANT);
  discover(log, rogue, ParticipantDiscoveryInfo::REMOVED_PARTICIPANT);
  EXPECT_TRUE(log.unauthenticated(now).empty());

  // Without DDS Security nothing is listed: there is no handshake.
  ParticipantEventLog plain("odonav-recorder", false);
  discover(plain, cal, ParticipantDiscoveryInfo::DISCOVERED_PARTICIPANT);
  EXPECT_TRUE(plain.unauthenticated(now).empty());
}

TEST(ParticipantEvents, SecureDiscoveriesOnOneThreadAreNotHeldOnTwoThreadsTheyAreSpaced) {
  using Clock = std::chrono::steady_clock;
  LogCapture capture;
  const auto spacing = ParticipantEventLog::kSecureDiscoverySpacing;
  ParticipantEventLog secure("odonav-calibration", true);
  // One receive thread: the set-up of "a" is done when the thread delivers "b".
  discover(secure, Remote("a", 1), ParticipantDiscoveryInfo::DISCOVERED_PARTICIPANT);
  discover(secure, Remote("b", 2), ParticipantDiscoveryInfo::DISCOVERED_PARTICIPANT);
  auto c = secure.counts();
  EXPECT_EQ(c.setups_spaced, 2u);
  EXPECT_EQ(c.setups_delayed, 0u);
  // Another thread right after: held until the spacing after "b" (a lower bound only: sleep_until
  // never wakes early, so a slow machine cannot make this fail).
  const auto start = Clock::now();
  std::thread other([&] { discover(secure, Remote("c", 3), ParticipantDiscoveryInfo::DISCOVERED_PARTICIPANT); });
  other.join();
  const auto elapsed = Clock::now() - start;
  c = secure.counts();
  EXPECT_EQ(c.setups_spaced, 3u);
  // Held back, unless the machine stalled for the whole spacing before the thread ran.
  if (c.setups_delayed == 0u) {
    EXPECT_GE(elapsed, spacing);
  }
  EXPECT_EQ(c.discovered, 3u);
  EXPECT_EQ(c.without_credentials, 0u);
}

TEST(ParticipantEvents, AFloodWithoutCredentialsIsNeitherHeldNorLoggedPerParticipant) {
  LogCapture capture;
  std::vector<Remote> flood;
  for (unsigned i = 0; i < 200; ++i) flood.emplace_back("odonav-flood-" + std::to_string(i), 1000u + i, false);
  {
    ParticipantEventLog secure("odonav-recorder", true);
    const Remote peer("odonav-gateway", 0x21);
    discover(secure, peer, ParticipantDiscoveryInfo::DISCOVERED_PARTICIPANT);
    // As Fast DDS 2.9 does for each: the discovery, then at once the refusal (no identity token).
    // Every other one from a second thread: not held either, whatever thread it comes on.
    for (std::size_t i = 0; i < flood.size(); ++i) {
      const auto one = [&] {
        discover(secure, flood[i], ParticipantDiscoveryInfo::DISCOVERED_PARTICIPANT);
        authenticate(secure, flood[i], ParticipantAuthenticationInfo::UNAUTHORIZED_PARTICIPANT);
      };
      if (i % 2 == 0) {
        one();
      } else {
        std::thread t(one);
        t.join();
      }
    }
    authenticate(secure, peer, ParticipantAuthenticationInfo::AUTHORIZED_PARTICIPANT);
    const auto c = secure.counts();
    EXPECT_EQ(c.discovered, 201u);
    EXPECT_EQ(c.without_credentials, 200u);
    EXPECT_EQ(c.refused, 200u);
    EXPECT_EQ(c.authenticated, 1u);
    EXPECT_EQ(c.setups_spaced, 1u);  // the legitimate peer only
    EXPECT_EQ(c.setups_delayed, 0u);
    // Health lists every refused one (it shows the first and the count).
    EXPECT_EQ(secure.unauthenticated(std::chrono::hours(1)).size(), 200u);
    // A burst of lines, not one per participant, and the refusal callbacks add none.
    EXPECT_EQ(capture.count("without DDS Security credentials: refused"),
              static_cast<int>(ParticipantEventLog::kStrangerLogBurst));
    EXPECT_EQ(capture.count("failed DDS Security authentication"), 0);
    EXPECT_EQ(capture.count("discovered participant 'odonav-gateway'"), 1);
    // The flood ends: their leases expire. No warning (they were never ours), a few lines only;
    // the legitimate peer's loss is still a warning.
    for (const auto& f : flood) discover(secure, f, ParticipantDiscoveryInfo::DROPPED_PARTICIPANT);
    EXPECT_EQ(capture.count("lost: its lease expired"), 0);
    EXPECT_EQ(capture.count("gone (lease expired)"), static_cast<int>(ParticipantEventLog::kStrangerLogBurst));
    EXPECT_TRUE(secure.unauthenticated(std::chrono::hours(1)).empty());
    discover(secure, peer, ParticipantDiscoveryInfo::DROPPED_PARTICIPANT);
    EXPECT_EQ(capture.count("warning odonav::dds: odonav-recorder: participant 'odonav-gateway' "
                            "(21.21.21.21.21.21.21.21.21.21.21.21) lost: its lease expired"),
              1);
  }
  // Its life in one line when it goes.
  EXPECT_EQ(capture.count("DDS Security summary: 201 participants discovered, 200 without credentials, 200 refused, "
                          "1 authenticated; 1 handshake set-ups spaced, 0 held back"),
            1);
}

TEST(ParticipantEvents, AnUnknownFastDdsLogLevelIsRefusedNamingTheVariable) {
  ::setenv(odonav::dds::kFastDdsLogEnv, "loud", 1);
  odonav::dds::ParticipantOptions options;
  options.profiles_file = std::string(ODONAV_SOURCE_DIR) + "/deploy/profiles/loopback.xml";
  options.domain_id = 10;
  try {
    odonav::dds::Participant participant(options);
    ADD_FAILURE() << "ODONAV_FASTDDS_LOG=loud was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("ODONAV_FASTDDS_LOG='loud' is not one of error, warning, info"),
              std::string::npos)
        << e.what();
  }
  ::unsetenv(odonav::dds::kFastDdsLogEnv);
}

}  // namespace
