// EventTimeAligner: watermarks, maximum wait, absent inputs, late samples, resumption and paced
// (estimate) streams, all on a fake wall clock so every case is deterministic.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <vector>

#include "odonav/consumer_rules.hpp"
#include "odonav/event_time_aligner.hpp"

using namespace odonav;

namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();

/// An aligner (EventTimeAligner's arguments) with the dead reckoning's two sample streams,
/// odometer then GNSS: `auto [a, odo, gnss] = odometer_and_gnss(...)`.
struct OdometerAndGnss {
  OdometerAndGnss(double max_wait_s, double start_s, double in_flight_max_wait_s)
      : a(max_wait_s, start_s, in_flight_max_wait_s) {}
  EventTimeAligner a;
  EventTimeAligner::StreamId odo = a.add_stream("odometer");
  EventTimeAligner::StreamId gnss = a.add_stream("gnss");
};
OdometerAndGnss odometer_and_gnss(double max_wait_s, double start_s, double in_flight_max_wait_s = 0.0) {
  return OdometerAndGnss(max_wait_s, start_s, in_flight_max_wait_s);
}
}  // namespace

TEST(EventTimeAligner, WatermarkIsTheMinimumOverStreams) {
  auto [a, odo, gnss] = odometer_and_gnss(2.0, 0.0);
  EXPECT_EQ(a.on_sample(odo, 10.00, 0.0), SampleAdmission::kAccepted);
  EXPECT_EQ(a.on_sample(odo, 10.01, 0.0), SampleAdmission::kAccepted);
  // GNSS has said nothing: nothing can be processed.
  EXPECT_FALSE(a.advance(0.1).has_value());
  EXPECT_EQ(a.on_sample(gnss, 10.005, 0.1), SampleAdmission::kAccepted);
  ASSERT_TRUE(a.advance(0.1).has_value());
  EXPECT_EQ(a.processed_s(), 10.005);
  // No stream moved: no new watermark.
  EXPECT_FALSE(a.advance(0.2).has_value());
  a.on_sample(gnss, 10.2, 0.2);
  const auto w = a.advance(0.2);
  ASSERT_TRUE(w.has_value());
  EXPECT_EQ(*w, 10.01);  // now the odometer is the slower one
}

TEST(EventTimeAligner, SilentStreamBecomesAbsentOnlyAfterMaxWaitWhileOthersAreAhead) {
  auto [a, odo, gnss] = odometer_and_gnss(2.0, 100.0);
  a.on_sample(odo, 1.0, 100.0);
  a.on_sample(gnss, 1.0, 100.0);
  EXPECT_EQ(a.advance(100.0), std::optional<double>(1.0));
  // Both stop at 1.0: nobody is ahead, so nobody is absent however long the silence.
  EXPECT_FALSE(a.advance(200.0).has_value());
  EXPECT_FALSE(a.status(gnss, 200.0).absent);
  // The odometer goes on; GNSS stays silent. Silence counts from when the odometer got ahead.
  a.on_sample(odo, 2.0, 201.0);
  EXPECT_FALSE(a.advance(201.0).has_value());
  EXPECT_FALSE(a.advance(202.9).has_value());
  EXPECT_FALSE(a.status(gnss, 202.9).absent);
  const auto w = a.advance(203.1);
  ASSERT_TRUE(w.has_value());
  EXPECT_EQ(*w, 2.0);
  const auto st = a.status(gnss, 203.1);
  EXPECT_TRUE(st.absent);
  EXPECT_EQ(st.absent_events, 1u);
  EXPECT_NEAR(st.silent_for_s, 103.1, 1e-9);  // since its last sample at wall 100
  // Counted once, not once per call.
  a.on_sample(odo, 3.0, 204.0);
  EXPECT_EQ(a.advance(210.0), std::optional<double>(3.0));
  EXPECT_EQ(a.status(gnss, 210.0).absent_events, 1u);
}

