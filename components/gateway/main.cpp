// odonav-gateway: publishes one vehicle's sensor streams from the simulator, a dataset, or live
// line-protocol devices over UDP or a serial line, and GNSS from gpsd (README.md).
#include <spdlog/spdlog.h>

#include <atomic>
#include <mutex>
#include <optional>
#include <thread>

#include "core/gpsd_source.hpp"
#include "core/live_input.hpp"
#include "node/gateway_node.hpp"
#include "odonav/topics.hpp"

namespace {

/// Live sources: every accepted line is published at once, stamped with its own t, with the same
/// sample -> message mapping as the replay (odometer_message, ins_message, gnss_message).
/// Thread-safe: with a gpsd GNSS source beside a line source, GNSS arrives on its own thread.
class LivePublisher : public odonav::gateway::SampleSink {
 public:
  explicit LivePublisher(odonav::dds::ComponentRuntime& runtime)
      : runtime_(runtime),
        odometer_(runtime.participant(), odonav::topics::kOdometer.name, odonav::topics::kSensorWriterProfile),
        ins_(runtime.participant(), odonav::topics::kInsAttitude.name, odonav::topics::kSensorWriterProfile),
        gnss_(runtime.participant(), odonav::topics::kGnssFix.name, odonav::topics::kSensorWriterProfile) {}

  void odometer(const odonav::OdometerSample& s) override {
    const std::lock_guard<std::mutex> lock(mutex_);
    count(odometer_.write(odonav::gateway::odometer_message(s, vehicle())), 0, s.t_s);
  }
  void ins(const odonav::InsSample& s) override {
    const std::lock_guard<std::mutex> lock(mutex_);
    count(ins_.write(odonav::gateway::ins_message(s, vehicle())), 1, s.t_s); }
  void gnss(const odonav::GnssSample& s) override {
    const std::lock_guard<std::mutex> lock(mutex_);
    const odonav::msg::GnssFix m = odonav::gateway::gnss_message(s, vehicle());
    if (!m.valid()) ++gnss_invalid_;
    count(gnss_.write(m), 2, s.t_s);
  }

  void health(odonav::msg::HealthState state, const std::string& reason, const odonav::gateway::LineCounters& lines,
              const odonav::gateway::LiveInputStats& stats, const std::optional<odonav::gateway::GpsdCounters>& gpsd,
              std::uint64_t gnss_lines_ignored, bool force) {
    const std::lock_guard<std::mutex> lock(mutex_);
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
    bool trouble = write_failures_ + lines.total_errors() + stats.source_failures + gnss_lines_ignored > 0;
    std::string why = reason.empty() ? stats.last_failure : reason;
    if (gpsd) {
      c.emplace_back("gnss_lines_ignored", static_cast<double>(gnss_lines_ignored));
      c.emplace_back("gpsd_connected", gpsd->connected ? 1.0 : 0.0);
      c.emplace_back("gpsd_reports", static_cast<double>(gpsd->reports));
      c.emplace_back("gpsd_connection_failures", static_cast<double>(gpsd->connection_failures));
      c.emplace_back("gnss_no_time", static_cast<double>(gpsd->no_time));
      c.emplace_back("gnss_time_backwards", static_cast<double>(gpsd->time_backwards));
      c.emplace_back("gnss_repeated", static_cast<double>(gpsd->repeated));
      // Not connected or time going back: a reason to look (the reason names the last failure).
      trouble = trouble || !gpsd->connected || gpsd->connection_failures + gpsd->no_time + gpsd->time_backwards > 0;
      if (why.empty() && !gpsd->connected) why = gpsd->last_failure.empty() ? "gpsd: not connected yet" : gpsd->last_failure;
    }
    runtime_.publish_health(state, trouble ? odonav::msg::HEALTH_LEVEL_WARN : odonav::msg::HEALTH_LEVEL_OK, why, c,
                            force);
  }
  void wait_for_acknowledgments() {
    for (odonav::dds::detail::WriterBase* w : {static_cast<odonav::dds::detail::WriterBase*>(&odometer_),
                                               static_cast<odonav::dds::detail::WriterBase*>(&ins_),
                                               static_cast<odonav::dds::detail::WriterBase*>(&gnss_)})
      odonav::dds::wait_for_acknowledgments_logged(*w, std::chrono::seconds(5));
  }
  double last_t_s() {
    const std::lock_guard<std::mutex> lock(mutex_);
    return last_t_s_;
  }

 private:
  const std::string& vehicle() const { return runtime_.settings().vehicle_id; }
  void count(bool ok, int stream, double t_s) {
    if (!ok && ++write_failures_ <= 10) spdlog::warn("write refused by the middleware at t={} s", t_s);
    ++published_[stream];
    last_t_s_ = t_s;
  }

  std::mutex mutex_;
  odonav::dds::ComponentRuntime& runtime_;
  odonav::dds::Writer<odonav::msg::Odometer> odometer_;
  odonav::dds::Writer<odonav::msg::InsAttitude> ins_;
  odonav::dds::Writer<odonav::msg::GnssFix> gnss_;
  std::uint64_t published_[3] = {0, 0, 0};
  std::uint64_t gnss_invalid_ = 0;
  std::uint64_t write_failures_ = 0;
  double last_t_s_ = 0.0;
};

/// The line source's samples: odometer and INS always; GNSS lines only when gpsd is not the GNSS
/// source (two GNSS streams on one topic would interleave two time bases; the lines are counted).
class LineSink : public odonav::gateway::SampleSink {
 public:
  LineSink(LivePublisher& publisher, bool gnss_from_gpsd) : publisher_(publisher), gnss_from_gpsd_(gnss_from_gpsd) {}
  void odometer(const odonav::OdometerSample& s) override { publisher_.odometer(s); }
  void ins(const odonav::InsSample& s) override { publisher_.ins(s); }
  void gnss(const odonav::GnssSample& s) override {
    if (gnss_from_gpsd_) {
      if (ignored_++ == 0) spdlog::warn("GNSS lines on the line source are ignored: --gnss-source gives the GNSS");
      return;
    }
    publisher_.gnss(s);
  }
  std::uint64_t ignored() const { return ignored_; }

