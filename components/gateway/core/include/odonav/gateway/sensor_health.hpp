#pragma once
// odonav-gateway's middleware-free core, part 6: the gateway's Health counters, one list for every
// source (README.md, "Health counters"). The sensor publisher (node/sensor_publisher.hpp) counts
// what it wrote; the source (replay/simulator, line protocol, gpsd) adds its own counters. Kept
// apart from the DDS node so the list and the WARN rule are tested without a participant.
#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "odonav/gateway/candump_source.hpp"
#include "odonav/gateway/gpsd_source.hpp"
#include "odonav/gateway/line_protocol.hpp"
#include "odonav/gateway/live_input.hpp"

namespace odonav::gateway {

/// Named figures in order, the type of odonav::dds::HealthCounters (odonav/dds/health.hpp), which
/// this core does not include (no DDS header here).
using Counters = std::vector<std::pair<std::string, double>>;

/// What the sensor publisher wrote.
struct PublishedCounts {
  std::array<std::uint64_t, 3> published{};  ///< samples written, indexed by SensorEvent::Stream.
  std::uint64_t gnss_invalid = 0;            ///< of the GNSS samples, those published with valid = false.
  std::uint64_t write_failures = 0;          ///< writes the middleware refused.
  double last_t_s = 0.0;                     ///< event time of the last sample written, s (0 before any).
};

/// What a source adds to the gateway's Health.
struct SourceHealth {
  /// Shown after the publisher's sample counters, before write_failures.
  Counters counters;
  /// Shown after write_failures.
  Counters trailing_counters;
  bool warn = false;   ///< something the source counted needs a look (Health level WARN).
  std::string reason;  ///< why, when the caller gives no reason of its own ("" if none).
};

/// The gateway's Health: counters, level and reason.
struct GatewayHealth {
  /// odometer_published, ins_published, gnss_published, gnss_invalid_published, event_time_s,
  /// the source's counters, write_failures, the source's trailing counters.
  Counters counters;
  bool warn = false;   ///< a write failure, or source.warn.
  std::string reason;  ///< `reason` when not empty, else source.reason.
};

GatewayHealth gateway_health(const PublishedCounts& published, const SourceHealth& source, const std::string& reason);

/// The replay / simulator source: matched readers of the odometer, INS and GNSS writers, then
/// (trailing) ack_timeouts, the acknowledgment waits of the flow control that timed out (WARN when
/// any did).
SourceHealth replay_source_health(const std::array<std::size_t, 3>& matched_readers, std::uint64_t ack_timeouts);

/// A live source: lines_read, lines_<error> per LineError, source_failures; with gpsd (gpsd given)
/// trailing gnss_lines_ignored, gpsd_connected (1/0), gpsd_reports, gpsd_connection_failures,
/// gnss_no_time, gnss_time_backwards, gnss_repeated. WARN once any line error, source failure or
/// ignored GNSS line was counted, and with gpsd while it is not connected or once a connection
/// failure, a fix without time or a fix going back in time was counted. Reason: the live source's
/// last failure, else (gpsd not connected) gpsd's last failure or "gpsd: not connected yet".
SourceHealth live_source_health(const LineCounters& lines, const LiveInputStats& stats,
                                const std::optional<GpsdCounters>& gpsd, std::uint64_t gnss_lines_ignored);

/// The CAN input (candump): can_lines_read, can_frames_decoded, can_odometer_samples,
/// can_frames_malformed, can_frames_unknown, can_frames_out_of_order, can_frames_stale,
/// can_frames_undecodable. WARN once a malformed, out-of-order, stale or undecodable frame was
/// counted (unknown frames are other traffic of a shared bus: counted, not a warning).
SourceHealth can_source_health(const CanCounters& can);

/// `first` then `second`: counters and trailing counters appended in that order, WARN if either
/// warns, the first non-empty reason.
SourceHealth combine(SourceHealth first, const SourceHealth& second);

}  // namespace odonav::gateway
