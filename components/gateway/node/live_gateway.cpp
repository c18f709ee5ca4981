#include "node/live_gateway.hpp"

#include <spdlog/spdlog.h>

#include <atomic>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include <poll.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "odonav/gateway/candump_source.hpp"
#include "odonav/gateway/gpsd_source.hpp"
#include "odonav/gateway/live_input.hpp"
#include "odonav/gateway/sensor_health.hpp"
#include "node/sensor_publisher.hpp"
#include "odonav/topics.hpp"

namespace odonav::gateway {

namespace {

/// The line source's samples: odometer lines unless the CAN input gives the odometer, INS always;
/// GNSS lines only when gpsd is not the GNSS source (dropped lines are counted, see run_live_gateway).
class LineSink : public SampleSink {
 public:
  LineSink(SensorPublisher& publisher, bool gnss_from_gpsd, bool odometer_from_can)
      : publisher_(publisher), gnss_from_gpsd_(gnss_from_gpsd), odometer_from_can_(odometer_from_can) {}
  void odometer(const OdometerSample& s) override {
    if (odometer_from_can_) {
      if (odometer_ignored_++ == 0)
        spdlog::warn("ODO lines on --ins-source are ignored: the CAN input gives the odometer");
      return;
    }
    publisher_.odometer(s);
  }
  void ins(const InsSample& s) override { publisher_.ins(s); }
  void gnss(const GnssSample& s) override {
    if (gnss_from_gpsd_) {
      if (ignored_++ == 0) spdlog::warn("GNSS lines on the line source are ignored: --gnss-source gives the GNSS");
      return;
    }
    publisher_.gnss(s);
  }
  std::uint64_t ignored() const { return ignored_; }
  std::uint64_t odometer_ignored() const { return odometer_ignored_; }