TEST(EventTimeAligner, LateSamplesAreDroppedAndCountedThenTheStreamResumes) {
  auto [a, odo, gnss] = odometer_and_gnss(1.0, 0.0);
  a.on_sample(odo, 1.0, 0.0);
  a.on_sample(gnss, 1.0, 0.0);
  ASSERT_TRUE(a.advance(0.0));
  for (int i = 1; i <= 50; ++i) a.on_sample(odo, 1.0 + 0.1 * i, 0.0);  // odometer up to 6.0
  EXPECT_FALSE(a.advance(0.5).has_value());
  EXPECT_FALSE(a.advance(1.5).has_value());  // silent for exactly the maximum wait: not yet
  ASSERT_TRUE(a.advance(1.6).has_value());   // GNSS absent: processed up to the odometer
  EXPECT_DOUBLE_EQ(a.processed_s(), 6.0);
  // GNSS resumes with old data: late, dropped, counted; the stream is present again.
  EXPECT_EQ(a.on_sample(gnss, 2.0, 2.0), SampleAdmission::kLate);
  EXPECT_EQ(a.on_sample(gnss, 6.0, 2.0), SampleAdmission::kLate);  // at the processed watermark: late too
  EXPECT_FALSE(a.status(gnss, 2.0).absent);
  // The odometer moves on but the resumed GNSS holds the watermark back until it passes 6.0.
  a.on_sample(odo, 7.0, 2.0);
  EXPECT_FALSE(a.advance(2.0).has_value());
  EXPECT_EQ(a.on_sample(gnss, 6.5, 2.1), SampleAdmission::kAccepted);
  EXPECT_EQ(a.advance(2.1), std::optional<double>(6.5));
  const auto st = a.status(gnss, 2.1);
  EXPECT_EQ(st.late, 2u);
  EXPECT_EQ(st.accepted, 2u);  // 1.0 and 6.5
  EXPECT_EQ(st.absent_events, 1u);
}

TEST(EventTimeAligner, BackwardsAndRepeatedStampsAreNotAccepted) {
  EventTimeAligner a(2.0, 0.0);
  const auto k = a.add_stream("scale_factor");
  EXPECT_EQ(a.on_sample(k, 5.0, 0.0), SampleAdmission::kAccepted);
  EXPECT_EQ(a.on_sample(k, 5.0, 0.5), SampleAdmission::kRepeated);  // a heartbeat
  EXPECT_EQ(a.on_sample(k, 4.0, 0.6), SampleAdmission::kBackwards);
  EXPECT_EQ(a.on_sample(k, std::nan(""), 0.7), SampleAdmission::kInvalid);
  EXPECT_EQ(a.on_sample(k, 5.1, 0.8), SampleAdmission::kAccepted);
  const auto st = a.status(k, 1.0);
  EXPECT_EQ(st.accepted, 2u);
  EXPECT_EQ(st.repeated, 1u);
  EXPECT_EQ(st.backwards, 1u);
  EXPECT_EQ(st.invalid, 1u);
  EXPECT_EQ(*st.last_t_s, 5.1);
  EXPECT_NEAR(st.silent_for_s, 0.2, 1e-12);
}

TEST(EventTimeAligner, HeartbeatsKeepAStreamAliveWhileItIsBehind) {
  EventTimeAligner a(2.0, 0.0);
  const auto odo = a.add_stream("odometer");
  const auto mis = a.add_stream("misalignment");
  a.on_sample(odo, 10.0, 0.0);
  a.on_sample(mis, 9.0, 0.0);
  EXPECT_EQ(a.advance(0.0), std::optional<double>(9.0));
  // The producer is alive (republishes its last estimate every second) but has nothing new yet.
  for (double now = 1.0; now <= 10.0; now += 1.0) {
    EXPECT_EQ(a.on_sample(mis, 9.0, now), SampleAdmission::kRepeated);
    EXPECT_FALSE(a.advance(now + 0.5).has_value());
  }
  EXPECT_FALSE(a.status(mis, 10.5).absent);
  // Once the heartbeats stop, it is absent after the maximum wait.
  EXPECT_FALSE(a.advance(11.9).has_value());
  EXPECT_EQ(a.advance(12.1), std::optional<double>(10.0));
  EXPECT_TRUE(a.status(mis, 12.1).absent);
}

