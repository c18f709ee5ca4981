#pragma once
// The skeleton shared by the calibration, identification and dead-reckoning nodes (header-only:
// it needs odonav_samples' EventTimeAligner, which odonav_dds does not link).
//
// One worker thread (ComponentRuntime::run) owns the core and the aligner. Reader callbacks only
// copy the sample into the runtime's queue. After each batch the worker asks the aligner for the
// event-time watermark, calls the node's process_until (core + publication), sends heartbeats and
// publishes Health (1 Hz on the wall clock, at once when state, level or reason change).
// On SIGINT/SIGTERM: readers closed (no more input), queued samples fed, the core finished and
// every remaining output published, writers' acknowledgments awaited (bounded), Health "stopping".
#include <chrono>
#include <cmath>
#include <memory>
#include <string>
#include <tuple>
#include <vector>

#include "odonav/dds/component.hpp"
#include "odonav/dds/node_support.hpp"
#include "odonav/topics.hpp"

namespace odonav::dds {

class EventTimeNode {
 public:
  explicit EventTimeNode(ComponentRuntime& runtime)
      : runtime_(runtime), aligner_(runtime.settings().max_wait_s, steady_now_s()) {}
  virtual ~EventTimeNode() = default;
  EventTimeNode(const EventTimeNode&) = delete;
  EventTimeNode& operator=(const EventTimeNode&) = delete;

  /// Runs until a stop is requested, then drains (see the file comment). Returns the exit code.
  int run() {
    const double t0 = steady_now_s();
    publish_health(t0, true);
    spdlog::info("{} running: vehicle '{}', domain {}, max wait {} s", runtime_.settings().component,
                 runtime_.settings().vehicle_id, runtime_.settings().participant.domain_id,
                 runtime_.settings().max_wait_s);
    runtime_.run([this] { tick(); });

    const int sig = runtime_.stop_signals().signal_number();
    spdlog::info("stop requested{}: draining", sig ? " (signal " + std::to_string(sig) + ")" : std::string());
    stopping_ = true;
    publish_health(steady_now_s(), true);
    close_inputs();          // no more input: no callback runs after this
    runtime_.run_pending();  // samples received before the stop are still fed
    tick();
    try {
      finish();
    } catch (const std::exception& e) {
      ++process_errors_;
      spdlog::error("finishing the core failed: {}", e.what());
    }
    bool acknowledged = true;
    for (detail::WriterBase* w : output_writers())
      acknowledged = wait_for_acknowledgments_logged(*w, std::chrono::seconds(5)) && acknowledged;
    drained_ = true;
    publish_health(steady_now_s(), true);
    wait_for_acknowledgments_logged(runtime_.health().writer(), std::chrono::seconds(4));
    spdlog::info("stopped after {} outputs{}", outputs_, acknowledged ? "" : " (some not acknowledged)");
    return 0;
  }

 protected:
  /// Health as the node sees it, past the checks on its required inputs.
  struct Status {
    odonav::msg::HealthState state = odonav::msg::HEALTH_STATE_RUNNING;
    odonav::msg::HealthLevel level = odonav::msg::HEALTH_LEVEL_OK;
    std::string reason;
  };

  /// Declares an input stream (plain, or paced by `pacing`, an input declared before). `required`:
  /// its absence degrades the node (WARN "no <name> for N s"); an optional input's absence is the
  /// node's to describe (node_status). Call in the derived constructor, before creating readers.
  NodeInput& add_input(const std::string& name, bool required, const NodeInput* pacing = nullptr) {
    auto in = std::make_unique<NodeInput>();
    in->name = name;
    in->estimate = pacing != nullptr;
    in->id = pacing ? aligner_.add_paced_stream(name, pacing->id) : aligner_.add_stream(name);
    inputs_.push_back(in.get());
    if (required) required_.push_back(in.get());
    owned_.push_back(std::move(in));
    return *owned_.back();
  }

