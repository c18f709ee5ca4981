// GapDetector (odonav/gap_detector.hpp): holes in a periodic stream counted from the stamps.
#include <gtest/gtest.h>

#include <stdexcept>
#include <vector>

#include "odonav/gap_detector.hpp"

namespace {

using odonav::GapDetector;

TEST(GapDetector, AHoleOf522OutputsAt100HzIsCountedAndDescribed) {
  GapDetector g;  // learns 0.01 s
  for (int i = 0; i <= 4000; ++i) EXPECT_FALSE(g.offer(i * 0.01).has_value()) << i;
  // Outputs 4001..4522 (t = 40.01 .. 45.22 s) never arrive.
  const auto gap = g.offer(4523 * 0.01);
  ASSERT_TRUE(gap.has_value());
  EXPECT_EQ(gap->missed, 522u);
  EXPECT_NEAR(gap->first_missing_t_s, 40.01, 1e-9);
  EXPECT_NEAR(gap->last_missing_t_s, 45.22, 1e-9);
  EXPECT_EQ(odonav::describe_gap(*gap, "dead-reckoning"), "missed 522 dead-reckoning outputs t=40.010-45.220 s");
  for (int i = 4524; i < 5000; ++i) EXPECT_FALSE(g.offer(i * 0.01).has_value());
  EXPECT_EQ(g.missed(), 522u);
  EXPECT_EQ(g.gaps(), 1u);
}

TEST(GapDetector, JitterAndRepeatsAreNoGapsAndOneMissingSampleIs) {
  GapDetector g(0.01);
  EXPECT_FALSE(g.offer(0.0));
  EXPECT_FALSE(g.offer(0.0112));  // late by 12 % of a period
  EXPECT_FALSE(g.offer(0.0112));  // repeat
  EXPECT_FALSE(g.offer(0.005));   // backwards: ignored
  EXPECT_FALSE(g.offer(0.02));
  const auto one = g.offer(0.04);
  ASSERT_TRUE(one.has_value());
  EXPECT_EQ(one->missed, 1u);
  EXPECT_EQ(g.period_s().value_or(0), 0.01);
}

TEST(GapDetector, TheLearnedPeriodIsTheSmallestInterval) {
  GapDetector g;
  EXPECT_FALSE(g.period_s().has_value());
  g.offer(0.0);
  g.offer(0.1);  // 10 Hz stream so far
  EXPECT_NEAR(*g.period_s(), 0.1, 1e-12);
  EXPECT_FALSE(g.offer(0.2));
  const auto gap = g.offer(0.5);
  ASSERT_TRUE(gap);
  EXPECT_EQ(gap->missed, 2u);
  EXPECT_THROW(GapDetector(-1.0), std::invalid_argument);
}

// Estimate rows against GNSS epochs: 10 Hz epochs 0.0-30.0 s; the identification's rows of
// 10.1-15.0 s (50) never came, nor those after 28.0 s (20), and its first row is the epoch 0.1 s.
// Row stamps a few ns off the epochs (DDS integer nanoseconds) still match; a repeated row and a row
// at no epoch change nothing.
TEST(MissingEpochs, RunsOfGnssEpochsWithoutAnEstimateRow) {
  std::vector<double> epochs, rows;
  for (int i = 0; i <= 300; ++i) epochs.push_back(i * 0.1);
  for (int i = 1; i <= 280; ++i)
    if (i < 101 || i > 150) rows.push_back(i * 0.1 + (i % 2 ? 3e-9 : -3e-9));
  rows.push_back(5.0);     // a repeat (heartbeat)
  rows.push_back(12.05);   // at no epoch
  epochs.push_back(20.0);  // an epoch seen twice
  const auto runs = odonav::missing_epochs(epochs, rows);
  ASSERT_EQ(runs.size(), 3u);
  EXPECT_NEAR(runs[0].first_missing_t_s, 0.0, 1e-12);
  EXPECT_EQ(runs[0].missed, 1u);
  EXPECT_NEAR(runs[1].first_missing_t_s, 10.1, 1e-9);
  EXPECT_NEAR(runs[1].last_missing_t_s, 15.0, 1e-9);
  EXPECT_EQ(runs[1].missed, 50u);
  EXPECT_NEAR(runs[2].first_missing_t_s, 28.1, 1e-9);
  EXPECT_NEAR(runs[2].last_missing_t_s, 30.0, 1e-9);
  EXPECT_EQ(runs[2].missed, 20u);
  // Every epoch with its row: nothing missing.
  EXPECT_TRUE(odonav::missing_epochs(epochs, epochs).empty());
}

}  // namespace