TEST(EventTimeAligner, PacedStreamIsCompleteUpToTheNextPacingEpoch) {
  auto [a, odo, gnss] = odometer_and_gnss(2.0, 0.0);
  const auto k = a.add_paced_stream("scale_factor", gnss);
  for (int i = 0; i <= 35; ++i) a.on_sample(odo, 0.01 * i, 0.0);  // odometer to 0.35
  for (double g : {0.0, 0.1, 0.2, 0.3}) a.on_sample(gnss, g, 0.0);
  // No K yet: K can still come for the first GNSS epoch 0.0, so nothing at or after it is final.
  EXPECT_EQ(a.status(k, 0.0).watermark_s, std::nextafter(0.0, -kInf));
  const auto w0 = a.advance(0.0);
  ASSERT_TRUE(w0.has_value());
  EXPECT_LT(*w0, 0.0);
  // K for epoch 0.0 arrives: complete for every time before the next epoch 0.1.
  a.on_sample(k, 0.0, 0.1);
  const auto w = a.advance(0.1);
  ASSERT_TRUE(w.has_value());
  EXPECT_EQ(*w, std::nextafter(0.1, -kInf));
  EXPECT_LT(*w, 0.1);
  // K for 0.1 and 0.3 (0.2 lost on the way): complete up to GNSS's own watermark 0.3; the skipped
  // epoch is counted.
  a.on_sample(k, 0.1, 0.2);
  a.on_sample(k, 0.3, 0.2);
  EXPECT_EQ(a.status(k, 0.2).skipped_pacing_epochs, 1u);
  EXPECT_EQ(a.advance(0.2), std::optional<double>(0.3));
}

// The hold-off rule with the gateway's GNSS completeness: at odometer time t the consumer waits only
// for the estimates of the epochs <= t - hold-off, and an estimate later than that is a bounded,
// counted wait, never a different result.
TEST(EventTimeAligner, HoldOffStreamsLimitOnlyUpToTheirEpochPlusTheHoldOff) {
  const double d = 0.2;
  EventTimeAligner a(2.0, 0.0);
  const auto odo = a.add_stream("odometer");
  const auto gnss = a.add_stream("gnss", d);
  const auto k = a.add_paced_stream("scale_factor", gnss, d);
  for (double g : {0.0, 0.1, 0.2, 0.3}) a.on_sample(gnss, g, 0.0);
  for (double g : {0.0, 0.1}) a.on_sample(k, g, 0.0);
  for (int i = 0; i <= 35; ++i) a.on_sample(odo, 0.01 * i, 0.0);  // odometer to 0.35
  // K of 0.2 is not in: everything before 0.2 + d is final, the odometer (0.35) is what limits.
  EXPECT_EQ(a.status(k, 0.0).watermark_s, std::nextafter(estimate_applies_from_s(0.2, d), -kInf));
  EXPECT_DOUBLE_EQ(*a.advance(0.0), 0.35);
  EXPECT_EQ(a.status(k, 0.0).hold_off_waits, 0u);
  // The odometer runs on to 0.45; K of 0.2 is still missing: it holds the watermark (a wait, counted
  // once for the episode), and a K that arrives now is fed (0.2 + d > what was processed).
  for (int i = 36; i <= 45; ++i) a.on_sample(odo, 0.01 * i, 0.1);
  const auto w = a.advance(0.1);
  ASSERT_TRUE(w.has_value());
  EXPECT_LT(*w, estimate_applies_from_s(0.2, d));
  EXPECT_FALSE(a.advance(0.15).has_value());
  EXPECT_EQ(a.status(k, 0.15).hold_off_waits, 1u);
  EXPECT_EQ(a.on_sample(k, 0.2, 0.2), SampleAdmission::kAccepted);
  a.on_sample(k, 0.3, 0.2);
  EXPECT_DOUBLE_EQ(*a.advance(0.2), 0.45);
  EXPECT_EQ(a.status(k, 0.2).hold_off_waits, 1u);
  // GNSS itself (a reference with the same hold-off) is late only at or before processed - d.
  EXPECT_EQ(a.on_sample(gnss, 0.4, 0.2), SampleAdmission::kAccepted);
}