  /// A reader of one input topic for this node's vehicle: each sample of another vehicle is ignored;
  /// each of ours is posted to the worker thread, admitted by the aligner on its stamp (late,
  /// repeated and bad stamps are counted there) and, if admitted, handed to feed(msg, t_s) there.
  /// The reader lives as long as the returned pointer (reset it in close_inputs).
  template <class Msg, class Feed>
  std::unique_ptr<Reader<Msg>> subscribe(const odonav::topics::TopicSpec& topic, NodeInput& input, Feed feed) {
    const std::string vehicle = runtime_.settings().vehicle_id;
    NodeInput* in = &input;
    return std::make_unique<Reader<Msg>>(
        runtime_.participant(), topic.name, topic.reader_profile, [this, vehicle, in, feed](const Msg& m) {
          if (m.vehicle_id() != vehicle) return;
          runtime_.post([this, in, feed, m] {
            admit_sample(aligner_, *in, m.header().stamp(), steady_now_s(), [&](double t_s) { feed(m, t_s); });
          });
        });
  }

  /// Calls the core's process_until(watermark_s) and publishes every output (count them with
  /// count_outputs).
  virtual void process_until(double watermark_s) = 0;
  /// The core's finish() and publication of every remaining output.
  virtual void finish() = 0;
  /// Destroys the data readers.
  virtual void close_inputs() = 0;
  /// Writers whose acknowledgments the drain waits for.
  virtual std::vector<detail::WriterBase*> output_writers() = 0;
  /// Node-specific health (optional inputs, convergence, commands).
  virtual Status node_status(double now_s) = 0;
  /// Node-specific counters, appended after the common ones.
  virtual void append_counters(HealthCounters& counters) = 0;
  /// Called every tick (heartbeats).
  virtual void on_tick(double /*now_s*/) {}

  void count_outputs(std::size_t n) { outputs_ += n; }
  bool input_absent(const NodeInput& in, double now_s) const { return aligner_.status(in.id, now_s).absent; }
  bool input_heard(const NodeInput& in, double now_s) const {
    return aligner_.status(in.id, now_s).last_t_s.has_value();
  }

  ComponentRuntime& runtime_;
  EventTimeAligner aligner_;

 private:
  void tick() {
    const double now = steady_now_s();
    if (const auto w = aligner_.advance(now)) {
      try {
        process_until(*w);
      } catch (const std::exception& e) {  // a core refusing a watermark must not end the process
        ++process_errors_;
        spdlog::error("processing up to t={} s failed: {}", *w, e.what());
      }
    }
    on_tick(now);
    publish_health(now, false);
  }

  Status status(double now_s) {
    using namespace odonav::msg;
    if (stopping_) return {HEALTH_STATE_STOPPING, HEALTH_LEVEL_OK, drained_ ? "stopped: drained" : "stopping: draining"};
    if (auto r = absent_reason(aligner_, required_, now_s)) return {HEALTH_STATE_DEGRADED, HEALTH_LEVEL_WARN, *r};
    if (auto r = waiting_reason(aligner_, required_, now_s)) return {HEALTH_STATE_STARTING, HEALTH_LEVEL_OK, *r};
    Status s = node_status(now_s);
    if (s.level == HEALTH_LEVEL_OK) {
      if (auto r = rejection_reason(inputs_, now_s)) {
        s.level = HEALTH_LEVEL_WARN;
        s.reason = s.reason.empty() ? *r : *r + "; " + s.reason;
      }
    }
    return s;
  }

  void publish_health(double now_s, bool force) {
    const Status s = status(now_s);
    const bool changed = std::tie(s.state, s.level, s.reason) != std::tie(last_.state, last_.level, last_.reason);
    if (changed && s.level != odonav::msg::HEALTH_LEVEL_OK) spdlog::warn("health: {}", s.reason);
    HealthCounters c;
    for (const NodeInput* in : inputs_) append_input_counters(c, aligner_, *in, now_s);
    c.emplace_back("outputs", static_cast<double>(outputs_));
    if (std::isfinite(aligner_.processed_s())) c.emplace_back("processed_until_s", aligner_.processed_s());
    c.emplace_back("queue_depth", static_cast<double>(runtime_.queue_depth()));
    c.emplace_back("process_errors", static_cast<double>(process_errors_));
    append_counters(c);
    runtime_.publish_health(s.state, s.level, s.reason, c, force || changed);
    last_ = s;
  }

  std::vector<std::unique_ptr<NodeInput>> owned_;
  std::vector<const NodeInput*> inputs_;
  std::vector<const NodeInput*> required_;
  Status last_{odonav::msg::HEALTH_STATE_STARTING, odonav::msg::HEALTH_LEVEL_STALE, "(none yet)"};
  uint64_t outputs_ = 0;
  uint64_t process_errors_ = 0;
  bool stopping_ = false;
  bool drained_ = false;
};

}  // namespace odonav::dds
