#pragma once
// odonav-gateway's live mode: `--source udp:|serial:` (line protocol, core/live_input.hpp) with an
// optional `--gnss-source gpsd:...`, or `--source gpsd:...` alone (GNSS only, core/gpsd_source.hpp),
// or `--source candump:-` (the odometer from CAN frames on standard input, core/candump_source.hpp)
// with an optional `--ins-source udp:|serial:` (INS lines) and `--gnss-source gpsd:...`.
// Every accepted sample goes to the gateway's one SensorPublisher at once, stamped with its own t;
// Health adds the line and gpsd counters (core/sensor_health.hpp, live_source_health).
#include "odonav/config.hpp"
#include "odonav/dds/component.hpp"

namespace odonav::gateway {

/// True when --source names a live source (udp:, serial:, gpsd: or candump:-).
bool is_live_mode(const Options& options);

/// Runs live mode until SIGINT/SIGTERM. With both a line source and gpsd, gpsd is read on its own
/// thread and GNSS lines of the line source are dropped and counted (gnss_lines_ignored: two GNSS
/// streams on one topic would interleave two time bases). With candump:-, standard input is read on
/// its own thread (ODO lines of --ins-source are dropped and counted, odometer_lines_ignored) and
/// its end ends the run (exit 0). Returns the exit code: 0 after a stop
/// request, 1 when the line source cannot be opened. Throws ConfigError for a bad --source or
/// --gnss-source (or both giving GNSS).
int run_live_gateway(const Options& options, dds::ComponentRuntime& runtime);

}  // namespace odonav::gateway
