// odonav-ground: the ground station (README.md): fleet monitor, MCAP recorder, operator commands.
#include <unistd.h>
#include <sys/ioctl.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <sstream>
#include <thread>
#include <tuple>

#include "odonav/ground/fleet_state.hpp"
#include "odonav/ground/mcap_writer.hpp"
#include "odonav/ground/recording.hpp"
#include "odonav/ground/web_api.hpp"
#include "node/ground_node.hpp"
#include "web/ground_web.hpp"
#include "odonav/config.hpp"
#include "odonav/dds/component.hpp"
#include "odonav/dds/security.hpp"
#include "odonav/logging.hpp"
#include "odonav/tool_output.hpp"

namespace {

using namespace odonav;
using namespace odonav::ground;

constexpr int kExitOk = 0;
constexpr int kExitFailure = 1;  // also: command rejected
constexpr int kExitConfig = 2;
constexpr int kExitTimeout = 3;  // command: no acknowledgement in time

// The options every subcommand shares (before or after its name), then each subcommand's own.
void declare_options(Options& o) {
  odonav::dds::add_participant_options(o, "DDS domain id of the fleet");
  o.add_string("log-level", "", std::string("log level (") + kLogLevelNames + "); empty = $ODONAV_LOG_LEVEL or info");
  // DDS Security (secure profile): --security-dir / --security-identity, else the environment.
  odonav::dds::add_security_options(o);

  Options& monitor = o.add_subcommand("monitor", "live dashboard of every vehicle");
  monitor.add_string("vehicle", "", "vehicle ids to show, comma separated (empty: all)");
  monitor.add_bool("once", false, "print one snapshot after --settle-s and exit");
  monitor.add_bool("json", false, "the snapshot as JSON (with --once: exactly one JSON document on stdout)");
  monitor.add_double("settle-s", 2.0, "with --once: how long to listen before the snapshot (s)", 0.0, 3600.0);
  monitor.add_double("refresh-s", 0.5, "refresh period (s); in a pipe at least 5 s unless given", 0.05, 3600.0);

  Options& serve = o.add_subcommand("serve", "fleet page and Foxglove WebSocket");
  serve.add_int("port", 8765, "TCP port of the page and the Foxglove WebSocket (0: any free port)", 0, 65535);
  serve.add_string("bind", "127.0.0.1", "address to listen on (a warning when not loopback)");
  serve.add_string("token", "", "the token commands from the web need (empty: commands disabled)");
  serve.add_string("token-file", "", "read the token from the first line of this file instead");
  serve.add_double("diagnostics-period-s", 0.5, "DiagnosticArray of each vehicle this often (s)", 0.05, 60.0);
  serve.add_int("client-queue-kib", 4096, "data queued per Foxglove client before its frames are dropped (KiB)", 16,
                1 << 20);
  serve.add_double("forget-after-s", 60.0, "unadvertise a channel silent this long (s)", 1.0, 1e6);

  Options& record = o.add_subcommand("record", "MCAP recording (ros2msg + cdr)");
  record.add_string("out", "", "the MCAP file to write (required)");
  record.add_string("topics", "",
                    "topics, comma separated (odometer, ins/attitude, gnss/fix, misalignment, scale_factor, "
                    "dead_reckoning, health, command); empty = all");
  record.add_double("duration-s", 0.0, "stop after this many seconds (0: until SIGINT/SIGTERM)", 0.0, 1e9);
  record.add_bool("best-effort", false,
                  "read every topic best effort (weak links: odonav_ground_reader_best_effort) instead of reliably");

  Options& command = o.add_subcommand("command", "send an operator command to one component of one vehicle");
  command.add_positional("command", "reset | set-k | freeze | unfreeze | release-k", false);
  command.add_positional("value", "set-k: K in metres per pulse", false);
  command.add_string("vehicle", "", "the vehicle (exactly one id; required)");
  command.add_string("component", "", "the addressed component, e.g. odonav-identification (required)");
  command.add_double("timeout-s", 5.0, "how long to wait for the acknowledgement (s)", 0.01, 3600.0);
}

odonav::dds::ParticipantOptions participant_options(const Options& o) {
  return odonav::dds::participant_options_from(o, "odonav-ground");
}

std::vector<std::string> split_list(const std::string& s) {
  std::vector<std::string> items;
  std::istringstream in(s);
  std::string item;
  while (std::getline(in, item, ','))
    if (!item.empty()) items.push_back(item);
  return items;
}

/// Sleeps up to seconds, in small steps, returning early when a stop is requested.
void sleep_unless_stopped(double seconds, const odonav::dds::StopSignals& stop) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::microseconds(static_cast<long long>(seconds * 1e6));
  while (!stop.stop_requested() && std::chrono::steady_clock::now() < end)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
}

