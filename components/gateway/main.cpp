// odonav-gateway: publishes one vehicle's sensor streams from the simulator, a dataset, or live
// line-protocol devices over UDP or a serial line (README.md).
#include <spdlog/spdlog.h>

#include "core/live_input.hpp"
#include "node/gateway_node.hpp"
#include "odonav/topics.hpp"

namespace {

/// Live sources: every accepted line is published at once, stamped with its own t, with the same
/// sample -> message mapping as the replay (odometer_message, ins_message, gnss_message).
class LivePublisher : public odonav::gateway::SampleSink {
 public:
  explicit LivePublisher(odonav::dds::ComponentRuntime& runtime)
      : runtime_(runtime),
        odometer_(runtime.participant(), odonav::topics::kOdometer.name, odonav::topics::kSensorWriterProfile),
        ins_(runtime.participant(), odonav::topics::kInsAttitude.name, odonav::topics::kSensorWriterProfile),
        gnss_(runtime.participant(), odonav::topics::kGnssFix.name, odonav::topics::kSensorWriterProfile) {}

  void odometer(const odonav::OdometerSample& s) override {
    count(odometer_.write(odonav::gateway::odometer_message(s, vehicle())), 0, s.t_s);
  }
  void ins(const odonav::InsSample& s) override { count(ins_.write(odonav::gateway::ins_message(s, vehicle())), 1, s.t_s); }
  void gnss(const odonav::GnssSample& s) override {
    const odonav::msg::GnssFix m = odonav::gateway::gnss_message(s, vehicle());
    if (!m.valid()) ++gnss_invalid_;
    count(gnss_.write(m), 2, s.t_s);
  }

  void health(odonav::msg::HealthState state, const std::string& reason, const odonav::gateway::LineCounters& lines,
              const odonav::gateway::LiveInputStats& stats, bool force) {
    odonav::dds::HealthCounters c;
    c.emplace_back("odometer_published", static_cast<double>(published_[0]));
    c.emplace_back("ins_published", static_cast<double>(published_[1]));
    c.emplace_back("gnss_published", static_cast<double>(published_[2]));
    c.emplace_back("gnss_invalid_published", static_cast<double>(gnss_invalid_));
    c.emplace_back("event_time_s", last_t_s_);
    c.emplace_back("lines_read", static_cast<double>(lines.lines));
    for (std::size_t i = 0; i < odonav::gateway::kLineErrorCount; ++i)
      c.emplace_back(std::string("lines_") + odonav::gateway::to_string(static_cast<odonav::gateway::LineError>(i)),
                     static_cast<double>(lines.errors[i]));
    c.emplace_back("source_failures", static_cast<double>(stats.source_failures));
    c.emplace_back("write_failures", static_cast<double>(write_failures_));
    const bool trouble = write_failures_ + lines.total_errors() + stats.source_failures > 0;
    runtime_.publish_health(state, trouble ? odonav::msg::HEALTH_LEVEL_WARN : odonav::msg::HEALTH_LEVEL_OK,
                            reason.empty() ? stats.last_failure : reason, c, force);
  }
  void wait_for_acknowledgments() {
    for (odonav::dds::detail::WriterBase* w : {static_cast<odonav::dds::detail::WriterBase*>(&odometer_),
                                               static_cast<odonav::dds::detail::WriterBase*>(&ins_),
                                               static_cast<odonav::dds::detail::WriterBase*>(&gnss_)})
      odonav::dds::wait_for_acknowledgments_logged(*w, std::chrono::seconds(5));
  }
  double last_t_s() const { return last_t_s_; }

 private:
  const std::string& vehicle() const { return runtime_.settings().vehicle_id; }
  void count(bool ok, int stream, double t_s) {
    if (!ok && ++write_failures_ <= 10) spdlog::warn("write refused by the middleware at t={} s", t_s);
    ++published_[stream];
    last_t_s_ = t_s;
  }

  odonav::dds::ComponentRuntime& runtime_;
  odonav::dds::Writer<odonav::msg::Odometer> odometer_;
  odonav::dds::Writer<odonav::msg::InsAttitude> ins_;
  odonav::dds::Writer<odonav::msg::GnssFix> gnss_;
  std::uint64_t published_[3] = {0, 0, 0};
  std::uint64_t gnss_invalid_ = 0;
  std::uint64_t write_failures_ = 0;
  double last_t_s_ = 0.0;
};

int run_live(const odonav::Options& o, odonav::dds::ComponentRuntime& runtime) {
  using namespace odonav::gateway;
  const LiveSourceSpec spec = parse_live_source(o.get_string("source"), o.get_bool("allow-non-loopback"));
  std::unique_ptr<ByteSource> source;
  try {
    source = open_live_source(spec);
  } catch (const std::runtime_error& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
  spdlog::info("listening on {} (line protocol, README.md)", to_string(spec));
  LivePublisher publisher(runtime);
  LineDecoder decoder;
  LiveInputStats stats;
  publisher.health(odonav::msg::HEALTH_STATE_RUNNING, "", decoder.counters(), stats, true);
  run_live_input(
      std::move(source), decoder, publisher, [&] { return runtime.stop_signals().stop_requested(); },
      [&] {
        runtime.run_pending();  // commands (none supported: acknowledged as rejected), as in replay
        publisher.health(odonav::msg::HEALTH_STATE_RUNNING, "", decoder.counters(), stats, false);
      },
      [&] { return open_live_source(spec); }, stats);
  publisher.wait_for_acknowledgments();
  const std::string reason = "interrupted at t=" + std::to_string(publisher.last_t_s()) + " s";
  spdlog::info("{}: {} lines, {} rejected", reason, decoder.counters().lines, decoder.counters().total_errors());
  publisher.health(odonav::msg::HEALTH_STATE_STOPPING, reason, decoder.counters(), stats, true);
  odonav::dds::wait_for_acknowledgments_logged(runtime.health().writer(), std::chrono::seconds(1));
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return odonav::dds::run_component(
      argc, argv, "odonav-gateway",
      "Publishes rt/odonav/odometer (100 Hz), rt/odonav/ins/attitude (100 Hz) and rt/odonav/gnss/fix (10 Hz) of "
      "one vehicle from --source sim:<scenario> or replay:<dataset dir>, stamped with the sample time, in time "
      "order, at --speed 1 (real time), N or max (as fast as the readers acknowledge), or live from line-protocol "
      "devices (--source udp:... or serial:...). Exits 0 at the end of the data or on SIGINT/SIGTERM.",
      [](odonav::Options& o) { odonav::gateway::add_gateway_options(o); },
      [](const odonav::Options& o, odonav::dds::ComponentRuntime& runtime) {
        if (odonav::gateway::is_live_source(o.get_string("source"))) return run_live(o, runtime);
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
