// PeerTracker (odonav/peer_tracker.hpp): a matched writer silent for 2 s while another writer is
// heard is named; a pause of the whole flow is not a peer's fault; edges are reported once.
#include <gtest/gtest.h>

#include <stdexcept>

#include "odonav/peer_tracker.hpp"

namespace {

using odonav::PeerTracker;

TEST(PeerTracker, NamesTheWriterSilentForTwoSecondsWhileAnotherIsHeard) {
  PeerTracker t(2.0);
  t.matched("odometer", "w-odo", "odonav-gateway", 100.0);
  t.matched("scale_factor", "w-k", "odonav-identification", 100.0);
  // Both at 100 Hz / 10 Hz until t = 101; then only the identification is heard.
  for (double now = 100.0; now <= 101.0; now += 0.01) t.heard("w-odo", now);
  for (double now = 100.0; now <= 104.0; now += 0.1) t.heard("w-k", now);
  EXPECT_TRUE(t.silent(102.9).empty()) << "1.9 s is not yet silent";
  const auto s = t.silent(103.3);
  ASSERT_EQ(s.size(), 1u);
  EXPECT_EQ(s[0].stream, "odometer");
  EXPECT_EQ(s[0].peer, "odonav-gateway");
  EXPECT_NEAR(s[0].silent_s, 2.3, 0.011);
  EXPECT_EQ(t.reason(103.3).value_or(""), "no odometer from odonav-gateway for 2.3 s");
}

TEST(PeerTracker, AWriterMatchedButNeverHeardIsSilentFromItsMatch) {
  // The cut-off case: discovered, matched, and nothing ever arrives from it.
  PeerTracker t(2.0);
  t.matched("odometer", "w-odo", "odonav-gateway", 10.0);
  t.matched("scale_factor", "w-k", "odonav-identification", 10.5);
  for (double now = 10.0; now <= 13.0; now += 0.01) t.heard("w-odo", now);
  EXPECT_FALSE(t.reason(12.4).has_value());
  EXPECT_EQ(t.reason(12.6).value_or(""), "no scale_factor from odonav-identification for 2.1 s");
}

TEST(PeerTracker, APauseOfEverythingIsNotAPeersFault) {
  PeerTracker t(2.0);
  t.matched("odometer", "a", "odonav-gateway", 0.0);
  t.matched("gnss/fix", "b", "odonav-gateway", 0.0);
  t.heard("a", 5.0);
  t.heard("b", 5.0);
  EXPECT_TRUE(t.silent(20.0).empty());
  EXPECT_FALSE(t.reason(20.0).has_value());
}

TEST(PeerTracker, AnUnmatchedWriterIsForgottenAndTheLongestSilenceComesFirst) {
  PeerTracker t(2.0);
  t.matched("odometer", "a", "odonav-gateway", 0.0);
  t.matched("misalignment", "b", "odonav-calibration", 0.0);
  t.matched("scale_factor", "c", "odonav-identification", 0.0);
  t.heard("a", 1.0);
  t.heard("b", 3.0);
  for (double now = 0.0; now <= 8.0; now += 0.1) t.heard("c", now);
  auto s = t.silent(8.0);
  ASSERT_EQ(s.size(), 2u);
  EXPECT_EQ(s[0].peer, "odonav-gateway");      // 7 s
  EXPECT_EQ(s[1].peer, "odonav-calibration");  // 5 s
  EXPECT_EQ(t.reason(8.0).value_or(""), "no odometer from odonav-gateway for 7.0 s, and 1 more silent");
  t.unmatched("a");
  EXPECT_EQ(t.reason(8.0).value_or(""), "no misalignment from odonav-calibration for 5.0 s");
  EXPECT_EQ(t.matched_count(), 2u);
  t.heard("a", 8.0);  // a sample racing its unmatch: ignored
  EXPECT_EQ(t.matched_count(), 2u);
}

TEST(PeerTracker, EdgesAreReportedOncePerSilence) {
  PeerTracker t(2.0);
  t.matched("odometer", "a", "odonav-gateway", 0.0);
  t.matched("scale_factor", "c", "odonav-identification", 0.0);
  for (double now = 0.0; now <= 1.0; now += 0.1) t.heard("a", now);
  for (double now = 0.0; now <= 10.0; now += 0.1) {
    t.heard("c", now);
  }
  EXPECT_TRUE(t.edges(2.5).empty());
  auto e = t.edges(3.2);
  ASSERT_EQ(e.size(), 1u);
  EXPECT_TRUE(e[0].silent);
  EXPECT_EQ(e[0].who.peer, "odonav-gateway");
  EXPECT_TRUE(t.edges(5.0).empty()) << "still silent: no second edge";
  t.heard("a", 6.0);
  e = t.edges(6.0);
  ASSERT_EQ(e.size(), 1u);
  EXPECT_FALSE(e[0].silent);
  EXPECT_TRUE(t.edges(6.5).empty());
}

TEST(PeerTracker, StreamNamesDropTheOdonavTopicPrefix) {
  EXPECT_EQ(odonav::stream_name_of_topic("rt/odonav/gnss/fix"), "gnss/fix");
  EXPECT_EQ(odonav::stream_name_of_topic("rt/odonav/odometer"), "odometer");
  EXPECT_EQ(odonav::stream_name_of_topic("other/topic"), "other/topic");
  EXPECT_THROW(PeerTracker(0.0), std::invalid_argument);
}

}  // namespace
