// The event-time node skeleton (event_time_node.hpp): run loop, drain, inputs, health.
#include "odonav/dds/event_time_node.hpp"

#include <stdexcept>

#include <spdlog/spdlog.h>

#include <algorithm>

namespace odonav::dds {

EventTimeNode::EventTimeNode(ComponentRuntime& runtime, const std::vector<ComponentInput>& inputs,
                             double in_flight_max_wait_s)
    : runtime_(runtime),
      aligner_(runtime.settings().max_wait_s, steady_now_s(),
               in_flight_max_wait_s > 0.0 ? std::max(in_flight_max_wait_s, runtime.settings().max_wait_s) : 0.0) {
  // A core step and KEEP_LAST writes never block: run them where the sample arrives.
  runtime_.set_dispatch(TaskDispatcher::Mode::kOnPost);
  for (const ComponentInput& c : inputs) {
    const NodeInput* pacing = c.paced_by.empty() ? nullptr : &input(c.paced_by);
    auto in = std::make_unique<NodeInput>();
    in->name = c.name;
    in->estimate = pacing != nullptr;
    in->id = pacing ? aligner_.add_paced_stream(c.name, pacing->id, c.hold_off_s)
                    : aligner_.add_stream(c.name, c.hold_off_s);
    inputs_.push_back(in.get());
    if (c.required) required_.push_back(in.get());
    owned_.push_back(std::move(in));
  }
}

int EventTimeNode::run() {
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
  for (const NodeInput* in : inputs_) {
    const EventTimeAligner::StreamStatus st = aligner_.status(in->id, steady_now_s());
    if (in->estimate || st.hold_off_s > 0.0)
      spdlog::info("{}: {} waits for estimates later than their {} s hold-off", in->name, st.hold_off_waits,
                   st.hold_off_s);
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

NodeInput* EventTimeNode::find_input(const std::string& name) {
  for (const auto& in : owned_)
    if (in->name == name) return in.get();
  return nullptr;
}

NodeInput& EventTimeNode::input(const std::string& name) {
  if (NodeInput* in = find_input(name)) return *in;
  throw std::logic_error(runtime_.settings().component + ": no input '" + name + "' declared");
}

void EventTimeNode::tick() {
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
  // Ticks follow every sample (hundreds per second): health at most every kHealthEvaluationPeriod_s.
  if (now - last_health_tick_s_ >= kHealthEvaluationPeriod_s) {
    last_health_tick_s_ = now;
    publish_health(now, false);
  }
}

EventTimeNode::Status EventTimeNode::status_of(const ComponentHealth& h) {
  using namespace odonav::msg;
  Status s;
  switch (h.state) {
    case ComponentHealth::State::kStarting: s.state = HEALTH_STATE_STARTING; break;
    case ComponentHealth::State::kRunning: s.state = HEALTH_STATE_RUNNING; break;
    case ComponentHealth::State::kDegraded: s.state = HEALTH_STATE_DEGRADED; break;
  }
  s.level = h.level == ComponentHealth::Level::kWarn ? HEALTH_LEVEL_WARN : HEALTH_LEVEL_OK;
  s.reason = h.reason;
  return s;
}

EventTimeNode::Status EventTimeNode::status(double now_s) {
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

void EventTimeNode::publish_health(double now_s, bool force) {
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

}  // namespace odonav::dds
