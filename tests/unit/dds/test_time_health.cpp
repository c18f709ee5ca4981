// Middleware-free parts of the DDS layer: seconds <-> Time, the rate limiter, the deadline edge
// detector and make_health.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>

#include "odonav/dds/endpoints.hpp"
#include "odonav/dds/health.hpp"
#include "odonav/dds/silence_tracker.hpp"
#include "odonav/dds/time.hpp"
#include "odonav/wire_time.hpp"

using odonav::dds::to_seconds;
using odonav::dds::to_time_msg;

namespace {
builtin_interfaces::msg::Time make_time(std::int32_t sec, std::uint32_t nanosec) {
  builtin_interfaces::msg::Time t;
  t.sec(sec);
  t.nanosec(nanosec);
  return t;
}
std::string error_of(double seconds) {
  try {
    to_time_msg(seconds);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "no exception";
}
}  // namespace

TEST(DdsTime, KnownValuesFollowTheRosConvention) {
  EXPECT_EQ(to_time_msg(0.0), make_time(0, 0));
  EXPECT_EQ(to_time_msg(1.5), make_time(1, 500000000));
  EXPECT_EQ(to_time_msg(-0.25), make_time(-1, 750000000));  // sec negative, nanosec positive
  EXPECT_EQ(to_time_msg(-1.0), make_time(-1, 0));
  EXPECT_EQ(to_time_msg(604799.123456789), make_time(604799, 123456789));  // end of a GNSS week
  EXPECT_EQ(to_time_msg(12.0000000004), make_time(12, 0));                 // rounds down
  EXPECT_EQ(to_time_msg(12.0000000006), make_time(12, 1));                 // rounds up
  EXPECT_EQ(to_time_msg(12.9999999996), make_time(13, 0));                 // carries into sec
  EXPECT_EQ(to_time_msg(2147483647.0), make_time(2147483647, 0));
  EXPECT_EQ(to_time_msg(-2147483648.0), make_time(-2147483648, 0));
  EXPECT_DOUBLE_EQ(to_seconds(make_time(-1, 750000000)), -0.25);
  EXPECT_DOUBLE_EQ(to_seconds(make_time(1700000000, 250000000)), 1700000000.25);
}

TEST(DdsTime, RoundTripIsExactToTheNanosecondBelow2Pow22Seconds) {
  std::mt19937 rng(20261121);
  std::uniform_int_distribution<std::int32_t> sec(-(1 << 22) + 1, (1 << 22) - 1);
  std::uniform_int_distribution<std::uint32_t> nanosec(0, 999999999);
  int mismatches = 0;
  for (int i = 0; i < 200000; ++i) {
    const auto t = make_time(sec(rng), nanosec(rng));
    const auto back = to_time_msg(to_seconds(t));
    if (!(back == t)) {
      if (++mismatches < 5)
        ADD_FAILURE() << t.sec() << " s " << t.nanosec() << " ns came back as " << back.sec() << " s " << back.nanosec()
                      << " ns";
    }
  }
  EXPECT_EQ(mismatches, 0);
}

TEST(DdsTime, SecondsRoundTripWithinHalfANanosecondPlusRepresentation) {
  // seconds -> Time -> seconds differs by the rounding to the ns (<= 0.5 ns) plus one double
  // rounding of the result, an independent bound computed from the double spacing at t.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> seconds(-1.0e6, 1.0e6);
  for (int i = 0; i < 100000; ++i) {
    const double t = seconds(rng);
    const double back = to_seconds(to_time_msg(t));
    const double ulp = std::nextafter(std::abs(t), 1e300) - std::abs(t);
    ASSERT_LE(std::abs(back - t), 0.5e-9 + 2.0 * ulp) << t;
  }
}

TEST(DdsTime, BadInputIsRefusedWithTheValue) {
  EXPECT_NE(error_of(std::nan("")).find("is not finite"), std::string::npos);
  EXPECT_NE(error_of(std::numeric_limits<double>::infinity()).find("is not finite"), std::string::npos);
  EXPECT_NE(error_of(2147483648.0).find("2147483648 s does not fit int32 seconds"), std::string::npos)
      << error_of(2147483648.0);
  EXPECT_NE(error_of(-2147483648.5).find("does not fit int32 seconds"), std::string::npos);
  EXPECT_NE(error_of(2147483647.9999999999).find("does not fit int32 seconds"), std::string::npos);  // 2^31 as a double
  // fits_wire_time is the same rule without the exception (the dataset reader's row check).
  for (const double t : {std::nan(""), 2147483648.0, -2147483648.5, 2147483647.9999999999, 3.3e116}) {
    EXPECT_FALSE(odonav::fits_wire_time(t)) << t;
  }
  for (const double t : {-2147483648.0, 0.0, 2147483647.9999997, 1.7e9}) {
    EXPECT_TRUE(odonav::fits_wire_time(t)) << t;
    EXPECT_NO_THROW(odonav::to_wire_time(t)) << t;
  }
  try {
    to_seconds(make_time(3, 1000000000u));
    ADD_FAILURE() << "accepted nanosec = 1e9";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("nanosec 1000000000} is not normalized"), std::string::npos) << e.what();
  }
}