 private:
  SensorPublisher& publisher_;
  bool gnss_from_gpsd_;
  bool odometer_from_can_;
  std::atomic<std::uint64_t> ignored_{0};
  std::atomic<std::uint64_t> odometer_ignored_{0};
};

/// What --source, --ins-source and --gnss-source name: a line source, gpsd, or both; or the CAN
/// input on standard input with an optional line source (INS) and gpsd.
struct LiveSpecs {
  std::optional<LiveSourceSpec> line;
  std::optional<GpsdSourceSpec> gpsd;
  std::optional<CanOdometerConfig> can;  ///< candump:-: the odometer from standard input.
  double utc_origin_s = 0.0;             ///< gpsd: t = UTC - utc_origin_s.
};

constexpr const char* kCandumpStdin = "candump:-";

CanOdometerConfig can_config_from(const Options& o) {
  CanOdometerConfig c;
  c.channels = parse_can_channels(o.get_string("can-odometer"));
  c.pulses_per_m = o.get_double("can-pulses-per-m");
  c.gear_ratio = o.get_double("can-gear-ratio");
  c.sprocket_radius_m = o.get_double("can-sprocket-radius-m");
  c.etc1_pulses_per_rev = o.get_double("can-etc1-pulses-per-rev");
  validate(c);
  return c;
}

LiveSpecs parse_live_specs(const Options& o) {
  const std::string source_text = o.get_string("source"), gnss_text = o.get_string("gnss-source");
  const std::string ins_text = o.get_string("ins-source");
  const bool allow = o.get_bool("allow-non-loopback");
  LiveSpecs specs;
  if (!o.get_string("candump-dataset").empty())
    throw ConfigError("--candump-dataset goes with --source candump:<file> (a recorded log), not " + source_text);
  if (source_text == kCandumpStdin) {
    specs.can = can_config_from(o);
    if (!ins_text.empty()) specs.line = parse_live_source(ins_text, allow);
    if (!gnss_text.empty()) specs.gpsd = parse_gpsd_source(gnss_text, allow, "--gnss-source");
    specs.utc_origin_s = o.get_double("gnss-utc-origin-s");
    return specs;
  }
  if (!ins_text.empty()) throw ConfigError("--ins-source goes with --source candump:-");
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
        line_sink_(publisher_, specs_.gpsd.has_value(), specs_.can.has_value()) {
    if (specs_.can) can_ = std::make_unique<CanOdometer>(*specs_.can);
  }

  int run(std::unique_ptr<ByteSource> source) {
    health(odonav::msg::HEALTH_STATE_RUNNING, "", true);
    if (specs_.gpsd)
      spdlog::info("reading GNSS from {} (t = UTC - {} s)", to_string(*specs_.gpsd), specs_.utc_origin_s);
    std::thread can_thread;
    if (can_) {
      spdlog::info("reading candump -L lines from standard input, odometer channels {}", describe_channels());
      can_thread = std::thread([this] { run_can_input(); });
    }
    try {
      if (specs_.line)
        run_line_input(std::move(source));
      else if (specs_.gpsd)
        run_gpsd([this] { periodic(); });
      else
        while (!stop_requested()) {
          periodic();
          std::this_thread::sleep_for(std::chrono::milliseconds(50));
        }
    } catch (...) {
      runtime_.stop_signals().request_stop();
      if (can_thread.joinable()) can_thread.join();
      throw;
    }
    if (can_thread.joinable()) can_thread.join();
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
    SourceHealth h = live_source_health(decoder_.counters(), stats_, gpsd_snapshot(), line_sink_.ignored());
    if (can_) {
      SourceHealth c = can_source_health(can_snapshot());
      c.counters.emplace_back("odometer_lines_ignored", static_cast<double>(line_sink_.odometer_ignored()));
      c.warn = c.warn || line_sink_.odometer_ignored() > 0;
      h = combine(std::move(h), c);
    }
    publisher_.publish_health(state, reason, h, force);
  }
  CanCounters can_snapshot() {
    const std::lock_guard<std::mutex> lock(can_mutex_);
    return can_->counters();
  }
  std::string describe_channels() const {
    std::string d;
    for (const auto& c : specs_.can->channels) d += (d.empty() ? "" : "; ") + to_string(c);
    return d;
  }
  // Standard input on its own thread: lines as they arrive, each sample published at once with the
  // log's stamp. The end of the input (the pipe closed) ends the run like a signal.
  void run_can_input() {
    CandumpStream stream(*can_);
    std::vector<OdometerSample> samples;
    char buffer[65536];
    bool end = false;
    std::uint64_t unpublishable = 0;
    while (!stop_requested() && !end) {
      pollfd p{STDIN_FILENO, POLLIN, 0};
      const int r = ::poll(&p, 1, 100);
      if (r < 0 && errno == EINTR) continue;
      samples.clear();
      {
        const std::lock_guard<std::mutex> lock(can_mutex_);
        if (r < 0) {
          spdlog::error("candump: standard input: poll: {}", std::strerror(errno));
          end = true;
        } else if (r > 0) {
          const ssize_t n = ::read(STDIN_FILENO, buffer, sizeof(buffer));
          if (n > 0) {
            stream.feed(std::string_view(buffer, static_cast<std::size_t>(n)), samples);
          } else if (n == 0 || errno != EINTR) {
            if (n < 0) spdlog::error("candump: standard input: read: {}", std::strerror(errno));
            stream.finish(samples);
            end = true;
          }
        }
      }
      for (const OdometerSample& s : samples) {
        try {
          publisher_.odometer(s);
        } catch (const std::invalid_argument& e) {  // a stamp the message cannot carry (beyond 2038)
          if (++unpublishable <= 20) spdlog::warn("candump: sample at t={} s not published: {}", s.t_s, e.what());
        }
      }
    }
    if (end) {
      can_ended_ = true;
      spdlog::info("candump: end of standard input");
      runtime_.stop_signals().request_stop();
    }
  }
  void periodic() {
    runtime_.run_pending();  // commands (none supported: acknowledged as rejected), as in replay
    health(odonav::msg::HEALTH_STATE_RUNNING, "", false);
  }
  bool stop_requested() { return runtime_.stop_signals().stop_requested(); }
  void run_gpsd(const std::function<void()>& periodic_work) {
    run_gpsd_input(
        *specs_.gpsd, specs_.utc_origin_s, [this](const GnssSample& s) { publisher_.gnss(s); },
        [this] { return stop_requested(); }, periodic_work, gpsd_counters_, gpsd_mutex_);
  }
  // The line source on this thread, gpsd (if any) on its own.
  void run_line_input(std::unique_ptr<ByteSource> source) {
    std::thread gpsd_thread;
    if (specs_.gpsd) gpsd_thread = std::thread([this] { run_gpsd([] {}); });
    try {
      run_live_input(
          std::move(source), decoder_, line_sink_, [this] { return stop_requested(); }, [this] { periodic(); },
          [this] { return open_live_source(*specs_.line); }, stats_);
    } catch (...) {
      runtime_.stop_signals().request_stop();
      if (gpsd_thread.joinable()) gpsd_thread.join();
      throw;
    }
    if (gpsd_thread.joinable()) gpsd_thread.join();
  }
  void finish() {
    const std::string reason = std::string(can_ended_ ? "end of CAN input at t=" : "interrupted at t=") +
                               std::to_string(publisher_.counts().last_t_s) + " s";
    if (specs_.line || !can_)
      spdlog::info("{}: {} lines, {} rejected", reason, decoder_.counters().lines, decoder_.counters().total_errors());
    if (can_) {
      const CanCounters c = can_snapshot();
      spdlog::info(
          "{}: candump {} lines, {} frames decoded into {} odometer samples; {} malformed, {} unknown, {} out "
          "of order, {} stale, {} undecodable",
          reason, c.lines, c.decoded, c.samples, c.malformed, c.unknown, c.out_of_order, c.stale, c.undecodable);
    }
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
  std::unique_ptr<CanOdometer> can_;  // candump:-; its counters under can_mutex_
  std::mutex can_mutex_;
  std::atomic<bool> can_ended_{false};
};

}  // namespace

bool is_live_mode(const Options& options) {
  const std::string source = options.get_string("source");
  return is_live_source(source) || is_gpsd_source(source) || source == kCandumpStdin;
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
    spdlog::info("listening on {} (line protocol, README.md){}", to_string(*specs.line), specs.can ? " for INS" : "");
  }
  LiveGateway gateway(runtime, std::move(specs));
  return gateway.run(std::move(source));
}

}  // namespace odonav::gateway