TEST(EventTimeAligner, DeclaredCompletenessLetsAPacedStreamCatchUpWithoutTheNextEpoch) {
  auto [a, odo, gnss] = odometer_and_gnss(2.0, 0.0);
  const auto k = a.add_paced_stream("scale_factor", gnss);
  a.on_sample(gnss, 1.0, 0.0);
  a.on_sample(k, 1.0, 0.0);
  for (int i = 0; i <= 9; ++i) a.on_sample(odo, 1.0 + 0.01 * i, 0.0);
  // Without a declaration GNSS (and K, caught up with it) are complete up to 1.0 only.
  EXPECT_DOUBLE_EQ(*a.advance(0.0), 1.0);
  // The gateway declares with the odometer of 1.09: every GNSS <= 1.09 published, the last at 1.0.
  a.declare_published(gnss, 1.09, 1.0);
  EXPECT_DOUBLE_EQ(a.status(gnss, 0.0).watermark_s, 1.09);
  EXPECT_DOUBLE_EQ(a.status(k, 0.0).watermark_s, 1.09);
  EXPECT_DOUBLE_EQ(*a.advance(0.0), 1.09);
  // A declaration naming a GNSS not received yet counts only once it is in (the earlier one stays).
  a.on_sample(odo, 1.2, 0.1);
  a.declare_published(gnss, 1.2, 1.1);
  EXPECT_DOUBLE_EQ(a.status(gnss, 0.1).watermark_s, 1.09);
  EXPECT_FALSE(a.advance(0.1).has_value());
  a.on_sample(gnss, 1.1, 0.1);
  // GNSS 1.1 is in, its K not: K is complete below 1.1.
  EXPECT_EQ(*a.advance(0.1), std::nextafter(1.1, -kInf));
  a.on_sample(k, 1.1, 0.1);
  EXPECT_DOUBLE_EQ(*a.advance(0.1), 1.2);
}