// odonav-offline reads each stamp as the nodes read it from a message: one rounding for both.
TEST(DdsTime, WireTimeIsTheStampAConsumerReadsAndIsIdempotent) {
  std::mt19937 rng(8);
  std::uniform_real_distribution<double> seconds(-1.0e6, 1.0e6);
  for (int i = 0; i < 100000; ++i) {
    const double t = seconds(rng);
    const double wire = odonav::wire_time_s(t);
    ASSERT_EQ(wire, to_seconds(to_time_msg(t))) << t;
    ASSERT_EQ(odonav::wire_time_s(wire), wire) << t;
  }
  // A 20 Hz epoch stamped 323 x 0.05 s = 16.150000000000002 reads 16.15, the odometer's stamp.
  EXPECT_NE(323 * 0.05, 16.15);
  EXPECT_EQ(odonav::wire_time_s(323 * 0.05), 16.15);
  EXPECT_THROW(odonav::wire_time_s(std::nan("")), std::invalid_argument);
}

TEST(DdsTime, MakeHeaderSetsStampAndFrame) {
  const auto h = odonav::dds::make_header(345600.5, "enu");
  EXPECT_EQ(h.stamp(), make_time(345600, 500000000));
  EXPECT_EQ(h.frame_id(), "enu");
}

TEST(RateLimiter, PassesAtMostOncePerPeriod) {
  odonav::dds::RateLimiter limiter(1.0);
  EXPECT_TRUE(limiter.due(10.0));  // first call
  EXPECT_FALSE(limiter.due(10.5));
  EXPECT_FALSE(limiter.due(10.999999));
  EXPECT_TRUE(limiter.due(11.0));  // exactly one period later
  EXPECT_FALSE(limiter.due(11.7));
  EXPECT_TRUE(limiter.due(13.2));  // a gap: passes, and the period restarts at 13.2
  EXPECT_FALSE(limiter.due(14.1));
  EXPECT_TRUE(limiter.due(14.2));
  EXPECT_TRUE(limiter.due(3.0));  // clock reset (replay restarted)
  EXPECT_FALSE(limiter.due(3.5));
  EXPECT_FALSE(limiter.due(std::nan("")));
  limiter.reset();
  EXPECT_TRUE(limiter.due(3.6));
}

TEST(RateLimiter, ZeroPeriodPassesEverythingAndBadPeriodsAreRefused) {
  odonav::dds::RateLimiter every(0.0);
  EXPECT_TRUE(every.due(1.0));
  EXPECT_TRUE(every.due(1.0));
  EXPECT_THROW(odonav::dds::RateLimiter(-1.0), std::invalid_argument);
  EXPECT_THROW(odonav::dds::RateLimiter(std::nan("")), std::invalid_argument);
  EXPECT_THROW(odonav::dds::RateLimiter(std::numeric_limits<double>::infinity()), std::invalid_argument);
}

TEST(SilenceTracker, ReportsOnlyTheEdgesPerInstance) {
  odonav::dds::SilenceTracker<int> tracker;
  EXPECT_FALSE(tracker.on_data(1));             // data while not silent: no edge
  EXPECT_TRUE(tracker.on_deadline_missed(1));   // goes silent
  EXPECT_FALSE(tracker.on_deadline_missed(1));  // every further period: no new edge
  EXPECT_FALSE(tracker.on_deadline_missed(1));
  EXPECT_TRUE(tracker.is_silent(1));
  EXPECT_FALSE(tracker.is_silent(2));
  EXPECT_TRUE(tracker.on_deadline_missed(2));  // instances are independent
  EXPECT_TRUE(tracker.on_data(1));             // data returns: one edge
  EXPECT_FALSE(tracker.on_data(1));
  EXPECT_FALSE(tracker.is_silent(1));
  EXPECT_TRUE(tracker.is_silent(2));
  EXPECT_TRUE(tracker.on_deadline_missed(1));  // silent again later: a new edge
}

