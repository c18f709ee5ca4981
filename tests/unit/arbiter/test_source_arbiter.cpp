// SourceArbiter on producer streams built here: 10 Hz epochs, a primary (priority 20) and a standby
// (priority 10) publishing the same epochs with their own values, arrivals interleaved in a seeded
// random order, heartbeats repeating the last stamp. Asserted on the delivered sequence itself:
// which source each delivered stamp came from, that every epoch is delivered exactly once and in
// order, and where the switches happen (in event time).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "odonav/source_arbiter.hpp"

namespace {

using odonav::KeyedSourceArbiter;
using odonav::SourceArbiter;
using odonav::SourceArbiterParams;

struct Estimate {
  std::string source;
  double t_s = 0.0;
};

constexpr const char* kPrimary = "identification";
constexpr const char* kStandby = "identification/standby";
constexpr std::uint32_t kPrimaryPriority = 20;
constexpr std::uint32_t kStandbyPriority = 10;

double epoch_s(int i) { return 100.0 + 0.1 * i; }

struct Arrival {
  std::string source;
  std::uint32_t priority;
  double t_s;
};

/// Epochs [first, last) of both sources; each epoch's two samples arrive in a random order, and each
/// source's samples stay in its own order (one reliable writer each). `primary_until` ends the
/// primary's samples (exclusive) and `primary_from` restarts them.
std::vector<Arrival> arrivals(int first, int last, int primary_until, int primary_from, unsigned seed,
                              bool heartbeats = false) {
  std::mt19937 rng(seed);
  std::vector<Arrival> out;
  for (int i = first; i < last; ++i) {
    std::vector<Arrival> epoch;
    if (i < primary_until || i >= primary_from) epoch.push_back({kPrimary, kPrimaryPriority, epoch_s(i)});
    epoch.push_back({kStandby, kStandbyPriority, epoch_s(i)});
    if (epoch.size() == 2 && rng() % 2) std::swap(epoch[0], epoch[1]);
    for (const auto& a : epoch) {
      out.push_back(a);
      if (heartbeats) out.push_back(a);  // the 100 ms heartbeat repeats the stamp
    }
  }
  return out;
}

std::vector<Estimate> run(SourceArbiter<Estimate>& arbiter, const std::vector<Arrival>& in) {
  std::vector<Estimate> delivered;
  for (const auto& a : in)
    for (auto& e : arbiter.offer(a.source, a.priority, a.t_s, Estimate{a.source, a.t_s})) delivered.push_back(e);
  return delivered;
}

/// Every epoch of [first, last) exactly once, in order.
void expect_every_epoch_once(const std::vector<Estimate>& d, int first, int last) {
  ASSERT_EQ(d.size(), static_cast<std::size_t>(last - first));
  for (int i = first; i < last; ++i) EXPECT_DOUBLE_EQ(d[i - first].t_s, epoch_s(i)) << "delivered #" << i - first;
}

TEST(SourceArbiter, OneSourceEachStampOnceHeartbeatsDropped) {
  SourceArbiter<Estimate> a;
  std::vector<Estimate> d;
  for (int i = 0; i < 50; ++i)
    for (int r = 0; r < 3; ++r)
      for (auto& e : a.offer(kPrimary, 0, epoch_s(i), {kPrimary, epoch_s(i)})) d.push_back(e);
  expect_every_epoch_once(d, 0, 50);
  EXPECT_EQ(a.counters().delivered, 50u);
  EXPECT_EQ(a.counters().repeated, 100u);
  EXPECT_EQ(a.counters().switches, 1u);
  ASSERT_EQ(a.switches().size(), 1u);
  EXPECT_EQ(a.switches()[0].reason, "first source");
  EXPECT_EQ(a.selected().value_or(""), kPrimary);
}

TEST(SourceArbiter, BothAliveThePrimaryIsFollowedOnceHeard) {
  for (unsigned seed = 1; seed <= 20; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    SourceArbiter<Estimate> a;
    const auto d = run(a, arrivals(0, 200, 1000, 1000, seed, true));
    expect_every_epoch_once(d, 0, 200);
    // The standby may speak first at the very start (one epoch); from the primary's first sample on,
    // the primary only.
    for (std::size_t i = 1; i < d.size(); ++i) EXPECT_EQ(d[i].source, kPrimary) << "epoch " << i;
    EXPECT_LE(a.counters().switches, 2u);
  }
}

TEST(SourceArbiter, PrimaryDiesStandbyContinuesFromTheNextStampAfterSilence) {
  constexpr int kDeath = 100;  // the primary's last epoch is 99 (t = 109.9 s)
  for (unsigned seed = 1; seed <= 20; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    SourceArbiter<Estimate> a;  // silence 0.3 s
    std::vector<Estimate> d;
    int switched_at_epoch = -1;
    const auto in = arrivals(0, 200, kDeath, 1000, seed, true);
    for (const auto& arr : in) {
      const auto out = a.offer(arr.source, arr.priority, arr.t_s, Estimate{arr.source, arr.t_s});
      if (switched_at_epoch < 0 && !out.empty() && out.back().source == kStandby && arr.t_s > epoch_s(50))
        switched_at_epoch = static_cast<int>(std::lround((arr.t_s - 100.0) / 0.1));
      d.insert(d.end(), out.begin(), out.end());
    }
    expect_every_epoch_once(d, 0, 200);
    for (int i = 1; i < 200; ++i) EXPECT_EQ(d[i].source, i < kDeath ? kPrimary : kStandby) << "epoch " << i;
    // Silence 0.3 s: the standby's epoch 103 is 0.4 s after the primary's last (99): switch there,
    // delivering 100..103 at once.
    EXPECT_EQ(switched_at_epoch, kDeath + 3);
    const auto& sw = a.switches().back();
    EXPECT_EQ(sw.from, kPrimary);
    EXPECT_EQ(sw.to, kStandby);
    EXPECT_NE(sw.reason.find("'identification' silent: its newest t=109.9 s"), std::string::npos) << sw.reason;
    EXPECT_NE(sw.reason.find("(silence 0.3 s)"), std::string::npos) << sw.reason;
  }
}

TEST(SourceArbiter, RestartedPrimaryTakesOverAgainWithoutRepeatsOrGaps) {
  // The primary dies after epoch 59, comes back at epoch 90 with its persisted last sample (epoch 59,
  // as TRANSIENT durability serves it) and then live epochs from 90: the standby covers 60..89, the
  // primary takes over again at 90.
  SourceArbiter<Estimate> a;
  auto in = arrivals(0, 60, 1000, 1000, 7);
  for (int i = 60; i < 90; ++i) in.push_back({kStandby, kStandbyPriority, epoch_s(i)});
  in.push_back({kPrimary, kPrimaryPriority, epoch_s(59)});
  for (int i = 90; i < 150; ++i) {
    in.push_back({kPrimary, kPrimaryPriority, epoch_s(i)});
    in.push_back({kStandby, kStandbyPriority, epoch_s(i)});
  }
  const auto d = run(a, in);
  expect_every_epoch_once(d, 0, 150);
  for (int i = 60; i < 150; ++i) EXPECT_EQ(d[i].source, i < 90 ? kStandby : kPrimary) << "epoch " << i;
  const auto& back = a.switches().back();
  EXPECT_EQ(back.to, kPrimary);
  EXPECT_DOUBLE_EQ(back.at_stamp_s, epoch_s(90));
  EXPECT_NE(back.reason.find("priority 20) is live and outranks 'identification/standby' (priority 10)"),
            std::string::npos)
      << back.reason;
}

TEST(SourceArbiter, AnEpochTheSelectedSourceSkippedIsFilledFromAnother) {
  // The primary misses epochs 90 and 91 (a restart shorter than the silence, without catching up):
  // the standby's copies, held, fill them when the primary's epoch 92 arrives. Nothing skipped,
  // nothing twice, no switch.
  SourceArbiter<Estimate> a;
  std::vector<Arrival> in;
  for (int i = 0; i < 90; ++i) {
    in.push_back({kPrimary, kPrimaryPriority, epoch_s(i)});
    in.push_back({kStandby, kStandbyPriority, epoch_s(i)});
  }
  for (int i = 90; i < 92; ++i) in.push_back({kStandby, kStandbyPriority, epoch_s(i)});
  for (int i = 92; i < 120; ++i) {
    in.push_back({kPrimary, kPrimaryPriority, epoch_s(i)});
    in.push_back({kStandby, kStandbyPriority, epoch_s(i)});
  }
  const auto d = run(a, in);
  expect_every_epoch_once(d, 0, 120);
  for (int i = 0; i < 120; ++i) EXPECT_EQ(d[i].source, i == 90 || i == 91 ? kStandby : kPrimary) << "epoch " << i;
  EXPECT_EQ(a.counters().filled, 2u);
  EXPECT_EQ(a.counters().switches, 1u);
}

TEST(SourceArbiter, APrimaryLaggingLessThanTheSilenceKeepsTheSelection) {
  // The standby runs one epoch ahead of the primary all along (two, 0.2 s, just before each primary
  // sample): below the 0.3 s silence.
  SourceArbiter<Estimate> a;
  std::vector<Estimate> d;
  for (int i = 0; i < 100; ++i) {
    for (auto& e : a.offer(kStandby, kStandbyPriority, epoch_s(i + 1), {kStandby, epoch_s(i + 1)})) d.push_back(e);
    for (auto& e : a.offer(kPrimary, kPrimaryPriority, epoch_s(i), {kPrimary, epoch_s(i)})) d.push_back(e);
  }
  // Start: the standby alone delivers epoch 1; the primary's 0 is then superseded, and from epoch 2
  // on the primary is followed although the standby is always ahead.
  ASSERT_GE(d.size(), 2u);
  EXPECT_EQ(d[0].source, kStandby);
  for (std::size_t i = 1; i < d.size(); ++i) {
    EXPECT_EQ(d[i].source, kPrimary);
    EXPECT_DOUBLE_EQ(d[i].t_s, epoch_s(static_cast<int>(i) + 1));
  }
  EXPECT_EQ(a.counters().switches, 2u);
}

TEST(SourceArbiter, EqualPrioritiesKeepTheSelectionThenTheSmallerName) {
  SourceArbiter<Estimate> a;
  a.offer("b", 5, 1.0, {"b", 1.0});
  a.offer("a", 5, 1.1, {"a", 1.1});  // a is live, equal priority: b stays
  EXPECT_EQ(a.selected().value_or(""), "b");
  const auto d = a.offer("b", 5, 1.1, {"b", 1.1});
  ASSERT_EQ(d.size(), 1u);
  EXPECT_EQ(d[0].source, "b");
}

TEST(SourceArbiter, HeldSamplesAreBoundedAndNonFiniteStampsDropped) {
  SourceArbiterParams p;
  p.max_pending_per_source = 5;
  p.silence_s = 1e9;  // the primary stays live: the standby's samples are only held
  SourceArbiter<Estimate> a(p);
  a.offer(kPrimary, kPrimaryPriority, epoch_s(0), {kPrimary, epoch_s(0)});
  for (int i = 1; i < 20; ++i) a.offer(kStandby, kStandbyPriority, epoch_s(i), {kStandby, epoch_s(i)});
  EXPECT_EQ(a.counters().pending_overflow, 14u);
  EXPECT_TRUE(a.offer(kPrimary, kPrimaryPriority, std::numeric_limits<double>::quiet_NaN(), {}).empty());
  EXPECT_EQ(a.counters().not_finite, 1u);
  // The primary's next epoch 1: stamps 15..19 of the standby are still held, after it.
  const auto d = a.offer(kPrimary, kPrimaryPriority, epoch_s(1), {kPrimary, epoch_s(1)});
  ASSERT_EQ(d.size(), 1u);
  EXPECT_EQ(d[0].source, kPrimary);
}

TEST(KeyedSourceArbiter, VehiclesAreArbitratedApart) {
  KeyedSourceArbiter<Estimate> a;
  EXPECT_EQ(a.offer("v1", kPrimary, 20, 1.0, {kPrimary, 1.0}).size(), 1u);
  EXPECT_EQ(a.offer("v2", kStandby, 10, 1.0, {kStandby, 1.0}).size(), 1u);  // same stamp, other vehicle
  ASSERT_NE(a.find("v2"), nullptr);
  EXPECT_EQ(a.find("v2")->selected().value_or(""), kStandby);
  EXPECT_EQ(a.find("v3"), nullptr);
}

}  // namespace