TEST(EventTimeAligner, AStreamWithDeclaredSamplesInFlightWaitsTheLongerInFlightWait) {
  // A restarted identification: the odometer's history arrives at once and declares GNSS published
  // up to t = 50 s, while GNSS's own history is slow to come.
  auto [a, odo, gnss] = odometer_and_gnss(2.0, 100.0, kInFlightMaxWait_s);
  a.on_sample(gnss, 20.0, 100.0);
  for (int i = 0; i <= 300; ++i) a.on_sample(odo, 20.0 + 0.1 * i, 100.0);
  a.declare_published(gnss, 50.0, 50.0);
  EXPECT_TRUE(a.status(gnss, 100.0).in_flight);
  a.advance(100.0);
  // Past max wait: still present, one in-flight wait counted, the watermark held at GNSS.
  EXPECT_FALSE(a.advance(103.0).has_value());
  EXPECT_FALSE(a.advance(120.0).has_value());
  auto st = a.status(gnss, 120.0);
  EXPECT_FALSE(st.absent);
  EXPECT_EQ(st.in_flight_waits, 1u);
  EXPECT_EQ(a.processed_s(), 20.0);
  // The history arrives 25 s later: nothing was late, everything is processed in order.
  for (int i = 1; i <= 300; ++i) EXPECT_EQ(a.on_sample(gnss, 20.0 + 0.1 * i, 125.0), SampleAdmission::kAccepted);
  EXPECT_FALSE(a.status(gnss, 125.0).in_flight);
  EXPECT_DOUBLE_EQ(*a.advance(125.0), 50.0);
  st = a.status(gnss, 125.0);
  EXPECT_EQ(st.late, 0u);
  EXPECT_EQ(st.absent_events, 0u);

  // Samples declared and never coming (their producer died): absent after the in-flight wait.
  a.on_sample(odo, 60.0, 130.0);
  a.declare_published(gnss, 60.0, 55.0);
  EXPECT_FALSE(a.advance(130.0).has_value());
  EXPECT_FALSE(a.advance(159.9).has_value());
  EXPECT_FALSE(a.status(gnss, 159.9).absent);
  EXPECT_DOUBLE_EQ(*a.advance(160.1), 60.0);
  st = a.status(gnss, 160.1);
  EXPECT_TRUE(st.absent);
  EXPECT_EQ(st.absent_events, 1u);
  EXPECT_EQ(st.in_flight_waits, 2u);

  // Without the longer wait (dead reckoning: fresh outputs first) the same stream is absent after
  // max wait, in flight or not.
  auto [fresh, fodo, fgnss] = odometer_and_gnss(2.0, 100.0);
  fresh.on_sample(fgnss, 20.0, 100.0);
  fresh.on_sample(fodo, 30.0, 100.0);
  fresh.declare_published(fgnss, 30.0, 30.0);
  fresh.advance(100.0);
  EXPECT_DOUBLE_EQ(*fresh.advance(102.1), 30.0);
  EXPECT_TRUE(fresh.status(fgnss, 102.1).absent);
  EXPECT_EQ(fresh.status(fgnss, 102.1).in_flight_waits, 0u);
}

TEST(EventTimeAligner, PacedStreamDoesNotHoldBackWhileItsPacingStreamIsAbsent) {
  auto [a, odo, gnss] = odometer_and_gnss(1.0, 0.0);
  const auto k = a.add_paced_stream("scale_factor", gnss);
  a.on_sample(gnss, 1.0, 0.0);
  a.on_sample(k, 1.0, 0.0);
  for (int i = 0; i <= 100; ++i) a.on_sample(odo, 1.0 + 0.1 * i, 0.0);  // odometer to 11.0
  EXPECT_EQ(a.advance(0.0), std::optional<double>(1.0));
  // GNSS outage without rows: GNSS goes silent, so does K (it has nothing to say). After the
  // maximum wait GNSS is absent and K, caught up with it, no longer limits: DR goes on.
  a.on_sample(k, 1.0, 0.9);  // heartbeat: K's producer is alive
  const auto w = a.advance(1.5);
  ASSERT_TRUE(w.has_value());
  EXPECT_DOUBLE_EQ(*w, 11.0);
  EXPECT_TRUE(a.status(gnss, 1.5).absent);
  EXPECT_FALSE(a.status(k, 1.5).absent);
  EXPECT_EQ(a.status(k, 1.5).watermark_s, kInf);
  EXPECT_EQ(a.status(k, 1.5).absent_events, 0u);
}

TEST(EventTimeAligner, PacedStreamThatNeverSpokeBecomesAbsentAndIsCounted) {
  // Dead reckoning without identification: the K stream never speaks.
  auto [a, odo, gnss] = odometer_and_gnss(2.0, 0.0);
  const auto k = a.add_paced_stream("scale_factor", gnss);
  for (int i = 0; i <= 90; ++i) {  // odometer and GNSS both end at 0.9
    a.on_sample(odo, 0.01 * i, 0.001 * i);
    if (i % 10 == 0) a.on_sample(gnss, 0.01 * i, 0.001 * i);
  }
  const auto w0 = a.advance(0.1);  // waits: K may come for GNSS epoch 0.0
  ASSERT_TRUE(w0.has_value());
  EXPECT_LT(*w0, 0.0);
  EXPECT_FALSE(a.advance(2.0).has_value());
  const auto w = a.advance(2.2);
  ASSERT_TRUE(w.has_value());
  EXPECT_DOUBLE_EQ(*w, 0.9);
  EXPECT_FALSE(a.status(gnss, 2.2).absent);  // nobody was ahead of GNSS
  EXPECT_TRUE(a.status(k, 2.2).absent);
  EXPECT_EQ(a.status(k, 2.2).absent_events, 1u);
}

