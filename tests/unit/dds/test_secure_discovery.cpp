// The secure-discovery policies of the DDS layer without a participant (secure_discovery.hpp):
// when a handshake set-up may start (SetupSpacing), and the log budget of refused participants.
#include <gtest/gtest.h>

#include <chrono>

#include "odonav/dds/secure_discovery.hpp"

using namespace std::chrono_literals;
using odonav::dds::LogBudget;
using odonav::dds::SetupSpacing;
using Clock = std::chrono::steady_clock;

namespace {
const Clock::time_point t0 = Clock::time_point{} + 1000s;
constexpr SetupSpacing::ThreadKey kUnicast = 11, kMulticast = 22, kShm = 33;
}  // namespace

TEST(SetupSpacing, FirstSetupAndSetupsOnTheSameThreadNeverWait) {
  SetupSpacing s(100ms);
  // A flood arriving on one socket: 200 discoveries 1 ms apart, one receive thread.
  for (int i = 0; i < 200; ++i) {
    const auto now = t0 + i * 1ms;
    EXPECT_EQ(s.admit(kUnicast, now), now) << i;
  }
  EXPECT_EQ(s.admitted(), 200u);
  EXPECT_EQ(s.delayed(), 0u);
  EXPECT_EQ(s.waited(), Clock::duration::zero());
}

TEST(SetupSpacing, ASetupOnAnotherThreadWaitsUntilThePreviousIsSpacingOld) {
  SetupSpacing s(100ms);
  EXPECT_EQ(s.admit(kUnicast, t0), t0);
  // 30 ms later on the multicast thread: the unicast thread's set-up may still run.
  EXPECT_EQ(s.admit(kMulticast, t0 + 30ms), t0 + 100ms);
  // The unicast thread again, 10 ms later: it must wait for the multicast one (handed over at
  // t0 + 100 ms), not for its own.
  EXPECT_EQ(s.admit(kUnicast, t0 + 40ms), t0 + 200ms);
  // The same thread once more, after its granted start: its own set-up is done, no wait.
  EXPECT_EQ(s.admit(kUnicast, t0 + 201ms), t0 + 201ms);
  EXPECT_EQ(s.delayed(), 2u);
  EXPECT_EQ(s.waited(), 70ms + 160ms);
}

TEST(SetupSpacing, ASetupOnAnotherThreadLongAfterThePreviousDoesNotWait) {
  SetupSpacing s(100ms);
  s.admit(kUnicast, t0);
  EXPECT_EQ(s.admit(kShm, t0 + 100ms), t0 + 100ms);
  EXPECT_EQ(s.admit(kMulticast, t0 + 500ms), t0 + 500ms);
  EXPECT_EQ(s.delayed(), 0u);
}

TEST(SetupSpacing, ThreeThreadsAreSerializedPairwise) {
  // Every set-up handed to a thread starts at least `spacing` after the latest one handed to
  // another thread: three threads discovering at the same instant end up 100 ms apart.
  SetupSpacing s(100ms);
  EXPECT_EQ(s.admit(kUnicast, t0), t0);
  EXPECT_EQ(s.admit(kMulticast, t0), t0 + 100ms);
  EXPECT_EQ(s.admit(kShm, t0), t0 + 200ms);
  EXPECT_EQ(s.admit(kUnicast, t0 + 1ms), t0 + 300ms);
  EXPECT_EQ(s.waited(), 100ms + 200ms + 299ms);
}

TEST(LogBudget, BurstPerWindowThenCountsWhatItLeftOut) {
  LogBudget b(5, 10s);
  // 200 refusals within 2 s: the first five are logged, the rest counted.
  int logged = 0;
  for (int i = 0; i < 200; ++i) {
    const auto g = b.take(t0 + i * 10ms);
    if (g.log) {
      ++logged;
      EXPECT_EQ(g.left_out, 0u);
    }
  }
  EXPECT_EQ(logged, 5);
  EXPECT_EQ(b.left_out(), 195u);
  // Still inside the window: nothing more.
  EXPECT_FALSE(b.take(t0 + 9s).log);
  EXPECT_EQ(b.left_out(), 196u);
  // The next window: the first line says how many were left out before it.
  const auto g = b.take(t0 + 10s);
  EXPECT_TRUE(g.log);
  EXPECT_EQ(g.left_out, 196u);
  EXPECT_EQ(b.left_out(), 0u);
  const auto g2 = b.take(t0 + 10s + 1ms);
  EXPECT_TRUE(g2.log);
  EXPECT_EQ(g2.left_out, 0u);
}

TEST(LogBudget, ZeroBurstLogsNothingAndCountsEverything) {
  LogBudget b(0, 1s);
  for (int i = 0; i < 3; ++i) EXPECT_FALSE(b.take(t0 + i * 1s).log);
  EXPECT_EQ(b.left_out(), 3u);
}
