#include "odonav/gateway/sensor_health.hpp"

namespace odonav::gateway {

namespace {
double number(std::uint64_t n) { return static_cast<double>(n); }
}  // namespace

GatewayHealth gateway_health(const PublishedCounts& published, const SourceHealth& source, const std::string& reason) {
  GatewayHealth h;
  Counters& c = h.counters;
  c.emplace_back("odometer_published", number(published.published[0]));
  c.emplace_back("ins_published", number(published.published[1]));
  c.emplace_back("gnss_published", number(published.published[2]));
  c.emplace_back("gnss_invalid_published", number(published.gnss_invalid));
  c.emplace_back("event_time_s", published.last_t_s);
  c.insert(c.end(), source.counters.begin(), source.counters.end());
  c.emplace_back("write_failures", number(published.write_failures));
  c.insert(c.end(), source.trailing_counters.begin(), source.trailing_counters.end());
  h.warn = published.write_failures > 0 || source.warn;
  h.reason = reason.empty() ? source.reason : reason;
  return h;
}

SourceHealth replay_source_health(const std::array<std::size_t, 3>& matched_readers, std::uint64_t ack_timeouts) {
  SourceHealth s;
  s.counters.emplace_back("odometer_readers", static_cast<double>(matched_readers[0]));
  s.counters.emplace_back("ins_readers", static_cast<double>(matched_readers[1]));
  s.counters.emplace_back("gnss_readers", static_cast<double>(matched_readers[2]));
  s.trailing_counters.emplace_back("ack_timeouts", number(ack_timeouts));
  s.warn = ack_timeouts > 0;
  return s;
}

SourceHealth live_source_health(const LineCounters& lines, const LiveInputStats& stats,
                                const std::optional<GpsdCounters>& gpsd, std::uint64_t gnss_lines_ignored) {
  SourceHealth s;
  s.counters.emplace_back("lines_read", number(lines.lines));
  for (std::size_t i = 0; i < kLineErrorCount; ++i)
    s.counters.emplace_back(std::string("lines_") + to_string(static_cast<LineError>(i)), number(lines.errors[i]));
  s.counters.emplace_back("source_failures", number(stats.source_failures));
  s.warn = lines.total_errors() + stats.source_failures + gnss_lines_ignored > 0;
  s.reason = stats.last_failure;
  if (!gpsd) return s;
  Counters& t = s.trailing_counters;
  t.emplace_back("gnss_lines_ignored", number(gnss_lines_ignored));
  t.emplace_back("gpsd_connected", gpsd->connected ? 1.0 : 0.0);
  t.emplace_back("gpsd_reports", number(gpsd->reports));
  t.emplace_back("gpsd_connection_failures", number(gpsd->connection_failures));
  t.emplace_back("gnss_no_time", number(gpsd->no_time));
  t.emplace_back("gnss_time_backwards", number(gpsd->time_backwards));
  t.emplace_back("gnss_repeated", number(gpsd->repeated));
  // Not connected or time going back: a reason to look (the reason names the last failure).
  s.warn = s.warn || !gpsd->connected || gpsd->connection_failures + gpsd->no_time + gpsd->time_backwards > 0;
  if (s.reason.empty() && !gpsd->connected)
    s.reason = gpsd->last_failure.empty() ? "gpsd: not connected yet" : gpsd->last_failure;
  return s;
}

SourceHealth can_source_health(const CanCounters& can) {
  SourceHealth s;
  Counters& c = s.counters;
  c.emplace_back("can_lines_read", number(can.lines));
  c.emplace_back("can_frames_decoded", number(can.decoded));
  c.emplace_back("can_odometer_samples", number(can.samples));
  c.emplace_back("can_frames_malformed", number(can.malformed));
  c.emplace_back("can_frames_unknown", number(can.unknown));
  c.emplace_back("can_frames_out_of_order", number(can.out_of_order));
  c.emplace_back("can_frames_stale", number(can.stale));
  c.emplace_back("can_frames_undecodable", number(can.undecodable));
  s.warn = can.problems() > 0;
  return s;
}

SourceHealth combine(SourceHealth first, const SourceHealth& second) {
  first.counters.insert(first.counters.end(), second.counters.begin(), second.counters.end());
  first.trailing_counters.insert(first.trailing_counters.end(), second.trailing_counters.begin(),
                                 second.trailing_counters.end());
  first.warn = first.warn || second.warn;
  if (first.reason.empty()) first.reason = second.reason;
  return first;
}

}  // namespace odonav::gateway