TEST(EventTimeAligner, AnyInterleavingNeverProcessesBeyondWhatEveryStreamDelivered) {
  // Independent check of the contract the cores rely on: whenever a watermark w is returned, every
  // sample stamped <= w of every stream has already been delivered. Random interleavings and
  // delays (fixed seed), all producers alive (max wait longer than the run).
  std::mt19937 rng(20240604);
  for (int run = 0; run < 50; ++run) {
    EventTimeAligner a(1e6, 0.0);
    const auto odo = a.add_stream("odometer");
    const auto ins = a.add_stream("ins");
    const auto gnss = a.add_stream("gnss");
    const auto mis = a.add_paced_stream("misalignment", gnss);
    std::map<std::size_t, std::vector<double>> pending;
    for (int i = 1; i <= 400; ++i) pending[odo].push_back(0.01 * i);
    for (int i = 1; i <= 400; ++i) pending[ins].push_back(0.01 * i + 0.003);
    for (int i = 1; i <= 40; ++i) pending[gnss].push_back(0.1 * i);
    for (int i = 1; i <= 40; ++i) pending[mis].push_back(0.1 * i);  // one per GNSS epoch
    std::map<std::size_t, std::size_t> next;
    double now = 0.0;
    double last_w = -kInf;
    while (true) {
      std::vector<std::size_t> open;
      for (auto& [id, v] : pending)
        if (next[id] < v.size()) open.push_back(id);
      if (open.empty()) break;
      const std::size_t id = open[std::uniform_int_distribution<std::size_t>(0, open.size() - 1)(rng)];
      const std::size_t burst = std::uniform_int_distribution<std::size_t>(1, 8)(rng);
      for (std::size_t b = 0; b < burst && next[id] < pending[id].size(); ++b)
        ASSERT_EQ(a.on_sample(id, pending[id][next[id]++], now), SampleAdmission::kAccepted);
      now += 0.001;
      if (const auto w = a.advance(now)) {
        ASSERT_GT(*w, last_w);
        last_w = *w;
        for (auto& [sid, v] : pending)
          for (std::size_t j = next[sid]; j < v.size(); ++j) ASSERT_GT(v[j], *w) << "stream " << sid;
      }
    }
    EXPECT_DOUBLE_EQ(last_w, 4.0);  // everything delivered: up to the slowest stream's end
  }
}

TEST(EventTimeAligner, RejectsBadConfiguration) {
  EXPECT_THROW(EventTimeAligner(0.0, 0.0), std::invalid_argument);
  EXPECT_THROW(EventTimeAligner(std::nan(""), 0.0), std::invalid_argument);
  EXPECT_THROW(EventTimeAligner(1.0, kInf), std::invalid_argument);
  EXPECT_THROW(EventTimeAligner(2.0, 0.0, 1.0), std::invalid_argument);  // in-flight wait below max wait
  EXPECT_THROW(EventTimeAligner(2.0, 0.0, kInf), std::invalid_argument);
  EventTimeAligner a(1.0, 0.0);
  const auto gnss = a.add_stream("gnss");
  const auto k = a.add_paced_stream("k", gnss);
  EXPECT_THROW(a.add_paced_stream("k2", k), std::invalid_argument);   // paced by a paced stream
  EXPECT_THROW(a.add_paced_stream("k3", 17), std::invalid_argument);  // unknown pacing stream
  EXPECT_THROW(a.on_sample(17, 1.0, 0.0), std::out_of_range);
}
