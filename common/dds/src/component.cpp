// Component scaffolding: flags, signals, worker queue, health and commands (see component.hpp).
#include "odonav/dds/component.hpp"

#include <pthread.h>
#include <signal.h>
#include <time.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <iterator>
#include <stdexcept>
#include <tuple>

#include "odonav/dds/security.hpp"
#include "odonav/logging.hpp"
#include "odonav/topics.hpp"

namespace odonav::dds {

void add_participant_options(Options& o, const std::string& domain_help) {
  o.add_int("domain", 0, domain_help, 0, 232);
  o.add_string("profile", "",
               "Fast DDS XML file with the participant profile (qos.xml is read from its directory); "
               "empty = $FASTRTPS_DEFAULT_PROFILES_FILE");
  o.add_string("profile-name", topics::kLoopbackParticipantProfile, "participant profile name in --profile");
}

ParticipantOptions participant_options_from(const Options& o, const std::string& participant_name) {
  ParticipantOptions p;
  const std::optional<std::string> file = profiles_file_or_environment(o.get_string("profile"));
  if (!file)
    throw ConfigError(
        "--profile: not given and FASTRTPS_DEFAULT_PROFILES_FILE is not set (use e.g. "
        "--profile deploy/profiles/loopback.xml)");
  p.profiles_file = *file;
  p.participant_profile = o.get_string("profile-name");
  if (p.participant_profile.empty()) throw ConfigError("--profile-name: must not be empty");
  p.domain_id = static_cast<int>(o.get_int("domain"));
  p.participant_name = participant_name;
  std::tie(p.security_dir, p.security_identity) = security_options_from(o);
  return p;
}

void add_component_options(Options& o) {
  add_participant_options(o, "DDS domain id; components of one vehicle share it");
  o.add_string("vehicle-id", "vehicle-01", "vehicle whose topics are read and written (the DDS key)");
  o.add_double("max-wait-s", 2.0,
               "event time: an input silent this long (wall clock, s) while the others are ahead is treated "
               "as absent",
               0.01, 3600.0);
  o.add_string("log-level", "", std::string("log level (") + kLogLevelNames + "); empty = $ODONAV_LOG_LEVEL or info");
  // DDS Security for every component alike (--security-dir / --security-identity, else the
  // environment, else none): the systemd units and the multi-host test switch it on per host.
  add_security_options(o);
}

ComponentSettings component_settings_from(const Options& o, const std::string& component) {
  ComponentSettings s;
  s.component = component;
  s.vehicle_id = o.get_string("vehicle-id");
  if (s.vehicle_id.empty()) throw ConfigError("--vehicle-id: must not be empty");
  s.participant = participant_options_from(o, component);
  s.max_wait_s = o.get_double("max-wait-s");
  s.log_level = o.get_string("log-level");
  if (!s.log_level.empty()) parse_log_level(s.log_level, "--log-level");
  return s;
}

double steady_now_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

double unix_now_s() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

// ---- StopSignals ----

StopSignals::StopSignals() {
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  // Blocked here and in every thread created later: only sigtimedwait below receives them.
  if (const int rc = pthread_sigmask(SIG_BLOCK, &set, nullptr); rc != 0)
    throw std::runtime_error(std::string("StopSignals: pthread_sigmask failed: ") + std::strerror(rc));
  waiter_ = std::thread([this, set] {
    // Polls quit_ every 200 ms so the destructor can end the thread without sending a signal.
    const timespec period{0, 200 * 1000 * 1000};
    while (!quit_.load()) {
      const int sig = sigtimedwait(&set, nullptr, &period);
      if (sig == SIGINT || sig == SIGTERM) {
        signal_.store(sig);
        stop_.store(true);
      }
    }
  });
}

StopSignals::~StopSignals() {
  quit_.store(true);
  if (waiter_.joinable()) waiter_.join();
}

// ---- ComponentRuntime ----

ComponentRuntime::ComponentRuntime(const ComponentSettings& settings, StopSignals& stop)
    : settings_(settings), stop_(stop) {
  participant_ = std::make_unique<Participant>(settings_.participant);
  health_ = std::make_unique<HealthPublisher>(*participant_, settings_.vehicle_id, settings_.component);
  commands_ = std::make_unique<Reader<odonav::msg::Command>>(*participant_, topics::kCommand.name,
                                                             topics::kCommand.reader_profile,
                                                             [this](const odonav::msg::Command& c) { on_command(c); });
}

ComponentRuntime::~ComponentRuntime() {
  commands_.reset();  // no command callback after this
}

void ComponentRuntime::set_command_handler(CommandHandler handler) { command_handler_ = std::move(handler); }

void ComponentRuntime::on_command(const odonav::msg::Command& command) {
  // Listener thread: filter, then hand over to the worker.
  if (command.vehicle_id() != settings_.vehicle_id || command.target_component() != settings_.component) return;
  post([this, command] {
    CommandAck ack{command.command_id(), odonav::msg::COMMAND_RESULT_REJECTED, "command not supported"};
    if (command_handler_) ack = command_handler_(command);
    ack.command_id = command.command_id();
    spdlog::info("command {} (kind {}): {} {}", command.command_id(), static_cast<int>(command.command()),
                 ack.result == odonav::msg::COMMAND_RESULT_ACCEPTED ? "accepted" : "rejected", ack.detail);
    health_->acknowledge(ack.command_id, ack.result, ack.detail);
    ack_pending_ = true;
  });
}

void ComponentRuntime::post(std::function<void()> task) { tasks_.post(std::move(task)); }

std::size_t ComponentRuntime::queue_depth() const { return tasks_.queue_depth(); }

void ComponentRuntime::run(const std::function<void()>& tick, std::chrono::milliseconds tick_period) {
  tasks_.run([this] { return stop_.stop_requested(); }, tick, tick_period);
}

void ComponentRuntime::run_pending() { tasks_.run_pending(); }

void ComponentRuntime::publish_health(odonav::msg::HealthState state, odonav::msg::HealthLevel level,
                                      const std::string& reason_in, const HealthCounters& counters_in, bool force) {
  const double now = unix_now_s();
  if (ack_pending_) force = true;
  ack_pending_ = false;
  // A producer discovered (its writer matched) that sends nothing while the others do: cut off or
  // stalled. Each silence is logged once when it starts and once when it ends, and Health is sent
  // at once on either edge.
  std::string reason = reason_in;
  HealthCounters counters = counters_in;
  PeerTracker& peers = participant_->core()->peers();
  const double steady = steady_now_s();
  for (const auto& e : peers.edges(steady)) {
    force = true;
    if (e.silent)
      spdlog::warn(
          "no {} from {} for {:.1f} s although it is matched and others are heard (cut off, stalled, "
          "or gone without leaving)",
          e.who.stream, e.who.peer, e.who.silent_s);
    else
      spdlog::info("{} from {} heard again", e.who.stream, e.who.peer);
  }
  if (state != odonav::msg::HEALTH_STATE_STOPPING) {
    const auto silent = peers.silent(steady);
    counters.emplace_back("peers_silent", static_cast<double>(silent.size()));
    if (const auto r = peers.reason(steady)) {
      if (level == odonav::msg::HEALTH_LEVEL_OK) level = odonav::msg::HEALTH_LEVEL_WARN;
      reason = reason.empty() ? *r : *r + "; " + reason;
    }
  }
  const auto publish = [&](odonav::msg::HealthLevel l, const std::string& r, const HealthCounters& c) {
    if (force)
      health_->publish_now(now, state, l, r, c);
    else
      health_->publish_if_due(now, state, l, r, c);
  };
  // A secure peer whose handshake never completes gets no data and raises no error in Fast DDS,
  // and a refused one is someone on the network without our credentials: say so where the ground
  // station looks (deploy/README.md "DDS Security and Fast DDS 2.9").
  const auto strangers = participant_->unauthenticated_participants(kHandshakeStalledAfter);
  if (strangers.empty()) {
    stalled_handshakes_warned_.clear();
    publish(level, reason, counters);
    return;
  }
  std::set<std::string> listed;
  for (const auto& p : strangers) {
    listed.insert(p.guid);
    if (!p.refused && stalled_handshakes_warned_.insert(p.guid).second) {
      const auto grant = stalled_handshake_log_.take(std::chrono::steady_clock::now());
      if (!grant.log) continue;
      spdlog::warn(
          "DDS Security handshake with participant '{}' ({}) incomplete after {:.0f} s: no data flows "
          "between us (a peer of another PKI, or see deploy/README.md, DDS Security and Fast DDS 2.9){}",
          p.name, p.guid, p.age_s,
          grant.left_out == 0 ? std::string() : " (" + std::to_string(grant.left_out) + " more not logged)");
    }
  }
  // Forget those that left: the set stays as large as the list (bounded by the participant's).
  for (auto it = stalled_handshakes_warned_.begin(); it != stalled_handshakes_warned_.end();)
    it = listed.count(*it) == 0 ? stalled_handshakes_warned_.erase(it) : std::next(it);
  const auto& first = strangers.front();
  const std::string stranger = (first.refused ? "DDS Security refused '" + first.name + "'"
                                              : "DDS Security handshake with '" + first.name + "' incomplete for " +
                                                    std::to_string(static_cast<long>(first.age_s)) + " s") +
                               (strangers.size() > 1 ? " (and " + std::to_string(strangers.size() - 1) + " more)" : "");
  HealthCounters with_count = counters;
  with_count.emplace_back("dds_unauthenticated_participants", static_cast<double>(strangers.size()));
  publish(level == odonav::msg::HEALTH_LEVEL_OK ? odonav::msg::HEALTH_LEVEL_WARN : level,
          reason.empty() ? stranger : reason + "; " + stranger, with_count);
}

bool wait_for_acknowledgments_logged(detail::WriterBase& writer, std::chrono::milliseconds timeout) {
  if (writer.matched_readers() == 0) return true;
  if (writer.wait_for_acknowledgments(timeout)) return true;
  spdlog::warn("not every reader of '{}' acknowledged within {} ms", writer.topic_name(), timeout.count());
  return false;
}

// ---- run_component ----

int run_component(int argc, char** argv, const std::string& component, const std::string& description,
                  const std::function<void(Options&)>& declare,
                  const std::function<int(const Options&, ComponentRuntime&)>& run) {
  try {
    setup_logging(component);
  } catch (const std::exception& e) {
    // Only a bad ODONAV_LOG_LEVEL gets here; fall back to info so the message below is seen.
    setup_logging(component, "info");
    spdlog::error("{}", e.what());
    return 2;
  }
  // Before any thread (the participant starts several): see StopSignals.
  StopSignals stop;
  Options options(component, description);
  ComponentSettings settings;
  try {
    add_component_options(options);
    if (declare) declare(options);
    if (options.parse(argc, argv) == ParseResult::kHelp) return 0;
    settings = component_settings_from(options, component);
    setup_logging(component, settings.log_level);
  } catch (const ConfigError& e) {
    spdlog::error("bad configuration: {}", e.what());
    return 2;
  }
  std::unique_ptr<ComponentRuntime> runtime;
  try {
    runtime = std::make_unique<ComponentRuntime>(settings, stop);
  } catch (const std::exception& e) {
    spdlog::error("bad configuration: {}", e.what());
    return 2;
  }
  try {
    const int code = run(options, *runtime);
    runtime.reset();
    return code;
  } catch (const ConfigError& e) {
    spdlog::error("bad configuration: {}", e.what());
    return 2;
  } catch (const std::exception& e) {
    spdlog::critical("{} failed: {}", component, e.what());
    return 1;
  }
}

}  // namespace odonav::dds
