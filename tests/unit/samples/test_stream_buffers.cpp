// Stream buffers: wrap-safe count interpolation, bracket completeness, step histories.
#include <gtest/gtest.h>

#include "odonav/stream_buffers.hpp"

using namespace odonav;

TEST(OdometerBuffer, InterpolatesCountLinearlyAcrossAWrap) {
  OdometerBuffer b(1.0);
  b.add({0.0, 4294967290u, 1});
  b.add({0.1, 4u, 1});  // +10 pulses through the wrap
  b.add({0.2, 24u, 1});
  EXPECT_DOUBLE_EQ(*b.count_at(0.0, 0.2), 0.0);
  EXPECT_DOUBLE_EQ(*b.count_at(0.05, 0.2), 5.0);
  EXPECT_DOUBLE_EQ(*b.count_at(0.1, 0.2), 10.0);
  EXPECT_DOUBLE_EQ(*b.count_at(0.175, 0.2), 25.0);
}

TEST(OdometerBuffer, BracketIsPendingUntilASampleAfterOrTheWatermarkExcludesOne) {
  OdometerBuffer b(0.5);
  EXPECT_EQ(b.state_at(1.0, 1.0), BracketState::kPending);
  b.add({0.9, 100u, 1});
  EXPECT_EQ(b.state_at(1.0, 1.2), BracketState::kPending);   // a sample in (1.0, 1.4] may still come
  EXPECT_EQ(b.state_at(1.0, 1.5), BracketState::kMissing);   // none can: the gap would exceed 0.5 s
  b.add({1.1, 120u, 1});
  EXPECT_EQ(b.state_at(1.0, 1.2), BracketState::kReady);
  EXPECT_DOUBLE_EQ(*b.count_at(1.0, 1.2), 10.0);
  b.add({2.0, 130u, 1});  // 0.9 s gap > 0.5 s: no interpolation across it
  EXPECT_EQ(b.state_at(1.5, 3.0), BracketState::kMissing);
  EXPECT_EQ(b.state_at(0.5, 3.0), BracketState::kMissing);  // before the first sample
}

TEST(OdometerBuffer, RejectsNonIncreasingTimeAndBadDirectionWithAClearMessage) {
  OdometerBuffer b;
  b.add({1.0, 0u, 1});
  try {
    b.add({1.0, 1u, 1});
    FAIL() << "expected StreamInputError";
  } catch (const StreamInputError& e) {
    EXPECT_NE(std::string(e.what()).find("odometer"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("does not increase"), std::string::npos);
  }
  EXPECT_THROW(b.add({2.0, 1u, 2}), StreamInputError);
  EXPECT_THROW(b.add({std::numeric_limits<double>::quiet_NaN(), 1u, 1}), StreamInputError);
}

TEST(OdometerBuffer, ReversingIsSeenOnlyInsideTheInterval) {
  OdometerBuffer b;
  b.add({0.0, 0u, -1});
  b.add({0.1, 0u, 1});
  b.add({0.2, 0u, 1});
  b.add({0.3, 0u, -1});
  EXPECT_FALSE(b.any_reversing(0.0, 0.2));
  EXPECT_TRUE(b.any_reversing(0.1, 0.25));  // the sample at 0.3 closes the interval ending at 0.25
  EXPECT_TRUE(b.any_reversing(0.2, 0.3));
}

TEST(AttitudeBuffer, InterpolatesHeadingOnTheShortArc) {
  AttitudeBuffer b(1.0);
  b.add({0.0, Attitude{deg_to_rad(359.0), 0.0, 0.0}, std::nullopt});
  b.add({1.0, Attitude{deg_to_rad(3.0), deg_to_rad(2.0), 0.0}, std::nullopt});
  const Attitude a = *b.attitude_at(0.25, 1.0);
  EXPECT_NEAR(rad_to_deg(a.heading_rad), 0.0, 1e-9);
  EXPECT_NEAR(rad_to_deg(a.pitch_rad), 0.5, 1e-12);
  EXPECT_THROW(b.add({2.0, Attitude{0.0, 2.0, 0.0}, std::nullopt}), StreamInputError);  // pitch > 90 deg
}

TEST(StepHistory, LatestAtOrBeforeAndStrictlyBefore) {
  StepHistory<double> h("k");
  h.add(1.0, 10.0);
  h.add(2.0, 20.0);
  EXPECT_FALSE(h.at_or_before(0.5).has_value());
  EXPECT_EQ(*h.at_or_before(2.0), 20.0);
  EXPECT_EQ(*h.before(2.0), 10.0);
  h.drop_before(2.0);
  EXPECT_EQ(*h.before(2.0), 10.0);  // still answers for t >= 2
  EXPECT_EQ(*h.at_or_before(5.0), 20.0);
  EXPECT_THROW(h.add(2.0, 1.0), StreamInputError);
}