 private:
  LivePublisher& publisher_;
  bool gnss_from_gpsd_;
  std::atomic<std::uint64_t> ignored_{0};
};

/// Live mode: `--source udp:|serial:` (line protocol) with an optional `--gnss-source gpsd:...`, or
/// `--source gpsd:...` alone (GNSS only). With both, gpsd is read on its own thread.
int run_live(const odonav::Options& o, odonav::dds::ComponentRuntime& runtime) {
  using namespace odonav::gateway;
  const std::string source_text = o.get_string("source"), gnss_text = o.get_string("gnss-source");
  const bool allow = o.get_bool("allow-non-loopback");
  std::optional<LiveSourceSpec> line_spec;
  std::optional<GpsdSourceSpec> gpsd_spec;
  if (is_gpsd_source(source_text)) {
    if (!gnss_text.empty())
      throw odonav::ConfigError("--gnss-source '" + gnss_text + "': --source " + source_text +
                                " already gives the GNSS; --gnss-source goes with --source udp:... or serial:...");
    gpsd_spec = parse_gpsd_source(source_text, allow, "--source");
  } else {
    line_spec = parse_live_source(source_text, allow);
    if (!gnss_text.empty()) gpsd_spec = parse_gpsd_source(gnss_text, allow, "--gnss-source");
  }
  const double utc_origin_s = o.get_double("gnss-utc-origin-s");

  std::unique_ptr<ByteSource> source;
  if (line_spec) {
    try {
      source = open_live_source(*line_spec);
    } catch (const std::runtime_error& e) {
      spdlog::error("{}", e.what());
      return 1;
    }
    spdlog::info("listening on {} (line protocol, README.md)", to_string(*line_spec));
  }
  LivePublisher publisher(runtime);
  LineSink line_sink(publisher, gpsd_spec.has_value());
  LineDecoder decoder;
  LiveInputStats stats;
  GpsdCounters gpsd_counters;
  std::mutex gpsd_mutex;
  auto gpsd_snapshot = [&]() -> std::optional<GpsdCounters> {
    if (!gpsd_spec) return std::nullopt;
    const std::lock_guard<std::mutex> lock(gpsd_mutex);
    return gpsd_counters;
  };
  // Health is published from one thread only (the main loop's periodic call).
  auto health = [&](odonav::msg::HealthState state, const std::string& reason, bool force) {
    publisher.health(state, reason, decoder.counters(), stats, gpsd_snapshot(), line_sink.ignored(), force);
  };
  health(odonav::msg::HEALTH_STATE_RUNNING, "", true);
  auto periodic = [&] {
    runtime.run_pending();  // commands (none supported: acknowledged as rejected), as in replay
    health(odonav::msg::HEALTH_STATE_RUNNING, "", false);
  };
  auto stop = [&] { return runtime.stop_signals().stop_requested(); };
  auto publish_gnss = [&](const odonav::GnssSample& s) { publisher.gnss(s); };

  if (gpsd_spec) spdlog::info("reading GNSS from {} (t = UTC - {} s)", to_string(*gpsd_spec), utc_origin_s);
  if (line_spec) {
    std::thread gpsd_thread;
    if (gpsd_spec)
      gpsd_thread = std::thread([&] { run_gpsd_input(*gpsd_spec, utc_origin_s, publish_gnss, stop, [] {}, gpsd_counters, gpsd_mutex); });
    try {
      run_live_input(std::move(source), decoder, line_sink, stop, periodic, [&] { return open_live_source(*line_spec); },
                     stats);
    } catch (...) {
      runtime.stop_signals().request_stop();
      if (gpsd_thread.joinable()) gpsd_thread.join();
      throw;
    }
    if (gpsd_thread.joinable()) gpsd_thread.join();
  } else {
    run_gpsd_input(*gpsd_spec, utc_origin_s, publish_gnss, stop, periodic, gpsd_counters, gpsd_mutex);
  }
  publisher.wait_for_acknowledgments();
  const std::string reason = "interrupted at t=" + std::to_string(publisher.last_t_s()) + " s";
  spdlog::info("{}: {} lines, {} rejected", reason, decoder.counters().lines, decoder.counters().total_errors());
  if (gpsd_spec) {
    const GpsdCounters g = *gpsd_snapshot();
    spdlog::info("gpsd: {} reports, {} without time, {} backwards and {} repeated dropped, {} connection failures",
                 g.reports, g.no_time, g.time_backwards, g.repeated, g.connection_failures);
  }
  health(odonav::msg::HEALTH_STATE_STOPPING, reason, true);
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
      "devices (--source udp:... or serial:..., optionally with --gnss-source gpsd:...) or gpsd (--source gpsd:...). Exits 0 at the end of the data or on SIGINT/SIGTERM.",
      [](odonav::Options& o) { odonav::gateway::add_gateway_options(o); },
      [](const odonav::Options& o, odonav::dds::ComponentRuntime& runtime) {
        if (odonav::gateway::is_live_source(o.get_string("source")) ||
            odonav::gateway::is_gpsd_source(o.get_string("source")))
          return run_live(o, runtime);
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
