// odonav-gateway: publishes one vehicle's sensor streams from the simulator, a dataset, or live
// line-protocol devices over UDP or a serial line, GNSS from gpsd, and the odometer from CAN logs
// in candump -L form (README.md).
#include <spdlog/spdlog.h>

#include "node/gateway_node.hpp"
#include "node/live_gateway.hpp"

int main(int argc, char** argv) {
  return odonav::dds::run_component(
      argc, argv, "odonav-gateway",
      "Publishes rt/odonav/odometer (100 Hz), rt/odonav/ins/attitude (100 Hz) and rt/odonav/gnss/fix (10 Hz) of "
      "one vehicle from --source sim:<scenario> or replay:<dataset dir>, stamped with the sample time, in time "
      "order, at --speed 1 (real time), N or max (as fast as the readers acknowledge), or live from line-protocol "
      "devices (--source udp:... or serial:..., optionally with --gnss-source gpsd:...) or gpsd (--source gpsd:...), or "
      "the odometer from a CAN bus logged by candump -L (--source candump:<file> replayed at --speed, with the INS and "
      "GNSS of --candump-dataset; candump:- live from standard input, with --ins-source and --gnss-source). Exits 0 at the end of the data or on SIGINT/SIGTERM, 4 when a reliable reader was lost before the data was complete (--tolerate-lost-readers: 0).",
      [](odonav::Options& o) { odonav::gateway::add_gateway_options(o); },
      [](const odonav::Options& o, odonav::dds::ComponentRuntime& runtime) {
        if (odonav::gateway::is_live_mode(o)) return odonav::gateway::run_live_gateway(o, runtime);
        const odonav::gateway::GatewaySettings settings = odonav::gateway::gateway_settings_from(o);
        odonav::DatasetReadReport report;
        odonav::Dataset dataset;
        odonav::gateway::SourceHealth source_health;
        try {
          if (settings.source.kind == odonav::gateway::SourceSpec::Kind::kCandump) {
            // A recorded CAN log: decoded whole, then replayed like a dataset (any --speed).
            odonav::gateway::CanOdometer can(settings.can);
            dataset = odonav::gateway::load_candump_source(settings.source.name, can, settings.candump_dataset,
                                                           settings.on_bad_row, &report);
            const odonav::gateway::CanCounters& c = can.counters();
            spdlog::info(
                "{}: {} lines, {} frames decoded into {} odometer samples; {} malformed, {} unknown, {} out "
                "of order, {} stale, {} undecodable",
                settings.source.name, c.lines, c.decoded, c.samples, c.malformed, c.unknown, c.out_of_order, c.stale,
                c.undecodable);
            source_health = odonav::gateway::can_source_health(c);
          } else {
            dataset = odonav::gateway::load_source(settings.source, settings.simulator, settings.on_bad_row, &report);
          }
        } catch (const odonav::DatasetError& e) {
          spdlog::error("{}", e.what());
          return 1;
        }
        for (const auto& f : report.files)
          if (f.rows_bad) spdlog::warn("{}: skipped {} bad rows (kept {})", f.file, f.rows_bad, f.rows_read);
        odonav::gateway::GatewayNode node(runtime, settings, std::move(dataset), std::move(source_health));
        return node.run();
      });
}
