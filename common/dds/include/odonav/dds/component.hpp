#pragma once
// What every odonav DDS component process shares, so all behave alike: the common flags, the participant and
// health publisher, the operator command subscription, SIGINT/SIGTERM handling, and the one place
// where a component's tasks (its readers' samples, commands) are executed, one at a time.
//
//   int main(int argc, char** argv) {
//     return odonav::dds::run_component(argc, argv, "odonav-calibration", "...",
//         [](odonav::Options& o) { /* declare the core's own options */ },
//         [](const odonav::Options& o, odonav::dds::ComponentRuntime& rt) { /* build node, run */ });
//   }
//
// Exit codes: 0 normal end (also after SIGINT/SIGTERM and --help), 2 bad configuration (a flag,
// the config file, a profile file or profile name, a domain id: the message names it), 1 any other
// failure.
#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>

#include "odonav/config.hpp"
#include "odonav/dds/endpoints.hpp"
#include "odonav/dds/health.hpp"
#include "odonav/dds/participant.hpp"
#include "odonav/msg/Command.h"
#include "odonav/task_dispatcher.hpp"

namespace odonav::dds {

/// Settings every component takes from its flags.
struct ComponentSettings {
  std::string component;   ///< e.g. "odonav-calibration": health key, command target, logger name.
  std::string vehicle_id;  ///< key of everything published; only this vehicle's inputs are used.
  ParticipantOptions participant;
  double max_wait_s = 2.0;  ///< event-time alignment: how long an input may lag silently (s).
  std::string log_level;    ///< empty: ODONAV_LOG_LEVEL or info.
};

/// The participant options of every odonav program: --domain (0..232, default 0; domain_help says
/// what shares it), --profile (participant XML file; empty = $FASTRTPS_DEFAULT_PROFILES_FILE),
/// --profile-name (default "loopback_only"). The DDS Security options (add_security_options) are
/// declared beside them by the caller; participant_options_from reads them.
void add_participant_options(Options& options, const std::string& domain_help);
/// Reads them back for a participant named participant_name. Throws ConfigError naming the flag
/// when no profile file is given and FASTRTPS_DEFAULT_PROFILES_FILE is unset, or the name is empty.
ParticipantOptions participant_options_from(const Options& options, const std::string& participant_name);

/// Declares --domain (0..232, default 0), --profile (participant XML file; empty =
/// $FASTRTPS_DEFAULT_PROFILES_FILE), --profile-name (default "loopback_only"), --vehicle-id
/// (default "vehicle-01"), --max-wait-s (s, (0, 3600], default 2) and --log-level.
void add_component_options(Options& options);
/// Reads them back. Throws ConfigError naming the flag when a value is unusable (empty vehicle id,
/// no profile file and FASTRTPS_DEFAULT_PROFILES_FILE unset).
ComponentSettings component_settings_from(const Options& options, const std::string& component);

/// Monotonic wall clock (s, arbitrary origin): for maximum waits and rates.
double steady_now_s();
/// UNIX time (s): the stamp of Health messages ("component clock at publication").
double unix_now_s();

/// SIGINT / SIGTERM as a flag. Construct it in main() BEFORE any other thread exists (it blocks the
/// two signals for the calling thread, and threads created afterwards inherit that), so the
/// signals are received only by its own waiting thread, never in the middle of middleware code.
class StopSignals {
 public:
  StopSignals();
  ~StopSignals();
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;

  bool stop_requested() const { return stop_.load(); }
  /// The signal received (SIGINT, SIGTERM), 0 if none.
  int signal_number() const { return signal_.load(); }
  /// Requests the stop as a signal would (tests, fatal conditions).
  void request_stop() { stop_.store(true); }

 private:
  std::atomic<bool> stop_{false};
  std::atomic<int> signal_{0};
  std::atomic<bool> quit_{false};
  std::thread waiter_;
};

/// The participant, health publisher and command subscription of one component, and the execution of
/// its tasks. The component's own readers post their samples here (post()); while run() runs, each
/// task is executed, followed by the tick function, and the tick function also runs at least every
/// tick period, until a stop is requested. Tasks and ticks never run concurrently (one mutex), so a
/// node's state needs no locking of its own.
///
/// Where a task runs (TaskDispatcher::Mode, odonav/task_dispatcher.hpp, which does it):
/// - kQueued (default): queued, and executed in order by the thread that called run(), in batches. The
///   listener thread only copies the sample; a slow task (file I/O) never delays reception.
/// - kOnPost: executed at once by the thread that posts it (a Fast DDS listener thread),
///   under the mutex; run()'s thread only ticks every tick period. This saves a thread wake-up and
///   two context switches per sample (the largest per-sample cost at 100 Hz inputs, docs/DESIGN_DECISIONS.md),
///   and an output leaves on the thread that received its last input. For nodes whose tasks
///   are short and never block (the event-time nodes: a core step and non-blocking KEEP_LAST
///   writes). Tasks posted before run() and after the stop are queued and run by run() and
///   run_pending() as with the worker, so the drain is the same.
class ComponentRuntime {
 public:
  /// Executes one operator command addressed to this component (where tasks run, see the class comment); returns the
  /// acknowledgement carried by the following Health messages.
  using CommandHandler = std::function<CommandAck(const odonav::msg::Command& command)>;

