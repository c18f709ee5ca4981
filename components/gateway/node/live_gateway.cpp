#include "node/live_gateway.hpp"

#include <spdlog/spdlog.h>

#include <atomic>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "core/gpsd_source.hpp"
#include "core/live_input.hpp"
#include "core/sensor_health.hpp"
#include "node/sensor_publisher.hpp"
#include "odonav/topics.hpp"

namespace odonav::gateway {

namespace {

/// The line source's samples: odometer and INS always; GNSS lines only when gpsd is not the GNSS
/// source (the lines are then counted, see run_live_gateway).
class LineSink : public SampleSink {
 public:
  LineSink(SensorPublisher& publisher, bool gnss_from_gpsd) : publisher_(publisher), gnss_from_gpsd_(gnss_from_gpsd) {}
  void odometer(const OdometerSample& s) override { publisher_.odometer(s); }
  void ins(const InsSample& s) override { publisher_.ins(s); }
  void gnss(const GnssSample& s) override {
    if (gnss_from_gpsd_) {
      if (ignored_++ == 0) spdlog::warn("GNSS lines on the line source are ignored: --gnss-source gives the GNSS");
      return;
    }
    publisher_.gnss(s);
  }
  std::uint64_t ignored() const { return ignored_; }

 private:
  SensorPublisher& publisher_;
  bool gnss_from_gpsd_;
  std::atomic<std::uint64_t> ignored_{0};
};

/// What --source and --gnss-source name: a line source, gpsd, or both.
struct LiveSpecs {
  std::optional<LiveSourceSpec> line;
  std::optional<GpsdSourceSpec> gpsd;
  double utc_origin_s = 0.0;  ///< gpsd: t = UTC - utc_origin_s.
};

LiveSpecs parse_live_specs(const Options& o) {
  const std::string source_text = o.get_string("source"), gnss_text = o.get_string("gnss-source");
  const bool allow = o.get_bool("allow-non-loopback");
  LiveSpecs specs;
  if (is_gpsd_source(source_text)) {
    if (!gnss_text.empty())
      throw ConfigError("--gnss-source '" + gnss_text + "': --source " + source_text +
                        " already gives the GNSS; --gnss-source goes with --source udp:... or serial:...");
    specs.gpsd = parse_gpsd_source(source_text, allow, "--source");
  } else {
    specs.line = parse_live_source(source_text, allow);
    if (!gnss_text.empty()) specs.gpsd = parse_gpsd_source(gnss_text, allow, "--gnss-source");
  }
  specs.utc_origin_s = o.get_double("gnss-utc-origin-s");
  return specs;
}

/// One live run: the publisher, the inputs' counters and the Health built from them.
class LiveGateway {
 public:
  LiveGateway(dds::ComponentRuntime& runtime, LiveSpecs specs)
      : runtime_(runtime),
        specs_(std::move(specs)),
        publisher_(runtime, topics::kSensorWriterProfile),
        line_sink_(publisher_, specs_.gpsd.has_value()) {}

  int run(std::unique_ptr<ByteSource> source) {
    health(odonav::msg::HEALTH_STATE_RUNNING, "", true);
    if (specs_.gpsd)
      spdlog::info("reading GNSS from {} (t = UTC - {} s)", to_string(*specs_.gpsd), specs_.utc_origin_s);
    if (specs_.line) run_line_input(std::move(source));
    else run_gpsd([this] { periodic(); });
    publisher_.wait_for_acknowledgments(std::chrono::seconds(5));
    finish();
    return 0;
  }

 private:
  std::optional<GpsdCounters> gpsd_snapshot() {
    if (!specs_.gpsd) return std::nullopt;
    const std::lock_guard<std::mutex> lock(gpsd_mutex_);
    return gpsd_counters_;
  }
  // Published from one thread only (the main loop's periodic call, and at start and end).
  void health(odonav::msg::HealthState state, const std::string& reason, bool force) {
    publisher_.publish_health(state, reason,
                              live_source_health(decoder_.counters(), stats_, gpsd_snapshot(), line_sink_.ignored()),
                              force);
  }
  void periodic() {
    runtime_.run_pending();  // commands (none supported: acknowledged as rejected), as in replay
    health(odonav::msg::HEALTH_STATE_RUNNING, "", false);
  }
  bool stop_requested() { return runtime_.stop_signals().stop_requested(); }
  void run_gpsd(const std::function<void()>& periodic_work) {
    run_gpsd_input(*specs_.gpsd, specs_.utc_origin_s, [this](const GnssSample& s) { publisher_.gnss(s); },
                   [this] { return stop_requested(); }, periodic_work, gpsd_counters_, gpsd_mutex_);
  }
  // The line source on this thread, gpsd (if any) on its own.
  void run_line_input(std::unique_ptr<ByteSource> source) {
    std::thread gpsd_thread;
    if (specs_.gpsd) gpsd_thread = std::thread([this] { run_gpsd([] {}); });
    try {
      run_live_input(std::move(source), decoder_, line_sink_, [this] { return stop_requested(); },
                     [this] { periodic(); }, [this] { return open_live_source(*specs_.line); }, stats_);
    } catch (...) {
      runtime_.stop_signals().request_stop();
      if (gpsd_thread.joinable()) gpsd_thread.join();
      throw;
    }
    if (gpsd_thread.joinable()) gpsd_thread.join();
  }
  void finish() {
    const std::string reason = "interrupted at t=" + std::to_string(publisher_.counts().last_t_s) + " s";
    spdlog::info("{}: {} lines, {} rejected", reason, decoder_.counters().lines, decoder_.counters().total_errors());
    if (specs_.gpsd) {
      const GpsdCounters g = *gpsd_snapshot();
      spdlog::info("gpsd: {} reports, {} without time, {} backwards and {} repeated dropped, {} connection failures",
                   g.reports, g.no_time, g.time_backwards, g.repeated, g.connection_failures);
    }
    health(odonav::msg::HEALTH_STATE_STOPPING, reason, true);
    dds::wait_for_acknowledgments_logged(runtime_.health().writer(), std::chrono::seconds(1));
  }

  dds::ComponentRuntime& runtime_;
  const LiveSpecs specs_;
  SensorPublisher publisher_;
  LineSink line_sink_;
  LineDecoder decoder_;
  LiveInputStats stats_;
  GpsdCounters gpsd_counters_;
  std::mutex gpsd_mutex_;
};

}  // namespace

bool is_live_mode(const Options& options) {
  const std::string source = options.get_string("source");
  return is_live_source(source) || is_gpsd_source(source);
}

int run_live_gateway(const Options& options, dds::ComponentRuntime& runtime) {
  LiveSpecs specs = parse_live_specs(options);
  std::unique_ptr<ByteSource> source;
  if (specs.line) {
    try {
      source = open_live_source(*specs.line);
    } catch (const std::runtime_error& e) {
      spdlog::error("{}", e.what());
      return 1;
    }
    spdlog::info("listening on {} (line protocol, README.md)", to_string(*specs.line));
  }
  LiveGateway gateway(runtime, std::move(specs));
  return gateway.run(std::move(source));
}

}  // namespace odonav::gateway
