// Stream buffers: wrap-safe count interpolation, bracket completeness, step histories.
#include <gtest/gtest.h>

#include <cmath>

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
  EXPECT_EQ(b.state_at(1.0, 1.2), BracketState::kPending);  // a sample in (1.0, 1.4] may still come
  EXPECT_EQ(b.state_at(1.0, 1.5), BracketState::kMissing);  // none can: the gap would exceed 0.5 s
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

// --- pulse-jump gate (a counter glitch is not distance: an absurd pulse jump is rejected and counted) ---
namespace {
// 10 m/s at K = 0.0125 m/pulse sampled at 50 Hz: 16 pulses per sample, from a raw start of 1000.
constexpr uint32_t kPulsesPerSample = 16;
OdometerSample steady(int i, uint32_t offset = 0) {
  return {0.02 * i, 1000u + kPulsesPerSample * static_cast<uint32_t>(i) + offset, 1};
}
}  // namespace

TEST(OdometerBuffer, JumpGateIsMaxSpeedOverNominalKTimesDtPlusMargin) {
  const OdometerJumpGate gate;  // 100 m/s at 0.0125 m/pulse: 8000 pulses/s, plus 2 pulses
  EXPECT_DOUBLE_EQ(gate.max_increment_pulses(0.02), 162.0);
  EXPECT_DOUBLE_EQ(gate.max_increment_pulses(0.0), 2.0);
  // The bound itself passes, one pulse more over the same 20 ms does not.
  OdometerBuffer at_bound;
  at_bound.add({0.0, 0u, 1});
  EXPECT_EQ(at_bound.add({0.02, 162u, 1}), OdometerAddResult::kAccepted);
  OdometerBuffer above;
  above.add({0.0, 0u, 1});
  EXPECT_EQ(above.add({0.02, 163u, 1}), OdometerAddResult::kJumpRejected);
  EXPECT_EQ(above.jumps_rejected(), 1u);
  // A counter that steps back by one pulse is an increment of 2^32 - 1: rejected as well.
  OdometerBuffer backwards;
  backwards.add({0.0, 500u, 1});
  EXPECT_EQ(backwards.add({0.02, 499u, 1}), OdometerAddResult::kJumpRejected);
  // A real wrap is an ordinary increment.
  OdometerBuffer wrap;
  wrap.add({0.0, 4294967290u, 1});
  EXPECT_EQ(wrap.add({0.02, 10u, 1}), OdometerAddResult::kAccepted);
  EXPECT_DOUBLE_EQ(*wrap.count_at(0.02, 0.02), 16.0);
  EXPECT_THROW(OdometerBuffer(1.0, OdometerJumpGate{0.0, 0.0125, 2.0}), std::invalid_argument);
  EXPECT_THROW(OdometerBuffer(1.0, OdometerJumpGate{100.0, -1.0, 2.0}), std::invalid_argument);
}

TEST(OdometerBuffer, MillionfoldSpikeIsRejectedAndNoPulseIsLost) {
  OdometerBuffer b;
  int rejected = 0;
  for (int i = 0; i <= 100; ++i) {
    OdometerSample s = steady(i);
    if (i == 50) s.pulses += 1000000u * kPulsesPerSample;  // one bad value, then the counter goes on
    if (b.add(s) == OdometerAddResult::kJumpRejected) ++rejected;
  }
  EXPECT_EQ(rejected, 1);
  EXPECT_EQ(b.jumps_rejected(), 1u);
  EXPECT_EQ(b.rebases(), 0u);
  // Interpolated across the dropped sample: exactly the true count (constant speed).
  EXPECT_DOUBLE_EQ(*b.count_at(1.0, 2.0), 50.0 * kPulsesPerSample);
  EXPECT_DOUBLE_EQ(*b.count_at(2.0, 2.0), 100.0 * kPulsesPerSample);
}

TEST(OdometerBuffer, MillionfoldStepIsRejectedThenRebasedSoTheDistanceAfterItIsRight) {
  OdometerBuffer b;
  for (int i = 0; i <= 100; ++i) {
    // From sample 50 on the counter reads 16 million too high and keeps counting from there.
    b.add(steady(i, i >= 50 ? 1000000u * kPulsesPerSample : 0u));
  }
  EXPECT_EQ(b.jumps_rejected(), 1u);
  EXPECT_EQ(b.rebases(), 1u);
  // The interval holding the jump is estimated at the last rate (exact at constant speed) and every
  // later increment is the true one: the count at the end is the true 1600 pulses.
  EXPECT_DOUBLE_EQ(*b.count_at(2.0, 2.0), 100.0 * kPulsesPerSample);
  EXPECT_DOUBLE_EQ(*b.count_at(1.5, 2.0), 75.0 * kPulsesPerSample);
}

TEST(OdometerBuffer, StepAtChangingSpeedLosesAtMostTheOneEstimatedInterval) {
  // Speed ramps 5 -> 15 m/s (400 -> 1200 pulses/s); the counter steps by 2^31 at t = 1.01 s.
  OdometerBuffer b;
  auto pulses_at = [](double t) { return 400.0 * t + 200.0 * t * t; };  // N(t), pulses
  for (int i = 0; i <= 200; ++i) {
    const double t = 0.01 * i;
    uint32_t raw = static_cast<uint32_t>(std::floor(pulses_at(t)));
    if (i >= 101) raw += 2147483648u;
    b.add({t, raw, 1});
  }
  EXPECT_EQ(b.jumps_rejected(), 1u);
  EXPECT_EQ(b.rebases(), 1u);
  // The estimated interval [1.00, 1.01] s misses the acceleration term (about 0.04 pulses) plus
  // quantisation: the final count is within 2 pulses of the true 1600.
  EXPECT_NEAR(*b.count_at(2.0, 2.0), pulses_at(2.0), 2.0);
}
