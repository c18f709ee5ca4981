#pragma once
// The skeleton shared by the calibration, identification and dead-reckoning nodes (library
// odonav_node_support: it needs odonav_samples' EventTimeAligner, which odonav_dds does not link).
//
// The core and the aligner run one task at a time under the runtime's mutex, on the listener thread
// that received the sample (TaskDispatcher::Mode::kOnPost: no thread wake-up per
// sample). After each sample the aligner gives the event-time watermark, the node's process_until
// runs (core + publication), heartbeats are sent and Health is published (1 Hz on the wall clock, at
// once when state, level or reason change); run()'s thread does the same every 100 ms when no
// sample comes (maximum waits, health).
// On SIGINT/SIGTERM: readers closed (no more input), queued samples fed, the core finished and
// every remaining output published, writers' acknowledgments awaited (bounded), Health "stopping".
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <tuple>
#include <vector>

#include <spdlog/spdlog.h>

#include "odonav/component_health.hpp"
#include "odonav/dds/component.hpp"
#include "odonav/dds/node_support.hpp"
#include "odonav/source_arbiter.hpp"
#include "odonav/topics.hpp"

namespace odonav::dds {

class EventTimeNode {
 public:
  /// in_flight_max_wait_s: how long an input with samples declared published but not received yet
  /// may stay silent (EventTimeAligner, "Samples in flight"); 0 = the max wait, for components whose
  /// outputs must stay fresh.
  /// inputs: the component's inputs as its core declares them (ComponentInput: the same list
  /// odonav-offline aligns), declared in order before any reader exists.
  EventTimeNode(ComponentRuntime& runtime, const std::vector<ComponentInput>& inputs,
                double in_flight_max_wait_s = 0.0);
  virtual ~EventTimeNode() = default;
  EventTimeNode(const EventTimeNode&) = delete;
  EventTimeNode& operator=(const EventTimeNode&) = delete;

  /// Runs until a stop is requested, then drains (see the file comment). Returns the exit code.
  int run();

 protected:
  /// Health as the node sees it, past the checks on its required inputs.
  struct Status {
    odonav::msg::HealthState state = odonav::msg::HEALTH_STATE_RUNNING;
    odonav::msg::HealthLevel level = odonav::msg::HEALTH_LEVEL_OK;
    std::string reason;
  };
  /// The Health topic's state and level of a core's health decision (component_health.hpp).
  static Status status_of(const ComponentHealth& health);

  /// The input of that name (ComponentInput::name); `find_input` returns nullptr when the component
  /// has none (e.g. "ins" without use_ins), `input` throws std::logic_error. A required input's
  /// absence degrades the node (WARN "no <name> for N s"); an optional input's absence is the node's
  /// to describe (node_status).
  NodeInput* find_input(const std::string& name);
  NodeInput& input(const std::string& name);

  /// A reader of one input topic for this node's vehicle: each sample of another vehicle is ignored;
  /// each of ours is posted to the runtime (executed at once), admitted by the aligner on its stamp (late,
  /// repeated and bad stamps are counted there) and, if admitted, handed to feed(msg, t_s) there.
  /// The reader lives as long as the returned pointer (reset it in close_inputs).
  template <class Msg, class Feed>
  std::unique_ptr<Reader<Msg>> subscribe(const odonav::topics::TopicSpec& topic, NodeInput& input, Feed feed) {
    return subscribe<Msg>(topic, input, feed, [](const Msg&) {});
  }
  /// subscribe() with `before(msg)` called in the task before the sample is admitted (e.g.
  /// declare_gnss_published for the odometer, whose messages carry the GNSS completeness).
  template <class Msg, class Feed, class Before>
  std::unique_ptr<Reader<Msg>> subscribe(const odonav::topics::TopicSpec& topic, NodeInput& input, Feed feed,
                                         Before before) {
    const std::string vehicle = runtime_.settings().vehicle_id;
    NodeInput* in = &input;
    return std::make_unique<Reader<Msg>>(
        runtime_.participant(), topic.name, topic.reader_profile, [this, vehicle, in, feed, before](const Msg& m) {
          if (m.vehicle_id() != vehicle) return;
          runtime_.post([this, in, feed, before, m] {
            before(m);
            admit_sample(aligner_, *in, m.header().stamp(), steady_now_s(), [&](double t_s) { feed(m, t_s); });
          });
        });
  }

