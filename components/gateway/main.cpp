// odonav-gateway: publishes one vehicle's sensor streams from the simulator, a dataset, or live
// line-protocol devices over UDP or a serial line, and GNSS from gpsd (README.md).
#include <spdlog/spdlog.h>

#include "node/gateway_node.hpp"
#include "node/live_gateway.hpp"

int main(int argc, char** argv) {
  return odonav::dds::run_component(
      argc, argv, "odonav-gateway",
      "Publishes rt/odonav/odometer (100 Hz), rt/odonav/ins/attitude (100 Hz) and rt/odonav/gnss/fix (10 Hz) of "
      "one vehicle from --source sim:<scenario> or replay:<dataset dir>, stamped with the sample time, in time "
      "order, at --speed 1 (real time), N or max (as fast as the readers acknowledge), or live from line-protocol "
      "devices (--source udp:... or serial:..., optionally with --gnss-source gpsd:...) or gpsd (--source gpsd:...). Exits 0 at the end of the data or on SIGINT/SIGTERM, 4 when a reliable reader was lost before the data was complete (--tolerate-lost-readers: 0).",
      [](odonav::Options& o) { odonav::gateway::add_gateway_options(o); },
      [](const odonav::Options& o, odonav::dds::ComponentRuntime& runtime) {
        if (odonav::gateway::is_live_mode(o)) return odonav::gateway::run_live_gateway(o, runtime);
        const odonav::gateway::GatewaySettings settings = odonav::gateway::gateway_settings_from(o);
        odonav::DatasetReadReport report;
        odonav::Dataset dataset;
        try {
          dataset = odonav::gateway::load_source(settings.source, settings.simulator, settings.on_bad_row, &report);
        } catch (const odonav::DatasetError& e) {
          spdlog::error("{}", e.what());
          return 1;
        }
        for (const auto& f : report.files)
          if (f.rows_bad) spdlog::warn("{}: skipped {} bad rows (kept {})", f.file, f.rows_bad, f.rows_read);
        odonav::gateway::GatewayNode node(runtime, settings, std::move(dataset));
        return node.run();
      });
}
