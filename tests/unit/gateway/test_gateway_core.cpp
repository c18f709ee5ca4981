// odonav-gateway's core without DDS: --source and --speed parsing, the pacing clock, the
// acknowledgment schedule, the time-ordered merge of the streams, and the promise that the sim
// source gives exactly the dataset odonav-simulator writes (angles as the files hold them).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <random>
#include <string>

#include "odonav/gateway/pacing.hpp"
#include "odonav/gateway/sensor_source.hpp"
#include "odonav/simulator/simulator.hpp"
#include "odonav/config.hpp"

using namespace odonav;
using namespace odonav::gateway;

TEST(GatewaySource, ParsesSimAndReplay) {
  SourceSpec s = parse_source("sim:ring");
  EXPECT_EQ(s.kind, SourceSpec::Kind::kSimulator);
  EXPECT_EQ(s.name, "ring");
  EXPECT_EQ(parse_source("sim:").name, "terrain");
  s = parse_source("replay:/data/drive 1");
  EXPECT_EQ(s.kind, SourceSpec::Kind::kReplay);
  EXPECT_EQ(s.name, "/data/drive 1");
  for (const char* bad : {"", "sim", "replay:", "file:/x", "terrain"}) {
    try {
      parse_source(bad);
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find("--source"), std::string::npos) << e.what();
    }
  }
}

TEST(GatewaySource, UnknownScenarioNamesTheFlag) {
  try {
    load_source(parse_source("sim:moon"), SimulatorSettings{}, BadRowPolicy::kFail);
    FAIL() << "unknown scenario accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("sim:moon"), std::string::npos) << e.what();
  }
}

TEST(GatewayPacing, ParsesSpeeds) {
  EXPECT_TRUE(parse_speed("max").as_fast_as_possible);
  EXPECT_DOUBLE_EQ(parse_speed("1").factor, 1.0);
  EXPECT_DOUBLE_EQ(parse_speed("12.5").factor, 12.5);
  EXPECT_FALSE(parse_speed("0.5").as_fast_as_possible);
  for (const char* bad : {"", "0", "-1", "nan", "inf", "fast", "1e7", "2x"}) {
    EXPECT_THROW(parse_speed(bad), ConfigError) << bad;
  }
}

TEST(GatewayPacing, MapsEventTimeToWallTime) {
  // Speed 4: 10 s of data take 2.5 s; data before the first sample is due at the start.
  const PacingClock clock(parse_speed("4"), 1000.0, 50.0);
  EXPECT_DOUBLE_EQ(*clock.due_wall_s(1000.0), 50.0);
  EXPECT_DOUBLE_EQ(*clock.due_wall_s(1010.0), 52.5);
  EXPECT_DOUBLE_EQ(*clock.due_wall_s(990.0), 50.0);
  EXPECT_DOUBLE_EQ(clock.event_time_at(52.5), 1010.0);
  EXPECT_DOUBLE_EQ(clock.event_time_at(40.0), 1000.0);
  // Real time: one second per second.
  const PacingClock real(parse_speed("1"), 0.0, 7.0);
  EXPECT_DOUBLE_EQ(*real.due_wall_s(3.25), 10.25);
  // Max: nothing is ever waited for.
  const PacingClock max(parse_speed("max"), 0.0, 7.0);
  EXPECT_FALSE(max.due_wall_s(1e6).has_value());
  EXPECT_TRUE(std::isinf(max.event_time_at(8.0)));
  EXPECT_THROW(PacingClock(parse_speed("1"), std::nan(""), 0.0), std::invalid_argument);
}

TEST(GatewayPacing, AcknowledgmentEveryIntervalOfData) {
  // 16 Hz samples (exact binary times), interval 0.25 s: a wait before every 4th sample.
  AckSchedule schedule(0.25);
  int waits = 0;
  for (int i = 0; i < 100; ++i) {
    const bool wait = schedule.wait_before(i * 0.0625);
    EXPECT_EQ(wait, i > 0 && i % 4 == 0) << i;
    waits += wait;
  }
  EXPECT_EQ(waits, 24);
  EXPECT_THROW(AckSchedule(0.0), std::invalid_argument);
}