  /// The GNSS completeness an Odometer or InsAttitude message declares (idl Odometer), given to the
  /// aligner for the `gnss` input, so that a consumer knows which GNSS epochs exist up to the
  /// sample's time.
  template <class SensorMsg>
  void declare_gnss_published(const NodeInput& gnss, const SensorMsg& m) {
    if (!m.gnss_complete_known()) return;
    const double last = m.gnss_last_stamp_s();
    aligner_.declare_published(gnss.id, m.gnss_complete_through_s(),
                               last >= 0.0 ? std::optional<double>(last) : std::nullopt);
  }

  /// subscribe() for an estimate topic whose producers may be redundant (a hot standby: Msg has
  /// source() and source_priority()): in the task each sample of this vehicle first goes
  /// through `arbiter` (odonav/source_arbiter.hpp), and only what it hands on (one stream, the
  /// highest-priority live source, each stamp once, in order) is admitted and fed; repeats of the
  /// last stamp handed on reach the aligner as heartbeats. Each switch of source is logged with its
  /// reason. `arbiter` must outlive the returned reader.
  template <class Msg, class Feed>
  std::unique_ptr<Reader<Msg>> subscribe_arbitrated(const odonav::topics::TopicSpec& topic, NodeInput& input,
                                                    SourceArbiter<Msg>& arbiter, Feed feed) {
    const std::string vehicle = runtime_.settings().vehicle_id;
    NodeInput* in = &input;
    SourceArbiter<Msg>* arb = &arbiter;
    const std::string name = topic.name;
    return std::make_unique<Reader<Msg>>(
        runtime_.participant(), topic.name, topic.reader_profile, [this, vehicle, in, arb, feed, name](const Msg& m) {
          if (m.vehicle_id() != vehicle) return;
          runtime_.post([this, in, arb, feed, m, name] {
            double t_s = 0.0;
            try {
              t_s = to_seconds(m.header().stamp());
            } catch (const std::invalid_argument&) {  // not a time: the aligner names it
              admit_sample(aligner_, *in, m.header().stamp(), steady_now_s(), [&](double s) { feed(m, s); });
              return;
            }
            const std::uint64_t switches = arb->counters().switches;
            const std::vector<Msg> released = arb->offer(m.source(), m.source_priority(), t_s, m);
            if (arb->counters().switches != switches && !arb->switches().empty()) {
              const SourceSwitch& sw = arb->switches().back();
              spdlog::info("{}: following '{}' from t={:.3f} s ({})", name, sw.to, sw.at_stamp_s, sw.reason);
            }
            for (const Msg& r : released)
              admit_sample(aligner_, *in, r.header().stamp(), steady_now_s(), [&](double s) { feed(r, s); });
            // A repeat of the last stamp handed on (a heartbeat of any instance) still tells the
            // aligner the input is alive; it is never fed (the aligner takes it as a repeat).
            if (released.empty() && arb->last_delivered_s() && t_s == *arb->last_delivered_s())
              admit_sample(aligner_, *in, m.header().stamp(), steady_now_s(), [](double) {});
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
  void tick();

  Status status(double now_s);

  void publish_health(double now_s, bool force);

  std::vector<std::unique_ptr<NodeInput>> owned_;
  std::vector<const NodeInput*> inputs_;
  std::vector<const NodeInput*> required_;
  Status last_{odonav::msg::HEALTH_STATE_STARTING, odonav::msg::HEALTH_LEVEL_STALE, "(none yet)"};
  uint64_t outputs_ = 0;
  uint64_t process_errors_ = 0;
  /// Steady time (s) of the last health evaluation from tick().
  double last_health_tick_s_ = -std::numeric_limits<double>::infinity();
  bool stopping_ = false;
  bool drained_ = false;
};

}  // namespace odonav::dds