TEST(MakeHealth, FillsEveryField) {
  odonav::dds::CommandAck ack{99, odonav::msg::COMMAND_RESULT_REJECTED, "K must be > 0"};
  const auto h = odonav::dds::make_health("vehicle-02", "odonav-identification", 12.25, odonav::msg::HEALTH_STATE_ERROR,
                                          odonav::msg::HEALTH_LEVEL_ERROR, "no GNSS", {{"a", 1.5}, {"b", -2.0}}, ack);
  EXPECT_EQ(h.header().stamp(), make_time(12, 250000000));
  EXPECT_EQ(h.vehicle_id(), "vehicle-02");
  EXPECT_EQ(h.component(), "odonav-identification");
  EXPECT_EQ(h.state(), odonav::msg::HEALTH_STATE_ERROR);
  EXPECT_EQ(h.level(), odonav::msg::HEALTH_LEVEL_ERROR);
  EXPECT_EQ(h.reason(), "no GNSS");
  ASSERT_EQ(h.counters().size(), 2u);
  EXPECT_EQ(h.counters()[1].name(), "b");
  EXPECT_EQ(h.counters()[1].value(), -2.0);
  EXPECT_EQ(h.last_command_id(), 99u);
  EXPECT_EQ(h.last_command_result(), odonav::msg::COMMAND_RESULT_REJECTED);
  EXPECT_EQ(h.last_command_detail(), "K must be > 0");
  // The enum numbers are the diagnostic_msgs levels the .msg twin documents.
  EXPECT_EQ(static_cast<int>(odonav::msg::HEALTH_LEVEL_OK), 0);
  EXPECT_EQ(static_cast<int>(odonav::msg::HEALTH_LEVEL_WARN), 1);
  EXPECT_EQ(static_cast<int>(odonav::msg::HEALTH_LEVEL_ERROR), 2);
  EXPECT_EQ(static_cast<int>(odonav::msg::HEALTH_LEVEL_STALE), 3);
}

// A key's instance handle depends on the key alone: fastddsgen's getKey() left the previous key's
// bytes in the padding between Health's two key members (the same key then hashed differently after
// another), and a participant's one type support per type computes keys on the writing thread and
// on receive threads at once. Two threads computing the keys of two different Health samples at
// once must each get their own sample's key, every time.
TEST(ThreadSafeKeyType, KeysComputedOnTwoThreadsAtOnceAreEachTheirSamplesKeys) {
  odonav::dds::detail::ThreadSafeKeyType<odonav::msg::HealthPubSubType> type;
  odonav::msg::Health a, b;
  a.vehicle_id("tracked-vehicle-with-a-long-name-0001");
  a.component("odonav-identification");
  b.vehicle_id("another-tracked-vehicle-named-0002");
  b.component("odonav-dead-reckoning");
  eprosima::fastrtps::rtps::InstanceHandle_t key_a, key_b;
  ASSERT_TRUE(type.getKey(&a, &key_a));
  ASSERT_TRUE(type.getKey(&b, &key_b));
  ASSERT_NE(key_a, key_b);
  eprosima::fastrtps::rtps::InstanceHandle_t again;
  ASSERT_TRUE(type.getKey(&a, &again));
  EXPECT_EQ(again, key_a);  // the same key after another one
  auto hammer = [&type](odonav::msg::Health* sample, eprosima::fastrtps::rtps::InstanceHandle_t expected) {
    int wrong = 0;
    for (int i = 0; i < 100000; ++i) {
      eprosima::fastrtps::rtps::InstanceHandle_t key;
      type.getKey(sample, &key);
      wrong += key == expected ? 0 : 1;
    }
    return wrong;
  };
  int wrong_a = 0, wrong_b = 0;
  std::thread t([&] { wrong_a = hammer(&a, key_a); });
  wrong_b = hammer(&b, key_b);
  t.join();
  EXPECT_EQ(wrong_a, 0);
  EXPECT_EQ(wrong_b, 0);
}