int run_monitor(const Options& o, odonav::dds::StopSignals& stop) {
  const std::vector<std::string> only = split_list(o.get_string("vehicle"));
  odonav::dds::Participant participant(participant_options(o));
  FleetState state;
  FleetMonitor monitor(participant, state, odonav::dds::steady_now_s);
  std::ostringstream title;
  title << "odonav-ground  domain " << participant.domain_id();
  std::ostream& out = tool_output();

  if (o.get_bool("once")) {
    sleep_unless_stopped(o.get_double("settle-s"), stop);
    const FleetSnapshot snap = state.snapshot(odonav::dds::steady_now_s(), only);
    if (o.get_bool("json")) {
      nlohmann::json j = snapshot_json(snap);
      j["domain"] = participant.domain_id();
      out << j.dump(2) << std::endl;
    } else {
      out << render_dashboard(snap, 80, 24, false, title.str()) << std::flush;
    }
    return kExitOk;
  }

  const bool tty = ::isatty(STDOUT_FILENO) == 1;
  double refresh_s = o.get_double("refresh-s");
  if (!tty && !o.was_set("refresh-s")) refresh_s = 5.0;  // a log file wants snapshots, not a movie
  if (tty) out << "\x1b[?25l";                           // hide the cursor while redrawing
  while (!stop.stop_requested()) {
    const FleetSnapshot snap = state.snapshot(odonav::dds::steady_now_s(), only);
    if (o.get_bool("json")) {
      nlohmann::json j = snapshot_json(snap);
      j["domain"] = participant.domain_id();
      out << j.dump() << std::endl;  // one JSON document per line
    } else if (tty) {
      int width = 80, height = 24;
      winsize ws{};
      if (::ioctl(STDOUT_FILENO, TIOCGWINSZ, &ws) == 0 && ws.ws_col > 0 && ws.ws_row > 0) {
        width = ws.ws_col;
        height = ws.ws_row - 1;  // the cursor's line
      }
      out << "\x1b[H\x1b[2J" << render_dashboard(snap, width, height, true, title.str()) << std::flush;
    } else {
      out << render_dashboard(snap, 80, 24, false, title.str()) << "\n" << std::flush;
    }
    sleep_unless_stopped(refresh_s, stop);
  }
  if (tty) out << "\x1b[?25h" << std::flush;
  return kExitOk;
}

