// The gateway's Health counters (core/sensor_health.hpp): one list for the replay and the live
// sources, in the order the ground station shows them, and the WARN rule of each source.
#include <gtest/gtest.h>

#include <string>
#include <utility>
#include <vector>

#include "odonav/gateway/sensor_health.hpp"

namespace odonav::gateway {
namespace {

std::vector<std::string> names(const Counters& c) {
  std::vector<std::string> out;
  for (const auto& [name, value] : c) out.push_back(name);
  return out;
}

double value(const Counters& c, const std::string& name) {
  for (const auto& [n, v] : c)
    if (n == name) return v;
  ADD_FAILURE() << "no counter " << name;
  return -1.0;
}

PublishedCounts some_published() {
  PublishedCounts p;
  p.published = {1200, 1100, 120};
  p.gnss_invalid = 7;
  p.last_t_s = 412.37;
  return p;
}

TEST(GatewayHealth, ReplayCountersInOrderAndAckTimeoutsWarn) {
  const GatewayHealth ok = gateway_health(some_published(), replay_source_health({3, 2, 4}, 0), "");
  EXPECT_EQ(names(ok.counters),
            (std::vector<std::string>{"odometer_published", "ins_published", "gnss_published", "gnss_invalid_published",
                                      "event_time_s", "odometer_readers", "ins_readers", "gnss_readers",
                                      "write_failures", "ack_timeouts"}));
  EXPECT_EQ(value(ok.counters, "odometer_published"), 1200.0);
  EXPECT_EQ(value(ok.counters, "ins_published"), 1100.0);
  EXPECT_EQ(value(ok.counters, "gnss_published"), 120.0);
  EXPECT_EQ(value(ok.counters, "gnss_invalid_published"), 7.0);
  EXPECT_EQ(value(ok.counters, "event_time_s"), 412.37);
  EXPECT_EQ(value(ok.counters, "odometer_readers"), 3.0);
  EXPECT_EQ(value(ok.counters, "ins_readers"), 2.0);
  EXPECT_EQ(value(ok.counters, "gnss_readers"), 4.0);
  EXPECT_EQ(value(ok.counters, "write_failures"), 0.0);
  EXPECT_FALSE(ok.warn);
  EXPECT_EQ(ok.reason, "");

  const GatewayHealth late =
      gateway_health(some_published(), replay_source_health({3, 3, 3}, 2), "waiting for readers");
  EXPECT_EQ(value(late.counters, "ack_timeouts"), 2.0);
  EXPECT_TRUE(late.warn);
  EXPECT_EQ(late.reason, "waiting for readers");
}

TEST(GatewayHealth, AWriteFailureWarnsWhateverTheSource) {
  PublishedCounts p = some_published();
  p.write_failures = 1;
  const GatewayHealth h = gateway_health(p, replay_source_health({1, 1, 1}, 0), "");
  EXPECT_EQ(value(h.counters, "write_failures"), 1.0);
  EXPECT_TRUE(h.warn);
  const GatewayHealth live =
      gateway_health(p, live_source_health(LineCounters{}, LiveInputStats{}, std::nullopt, 0), "");
  EXPECT_TRUE(live.warn);
}

TEST(GatewayHealth, LineSourceCountersInOrderAndEveryErrorWarns) {
  LineCounters lines;
  lines.lines = 5000;
  const SourceHealth clean = live_source_health(lines, LiveInputStats{}, std::nullopt, 0);
  const GatewayHealth h = gateway_health(some_published(), clean, "");
  EXPECT_EQ(names(h.counters),
            (std::vector<std::string>{"odometer_published", "ins_published", "gnss_published", "gnss_invalid_published",
                                      "event_time_s", "lines_read", "lines_malformed", "lines_bad_checksum",
                                      "lines_time_backwards", "lines_overlong", "lines_wrong_field_count",
                                      "lines_non_finite", "source_failures", "write_failures"}));
  EXPECT_EQ(value(h.counters, "lines_read"), 5000.0);
  EXPECT_FALSE(h.warn);
  EXPECT_EQ(h.reason, "");

  for (std::size_t i = 0; i < kLineErrorCount; ++i) {
    LineCounters bad = lines;
    bad.errors[i] = 3;
    const GatewayHealth w =
        gateway_health(some_published(), live_source_health(bad, LiveInputStats{}, std::nullopt, 0), "");
    EXPECT_TRUE(w.warn) << to_string(static_cast<LineError>(i));
    EXPECT_EQ(value(w.counters, std::string("lines_") + to_string(static_cast<LineError>(i))), 3.0);
  }

  LiveInputStats failed;
  failed.source_failures = 2;
  failed.last_failure = "serial:/dev/ttyUSB0: end of file (device closed)";
  const GatewayHealth f = gateway_health(some_published(), live_source_health(lines, failed, std::nullopt, 0), "");
  EXPECT_EQ(value(f.counters, "source_failures"), 2.0);
  EXPECT_TRUE(f.warn);
  EXPECT_EQ(f.reason, "serial:/dev/ttyUSB0: end of file (device closed)");
  // The caller's reason (the stop) wins over the source's.
  const GatewayHealth stop = gateway_health(some_published(), live_source_health(lines, failed, std::nullopt, 0),
                                            "interrupted at t=412.370000 s");
  EXPECT_EQ(stop.reason, "interrupted at t=412.370000 s");
}

TEST(GatewayHealth, GpsdCountersFollowWriteFailuresAndNotConnectedWarns) {
  GpsdCounters g;
  g.connected = true;
  g.reports = 120;
  g.repeated = 4;  // gpsd may report one epoch twice: counted, not a reason to look
  const GatewayHealth h =
      gateway_health(some_published(), live_source_health(LineCounters{}, LiveInputStats{}, g, 0), "");
  const std::vector<std::string> n = names(h.counters);
  const std::vector<std::string> tail(n.end() - 8, n.end());
  EXPECT_EQ(tail, (std::vector<std::string>{"write_failures", "gnss_lines_ignored", "gpsd_connected", "gpsd_reports",
                                            "gpsd_connection_failures", "gnss_no_time", "gnss_time_backwards",
                                            "gnss_repeated"}));
  EXPECT_EQ(value(h.counters, "gpsd_connected"), 1.0);
  EXPECT_EQ(value(h.counters, "gpsd_reports"), 120.0);
  EXPECT_EQ(value(h.counters, "gnss_repeated"), 4.0);
  EXPECT_FALSE(h.warn);

  GpsdCounters down;
  const GatewayHealth first =
      gateway_health(some_published(), live_source_health(LineCounters{}, LiveInputStats{}, down, 0), "");
  EXPECT_TRUE(first.warn);
  EXPECT_EQ(first.reason, "gpsd: not connected yet");
  down.connection_failures = 1;
  down.last_failure = "gpsd:127.0.0.1:2947: connect failed: Connection refused";
  const GatewayHealth lost =
      gateway_health(some_published(), live_source_health(LineCounters{}, LiveInputStats{}, down, 0), "");
  EXPECT_EQ(lost.reason, "gpsd:127.0.0.1:2947: connect failed: Connection refused");
  EXPECT_EQ(value(lost.counters, "gpsd_connection_failures"), 1.0);

  GpsdCounters backwards = g;
  backwards.time_backwards = 1;
  EXPECT_TRUE(
      gateway_health(some_published(), live_source_health(LineCounters{}, LiveInputStats{}, backwards, 0), "").warn);
  GpsdCounters no_time = g;
  no_time.no_time = 1;
  EXPECT_TRUE(
      gateway_health(some_published(), live_source_health(LineCounters{}, LiveInputStats{}, no_time, 0), "").warn);
  // GNSS lines dropped because gpsd gives the GNSS: counted and a reason to look.
  const GatewayHealth ignored =
      gateway_health(some_published(), live_source_health(LineCounters{}, LiveInputStats{}, g, 9), "");
  EXPECT_EQ(value(ignored.counters, "gnss_lines_ignored"), 9.0);
  EXPECT_TRUE(ignored.warn);
}

}  // namespace
}  // namespace odonav::gateway