  /// Creates the participant (named after the component), the health writer and the command
  /// reader. Throws std::runtime_error naming the profile file, profile name or domain on failure.
  ComponentRuntime(const ComponentSettings& settings, StopSignals& stop);
  ~ComponentRuntime();
  ComponentRuntime(const ComponentRuntime&) = delete;
  ComponentRuntime& operator=(const ComponentRuntime&) = delete;

  const ComponentSettings& settings() const { return settings_; }
  Participant& participant() { return *participant_; }
  HealthPublisher& health() { return *health_; }
  StopSignals& stop_signals() { return stop_; }

  /// Handles the Command topic for this vehicle and component (set once, before run()).
  void set_command_handler(CommandHandler handler);

  /// Where tasks run (see the class comment); set before run(). Default kQueued.
  void set_dispatch(TaskDispatcher::Mode mode) { tasks_.set_mode(mode); }

  /// Executes a task as the dispatch says: queued for run()'s thread, or at once on the calling
  /// thread (kOnPost, while run() runs). Thread-safe (reader callbacks call it).
  void post(std::function<void()> task);
  /// Tasks waiting in the queue (always 0 with kOnPost while run() runs).
  std::size_t queue_depth() const;

  /// Runs posted tasks, and `tick` after each batch of tasks (each task with kOnPost) and
  /// at least every tick_period, until a stop is requested. Returns then (queued tasks stay queued;
  /// tasks posted from then on are queued).
  void run(const std::function<void()>& tick, std::chrono::milliseconds tick_period = std::chrono::milliseconds(100));
  /// Runs every task queued now (after the readers are gone: the drain).
  void run_pending();

  /// Publishes Health if a second has passed since the last (force: now, e.g. a state change; also
  /// forced once after each command so its acknowledgement is seen at once).
  /// Counters are the caller's; the acknowledgement is the last command's. With DDS Security, a
  /// participant of the domain it exchanges no data with turns an OK level into WARN, with the
  /// reason "DDS Security refused '<name>'" or "DDS Security handshake with '<name>' incomplete for
  /// N s" (pending for kHandshakeStalledAfter), "(and N more)", and the counter
  /// dds_unauthenticated_participants; an incomplete handshake is also logged once as a warning
  /// (within a budget: a flood of strangers with credentials costs a few lines, then a count).
  void publish_health(odonav::msg::HealthState state, odonav::msg::HealthLevel level, const std::string& reason,
                      const HealthCounters& counters, bool force = false);

  /// A handshake normally completes within about a second (its messages are resent every second).
  static constexpr std::chrono::seconds kHandshakeStalledAfter{10};

 private:
  void on_command(const odonav::msg::Command& command);

  ComponentSettings settings_;
  StopSignals& stop_;
  std::unique_ptr<Participant> participant_;
  std::unique_ptr<HealthPublisher> health_;
  CommandHandler command_handler_;
  bool ack_pending_ = false;  // set and read in tasks and ticks: a command was acknowledged, tell it at once
  std::set<std::string> stalled_handshakes_warned_;  // GUIDs already logged as incomplete, while listed
  LogBudget stalled_handshake_log_{5, std::chrono::seconds(10)};
  std::unique_ptr<Reader<odonav::msg::Command>> commands_;

  TaskDispatcher tasks_;
};

/// The main() of a component: declares the common options and the component's own (declare),
/// parses argv (--help prints the usage and returns 0), sets up logging (spdlog, stderr), creates
/// the runtime and calls run(options, runtime). Maps errors to exit codes (see the file comment)
/// after logging them; `run`'s return value is the exit code otherwise.
int run_component(int argc, char** argv, const std::string& component, const std::string& description,
                  const std::function<void(Options&)>& declare,
                  const std::function<int(const Options&, ComponentRuntime&)>& run);

/// Waits (bounded by timeout) until every matched reader acknowledged what `writer` wrote; logs a
/// warning naming the topic when it did not. Returns whether everything was acknowledged.
bool wait_for_acknowledgments_logged(detail::WriterBase& writer, std::chrono::milliseconds timeout);

}  // namespace odonav::dds