int run_record(const Options& o, odonav::dds::StopSignals& stop) {
  const std::string path = o.get_string("out");
  if (path.empty()) throw ConfigError("record: --out FILE.mcap is required");
  std::vector<topics::TopicSpec> chosen;
  try {
    chosen = select_topics(o.get_string("topics"));
  } catch (const std::invalid_argument& e) {
    throw ConfigError(e.what());
  }
  const double duration_s = o.get_double("duration-s");
  odonav::dds::Participant participant(participant_options(o));
  McapWriter writer(path);
  TopicRecorder recorder(participant, writer, chosen, o.get_bool("best-effort"));
  spdlog::info("recording {} topic(s) to {}{}", chosen.size(), path,
               duration_s > 0 ? " for " + std::to_string(duration_s) + " s" : std::string(" until SIGINT"));
  const double start_s = odonav::dds::steady_now_s();
  double last_flush_s = start_s;
  double last_progress_s = start_s;
  double last_diagnostics_s = start_s;
  while (!stop.stop_requested()) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    const double now_s = odonav::dds::steady_now_s();
    if (duration_s > 0.0 && now_s - start_s >= duration_s) break;
    // The standard diagnostics channel, as odonav-ground serve sends it live.
    if (now_s - last_diagnostics_s >= 0.5) {
      recorder.write_diagnostics();
      last_diagnostics_s = now_s;
    }
    // Every second: what a crash may lose.
    if (now_s - last_flush_s >= 1.0) {
      writer.flush();
      last_flush_s = now_s;
    }
    if (now_s - last_progress_s >= 10.0) {
      spdlog::info("recorded {} messages; {} of {} topics have a writer", writer.message_count(),
                   recorder.matched_topics(), recorder.topic_count());
      last_progress_s = now_s;
    }
  }
  recorder.stop();
  writer.close();
  const std::uint64_t standard = recorder.standard_messages();
  tool_output() << "recorded " << writer.message_count() - standard << " messages on " << chosen.size()
                << " topics and " << standard << " on the standard channels (NavSatFix, DiagnosticArray) to " << path
                << std::endl;
  return recorder.failures() == 0 ? kExitOk : kExitFailure;
}

bool is_loopback(const std::string& address) {
  return address == "localhost" || address == "::1" || address.rfind("127.", 0) == 0;
}

int run_serve(const Options& o, odonav::dds::StopSignals& stop) {
  ServeOptions serve;
  if (o.was_set("token") && o.was_set("token-file")) throw ConfigError("serve: give --token or --token-file, not both");
  serve.token = o.get_string("token");
  if (o.was_set("token") && serve.token.empty()) throw ConfigError("serve: --token must not be empty");
  if (!o.get_string("token-file").empty()) {
    try {
      serve.token = read_token_file(o.get_string("token-file"));
    } catch (const std::runtime_error& e) {
      throw ConfigError(e.what());
    }
  }
  serve.diagnostics_period_s = o.get_double("diagnostics-period-s");
  serve.forget_after_s = o.get_double("forget-after-s");
  WebServerOptions web;
  web.bind_address = o.get_string("bind");
  web.port = static_cast<int>(o.get_int("port"));
  web.max_queued_bytes_per_client = static_cast<std::size_t>(o.get_int("client-queue-kib")) * 1024;
  if (!is_loopback(web.bind_address)) {
    spdlog::warn(
        "serve: listening on {}, not loopback: the page and the Foxglove channels are readable by anyone "
        "who reaches this address{}",
        web.bind_address, serve.token.empty() ? "" : " (commands still need the token)");
  }
  odonav::dds::Participant participant(participant_options(o));
  serve.domain = participant.domain_id();
  web.metadata = {{"domain", std::to_string(participant.domain_id())}};
  GroundWeb ground(participant, serve, web);
  ground.start();
  const std::string host =
      web.bind_address.find(':') != std::string::npos ? "[" + web.bind_address + "]" : web.bind_address;
  tool_output() << "odonav-ground serve: page http://" << host << ":" << ground.port() << "/  Foxglove ws://" << host
                << ":" << ground.port() << "  (commands "
                << (serve.token.empty() ? "disabled: no --token" : "need the token") << ")" << std::endl;
  spdlog::info("serving domain {} on {}:{}", participant.domain_id(), web.bind_address, ground.port());
  while (!stop.stop_requested()) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    ground.tick(odonav::dds::steady_now_s());
  }
  ground.stop();
  const auto st = ground.stats();
  spdlog::info("serve: stopped; {} frames sent, {} dropped for slow clients", st.frames_sent, st.frames_dropped);
  return kExitOk;
}