TEST(GatewaySource, InterleavesInTimeOrderWithFixedTieOrder) {
  Dataset d;
  for (int i = 0; i < 5; ++i) d.odometer.push_back(OdometerSample{i * 0.5, static_cast<uint32_t>(i), 1});
  for (int i = 0; i < 3; ++i) d.ins.push_back(InsSample{i * 1.0, Attitude{}, std::nullopt});
  d.gnss.push_back(GnssSample{});
  d.gnss.back().t_s = 1.0;
  d.gnss.push_back(GnssSample{});
  d.gnss.back().t_s = 1.75;
  const auto events = interleave(d);
  ASSERT_EQ(events.size(), 10u);
  using S = SensorEvent::Stream;
  // t: 0 odo, 0 ins, 0.5 odo, 1 odo, 1 ins, 1 gnss, 1.5 odo, 1.75 gnss, 2 odo, 2 ins
  const std::vector<std::pair<double, S>> expected{
      {0, S::kOdometer}, {0, S::kIns},        {0.5, S::kOdometer}, {1, S::kOdometer}, {1, S::kIns},
      {1, S::kGnss},     {1.5, S::kOdometer}, {1.75, S::kGnss},    {2, S::kOdometer}, {2, S::kIns}};
  for (std::size_t i = 0; i < events.size(); ++i) {
    EXPECT_EQ(events[i].t_s, expected[i].first) << i;
    EXPECT_EQ(events[i].stream, expected[i].second) << i;
  }
  EXPECT_EQ(events[8].index, 4u);  // the last odometer row
}

TEST(GatewaySource, RecordedDegreesGiveTheRadiansBackWithinOneUlp) {
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> angle(-kPi, kPi);
  int exact = 0;
  const int n = 20000;
  for (int i = 0; i < n; ++i) {
    const double x = angle(rng);
    const double back = deg_to_rad(recorded_degrees(x));
    if (back == x) ++exact;
    EXPECT_LE(std::abs(back - x), std::abs(std::nextafter(x, 10.0) - x)) << x;
  }
  // About 91 % of arbitrary doubles have an exact degree twin (dataset.hpp); most do.
  EXPECT_GT(exact, n * 8 / 10);
  EXPECT_LT(exact, n);  // and some do not: the normalisation is needed at all
}

TEST(GatewaySource, SimSourceIsBitIdenticalToTheWrittenDataset) {
  // What the gateway publishes from sim:terrain equals what read_dataset gives for the files
  // odonav-simulator writes with the same seed and duration.
  SimulatorSettings settings;
  settings.seed = 7;
  settings.duration_s = 30.0;
  const Dataset published = load_source(parse_source("sim:terrain"), settings, BadRowPolicy::kFail);
  simulator::SimulationConfig cfg = simulator::scenario_config("terrain");
  cfg.seed = 7;
  cfg.duration_s = 30.0;
  const std::string dir = std::string(ODONAV_BINARY_DIR) + "/test-gateway-core-dataset";
  write_dataset(dir, simulator::simulate(cfg));
  const Dataset files = read_dataset(dir, BadRowPolicy::kFail);
  ASSERT_EQ(published.odometer.size(), files.odometer.size());
  ASSERT_EQ(published.ins.size(), files.ins.size());
  ASSERT_EQ(published.gnss.size(), files.gnss.size());
  ASSERT_GT(files.gnss.size(), 250u);
  for (std::size_t i = 0; i < files.odometer.size(); ++i) {
    ASSERT_EQ(published.odometer[i].t_s, files.odometer[i].t_s);
    ASSERT_EQ(published.odometer[i].pulses, files.odometer[i].pulses);
  }
  for (std::size_t i = 0; i < files.ins.size(); ++i) {
    ASSERT_EQ(published.ins[i].t_s, files.ins[i].t_s);
    ASSERT_EQ(published.ins[i].attitude.heading_rad, files.ins[i].attitude.heading_rad) << i;
    ASSERT_EQ(published.ins[i].attitude.pitch_rad, files.ins[i].attitude.pitch_rad) << i;
    ASSERT_EQ(published.ins[i].attitude.roll_rad, files.ins[i].attitude.roll_rad) << i;
  }
  for (std::size_t i = 0; i < files.gnss.size(); ++i) {
    const GnssSample& a = published.gnss[i];
    const GnssSample& b = files.gnss[i];
    ASSERT_EQ(a.t_s, b.t_s);
    ASSERT_EQ(a.position.lat_rad, b.position.lat_rad) << i;
    ASSERT_EQ(a.position.lon_rad, b.position.lon_rad) << i;
    ASSERT_EQ(a.position.height_m, b.position.height_m) << i;
    ASSERT_EQ(a.vel_enu_mps, b.vel_enu_mps) << i;
    ASSERT_EQ(a.fix, b.fix) << i;
    // A consumer converts the published degrees back: the same radians as the files give.
    ASSERT_EQ(deg_to_rad(recorded_degrees(a.position.lat_rad)), b.position.lat_rad) << i;
    ASSERT_EQ(deg_to_rad(recorded_degrees(a.position.lon_rad)), b.position.lon_rad) << i;
  }
}