int run_command(const Options& o) {
  CommandRequest request;
  request.vehicle_id = o.get_string("vehicle");
  request.component = o.get_string("component");
  if (request.vehicle_id.empty() || request.vehicle_id.find(',') != std::string::npos) {
    throw ConfigError("command: --vehicle ID (exactly one vehicle) is required");
  }
  if (request.component.empty()) throw ConfigError("command: --component NAME is required");
  if (!o.was_set("command")) throw ConfigError("command: which one? reset, set-k VALUE, freeze, unfreeze, release-k");
  try {
    request.kind = parse_command_kind(o.get_string("command"));
  } catch (const std::invalid_argument& e) {
    throw ConfigError(std::string("command: ") + e.what());
  }
  if (request.kind == odonav::msg::COMMAND_SET_K) {
    if (!o.was_set("value")) throw ConfigError("command set-k: the value (K in m/pulse) is missing");
    const std::string text = o.get_string("value");
    char* end = nullptr;
    request.value = std::strtod(text.c_str(), &end);
    if (end == text.c_str() || *end != '\0' || !std::isfinite(request.value) || request.value <= 0.0) {
      throw ConfigError("command set-k: value '" + text + "' is not a positive number of metres per pulse");
    }
  } else if (o.was_set("value")) {
    throw ConfigError("command " + o.get_string("command") + ": takes no value (got '" + o.get_string("value") + "')");
  }
  request.timeout_s = o.get_double("timeout-s");
  odonav::dds::Participant participant(participant_options(o));
  const CommandReply reply = send_command(participant, request);
  std::ostringstream what;
  what << request.vehicle_id << " " << request.component << ": " << command_kind_name(request.kind);
  if (request.kind == odonav::msg::COMMAND_SET_K) what << " " << o.get_string("value");
  what << " (command " << reply.command_id << ") ";
  switch (reply.outcome) {
    case CommandOutcome::kAccepted:
      tool_output() << what.str() << "ACCEPTED: " << reply.detail << std::endl;
      return kExitOk;
    case CommandOutcome::kRejected:
      tool_output() << what.str() << "REJECTED: " << reply.detail << std::endl;
      return kExitFailure;
    case CommandOutcome::kTimeout: break;
  }
  tool_output() << what.str() << "TIMEOUT: " << reply.detail << std::endl;
  return kExitTimeout;
}

}  // namespace

int main(int argc, char** argv) {
  // Before any thread exists: SIGINT/SIGTERM become a flag (see StopSignals).
  odonav::dds::StopSignals stop;
  Options options(
      "odonav-ground",
      "The ground station of an odonav fleet.\n"
      "  odonav-ground monitor [--once --json] [--vehicle ID,...]\n"
      "  odonav-ground serve [--port 8765] [--bind 127.0.0.1] [--token T | --token-file F]\n"
      "  odonav-ground record --out FILE.mcap [--topics a,b] [--duration-s S]\n"
      "  odonav-ground command --vehicle ID --component NAME (reset|set-k VALUE|freeze|unfreeze|release-k)\n"
      "Exit codes: 0 done (command: accepted), 1 failure (command: rejected), 2 bad configuration, "
      "3 command not acknowledged in time.");
  declare_options(options);
  try {
    if (options.parse(argc, argv) == ParseResult::kHelp) return kExitOk;
    setup_logging("odonav-ground", options.get_string("log-level"));
    const Options& sub = *options.subcommand();
    if (sub.name() == "monitor") return run_monitor(sub, stop);
    if (sub.name() == "record") return run_record(sub, stop);
    if (sub.name() == "serve") return run_serve(sub, stop);
    return run_command(sub);
  } catch (const ConfigError& e) {
    // Possibly before logging is set up (spdlog's default logger writes to stdout): stderr directly.
    std::cerr << "odonav-ground: " << e.what() << " (--help for the usage)" << std::endl;
    return kExitConfig;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return kExitFailure;
  }
}
