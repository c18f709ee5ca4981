#include "dead_reckoning_node.hpp"

#include "odonav/dds/output_messages.hpp"

#include <cmath>
#include <ctime>
#include <stdexcept>

#include <spdlog/spdlog.h>

#include "odonav/consumer_rules.hpp"
#include "odonav/dds/time.hpp"
#include "odonav/dead_reckoning/dead_reckoning_health.hpp"
#include "odonav/dead_reckoning/dead_reckoning_options.hpp"
#include "odonav/topics.hpp"

namespace odonav::dead_reckoning {

namespace {
/// The vehicle facts of the node's options: dead_reckoning_facts_from plus --use-ins.
DeadReckoningFacts node_facts_from(const Options& o) {
  DeadReckoningFacts facts = dead_reckoning_facts_from(o);
  facts.use_ins = o.get_bool("use-ins");
  return facts;
}

}  // namespace

void add_dead_reckoning_node_options(Options& o) {
  add_dead_reckoning_options(o);
  dds::add_sensor_node_options(o, "GNSS course, horizontal only", "dead-reckoning-<vehicle>.ckpt");
}

DeadReckonerParams dead_reckoning_node_params_from(const Options& o) {
  return dead_reckoner_params(node_facts_from(o));  // the function odonav-offline uses too
}

AnchoredPositionParams anchored_position_node_params_from(const Options& o) {
  return anchored_position_params(node_facts_from(o));
}

odonav::msg::DeadReckoning dead_reckoning_message(const DeadReckoningOutput& o, const Geodetic& origin,
                                                  const Misalignment& mis, const std::string& vehicle_id) {
  odonav::msg::DeadReckoning m = dds::message_of(output_row(o));  // the field table
  m.vehicle_id(vehicle_id);
  const Geodetic in_range = normalized(origin);  // lat [-90, 90], lon [-180, 180)
  m.origin_latitude_deg(rad_to_deg(in_range.lat_rad));
  m.origin_longitude_deg(rad_to_deg(in_range.lon_rad));
  m.origin_height_m(in_range.height_m);
  m.misalignment_heading_rad(mis.heading_rad);
  m.misalignment_pitch_rad(mis.pitch_rad);
  m.gnss_valid(o.gnss_reference);
  return m;
}

odonav::msg::NavigationPosition navigation_position_message(const AnchoredPosition& p, const std::string& vehicle_id) {
  odonav::msg::NavigationPosition m = dds::message_of(output_row(p));  // the field table
  m.vehicle_id(vehicle_id);
  const bool known = m.position_covariance_east_m2() >= 0.0 && m.position_covariance_north_m2() >= 0.0 &&
                     m.position_covariance_up_m2() >= 0.0;
  m.position_covariance_type(known ? 2 : 0);  // NavSatFix: COVARIANCE_TYPE_DIAGONAL_KNOWN / UNKNOWN
  return m;
}

DeadReckoningNode::DeadReckoningNode(dds::ComponentRuntime& runtime, const DeadReckonerParams& params,
                                     const AnchoredPositionParams& anchored, const CheckpointSettings& checkpoint)
    : EventTimeNode(runtime, dead_reckoning_inputs(params)),
      params_(params),
      component_(dds::make_node_core<DeadReckoningComponent>("dead-reckoning", params, anchored)),
      lifecycle_(checkpoint, runtime.settings().vehicle_id),
      odometer_(input("odometer")),
      gnss_(input("gnss")),
      ins_(find_input("ins")),
      misalignment_(input("misalignment")),
      scale_factor_(input("scale_factor")),
      writer_(runtime.participant(), topics::kDeadReckoning.name, topics::kDeadReckoning.writer_profile),
      navigation_writer_(runtime.participant(), topics::kNavigationPosition.name,
                         topics::kNavigationPosition.writer_profile) {
  runtime.set_command_handler([this](const odonav::msg::Command& c) { return on_command(c); });
  // Before any reader exists: no sample can reach the cores before the restored state.
  lifecycle_.start(component_.state(), static_cast<int64_t>(std::time(nullptr)), dds::steady_now_s());
  // Resumed from a checkpoint: the sensor readers ask the producers for their history (30 s), so the
  // downtime is processed (what the checkpoint holds is skipped). The estimate readers are
  // TRANSIENT_LOCAL with the same depth already. A fresh start reads from the moment it matched.
  const char* sensor_profile = dds::sensor_reader_profile(lifecycle_.restored_t_s());

  odometer_reader_ = subscribe<odonav::msg::Odometer>(
      topics::with_reader_profile(topics::kOdometer, sensor_profile), odometer_,
      [this](const auto& m, double t_s) {
        if (lifecycle_.take_sample(DeadReckoningInput::kOdometer, t_s))
          component_.add_odometer(dds::odometer_sample_from(m));
      },
      [this](const odonav::msg::Odometer& m) {
        declare_gnss_published(gnss_, m);
        note_live_sample(m.header().stamp());
      });
  gnss_reader_ = subscribe<odonav::msg::GnssFix>(topics::with_reader_profile(topics::kGnssFix, sensor_profile), gnss_,
                                                 [this](const auto& m, double t_s) {
                                                   if (lifecycle_.take_sample(DeadReckoningInput::kGnss, t_s))
                                                     component_.add_gnss(dds::gnss_sample_from(m));
                                                 });
  if (ins_) {
    ins_reader_ = subscribe<odonav::msg::InsAttitude>(topics::with_reader_profile(topics::kInsAttitude, sensor_profile),
                                                      *ins_, [this](const auto& m, double t_s) {
                                                        if (!lifecycle_.take_sample(DeadReckoningInput::kIns, t_s))
                                                          return;
                                                        if (!m.valid()) {
                                                          ++ins_->dropped_invalid;
                                                          return;
                                                        }
                                                        component_.add_ins(dds::ins_sample_from(m));
                                                      });
  }
  misalignment_reader_ =
      subscribe<odonav::msg::Misalignment>(topics::kMisalignment, misalignment_, [this](const auto& m, double t_s) {
        if (lifecycle_.take_sample(DeadReckoningInput::kMisalignment, t_s))
          component_.on_misalignment(dds::published_misalignment_from(m, t_s));
      });
  scale_factor_reader_ = subscribe_arbitrated<odonav::msg::ScaleFactor>(
      topics::kScaleFactor, scale_factor_, k_arbiter_, [this](const auto& m, double t_s) {
        if (lifecycle_.take_sample(DeadReckoningInput::kScaleFactor, t_s))
          component_.on_scale_factor(dds::published_scale_factor_from(m, t_s), dds::steady_now_s());
      });
}

void DeadReckoningNode::note_live_sample(const builtin_interfaces::msg::Time& stamp) {
  // On arrival, before the aligner holds the sample back for the other inputs: the live edge is the
  // newest odometer stamp handed over in the first second, not the newest processed.
  try {
    lifecycle_.note_live_sample(dds::to_seconds(stamp), dds::steady_now_s());
  } catch (const std::invalid_argument&) {
    // A bad stamp is counted and told by admit_sample right after this.
  }
}

DeadReckoningNode::~DeadReckoningNode() { close_inputs(); }

void DeadReckoningNode::close_inputs() {
  odometer_reader_.reset();
  gnss_reader_.reset();
  ins_reader_.reset();
  misalignment_reader_.reset();
  scale_factor_reader_.reset();
}

void DeadReckoningNode::publish(std::vector<DeadReckoningOutput> all) {
  if (all.empty()) return;
  const std::vector<DeadReckoningOutput> outputs = lifecycle_.outputs_to_publish(std::move(all), dds::steady_now_s());
  if (outputs.empty()) return;
  const Geodetic origin = component_.core().origin().value_or(Geodetic{});
  for (const DeadReckoningOutput& o : outputs) {
    const DeadReckoningStep step = component_.publish(o);
    if (!writer_.write(dead_reckoning_message(step.output, origin, step.misalignment, runtime_.settings().vehicle_id)))
      spdlog::warn("{}: write refused by the middleware", writer_.topic_name());
    if (!navigation_writer_.write(navigation_position_message(step.navigation, runtime_.settings().vehicle_id)))
      spdlog::warn("{}: write refused by the middleware", navigation_writer_.topic_name());
    // A burst (catching up after a wait, the drain) larger than the KEEP_LAST history would
    // overwrite samples not yet delivered: let the transport drain.
    throttle_.after_write();
  }
  last_output_ = outputs.back();
  count_outputs(outputs.size());
  // After the anchored position has taken these outputs: the state is the one after the last.
  lifecycle_.checkpoint_if_due(component_.state());
}

void DeadReckoningNode::process_until(double watermark_s) { publish(component_.process_until(watermark_s)); }

void DeadReckoningNode::finish() {
  publish(component_.finish());
  lifecycle_.checkpoint_at_finish(component_.state());
}

std::vector<dds::detail::WriterBase*> DeadReckoningNode::output_writers() { return {&writer_, &navigation_writer_}; }

dds::CommandAck DeadReckoningNode::on_command(const odonav::msg::Command& c) {
  using namespace odonav::msg;
  ScaleFactorCommandResult r;
  switch (c.command()) {
    case COMMAND_SET_K: r = component_.set_commanded_k(c.value(), aligner_.processed_s()); break;
    case COMMAND_RELEASE_K: r = component_.release_commanded_k(); break;
    case COMMAND_RESET_ESTIMATION:
      // Dead reckoning estimates nothing to restart; before COMMAND_RELEASE_K existed this kind
      // released the commanded K here: refuse it rather than guess which meaning the sender has.
      r = {false,
           "reset is for the estimators (calibration, identification); to follow the identified K again "
           "send release-k (COMMAND_RELEASE_K)",
           std::nullopt};
      break;
    case COMMAND_FREEZE_ESTIMATION:
    case COMMAND_UNFREEZE_ESTIMATION: r = {false, "freeze/unfreeze is for odonav-identification", std::nullopt}; break;
    default: r = {false, "unknown command kind", std::nullopt}; break;
  }
  return {c.command_id(), r.accepted ? COMMAND_RESULT_ACCEPTED : COMMAND_RESULT_REJECTED, r.detail};
}

dds::EventTimeNode::Status DeadReckoningNode::node_status(double now_s) {
  const DeadReckoner& core = component_.core();
  const ScaleFactorSelection& k_selection = component_.k_selection();
  const DeadReckoningConsumerState& consumer = component_.consumer();
  pulse_jumps_.observe(core.counters().pulse_jumps_rejected, now_s);
  DeadReckoningHealthFacts f;
  // After a restart: what the restore did, the catch-up of the downtime, failed checkpoint writes.
  static_cast<RestartHealthNotes&>(f) = lifecycle_.restart().health_notes();
  f.now_s = now_s;
  f.started = core.started();
  f.k_commanded = k_selection.commanded();
  f.scale_factor_absent = input_absent(scale_factor_, now_s);
  f.scale_factor_heard = input_heard(scale_factor_, now_s);
  f.k_applied = k_selection.counters().k_applied;
  f.k_source_note = k_selection.k_source_note();
  f.k_source_changed_at_s = k_selection.k_source_changed_at_s();
  f.pulse_jumps_rejected = core.counters().pulse_jumps_rejected;
  f.pulse_jumps_changed_at_s = pulse_jumps_.changed_at_s();
  f.misalignment_absent = input_absent(misalignment_, now_s);
  f.misalignment_heard = input_heard(misalignment_, now_s);
  f.misalignments_applied = consumer.misalignments_applied;
  f.held_misalignment_t_s = consumer.held_misalignment_t_s;
  f.misalignment_silent_s = aligner_.status(misalignment_.id, now_s).silent_for_s;
  held_k_outputs_.observe(core.counters().outputs_on_held_k, now_s);
  held_misalignment_outputs_.observe(core.counters().outputs_on_held_misalignment, now_s);
  f.held_k_span = core.last_held_span(HeldEstimate::kScaleFactor);
  f.held_k_changed_at_s = held_k_outputs_.changed_at_s();
  f.held_misalignment_span = core.last_held_span(HeldEstimate::kMisalignment);
  f.held_misalignment_changed_at_s = held_misalignment_outputs_.changed_at_s();
  f.inconsistency = component_.monitor().reason();
  f.pole_distance_m = core.pole_distance_m();
  f.pole_north = core.position().lat_rad >= 0.0;
  return status_of(dead_reckoning_health(f));
}

void DeadReckoningNode::append_counters(dds::HealthCounters& c) {
  const DeadReckoner& core = component_.core();
  const ScaleFactorSelection& k_selection = component_.k_selection();
  const DeadReckoningConsumerState& consumer = component_.consumer();
  const DeadReckonerCounters& k = core.counters();
  c.emplace_back("odometer_processed", static_cast<double>(k.odometer_samples));
  c.emplace_back("before_start", static_cast<double>(k.before_start));
  c.emplace_back("heading_held", static_cast<double>(k.heading_held));
  c.emplace_back("reversing", static_cast<double>(k.reversing));
  c.emplace_back("pulse_jumps_rejected", static_cast<double>(k.pulse_jumps_rejected));
  c.emplace_back("pulse_rebases", static_cast<double>(k.pulse_rebases));
  const ScaleFactorSelectionCounters& s = k_selection.counters();
  c.emplace_back("k_applied", static_cast<double>(s.k_applied));
  c.emplace_back("k_ignored", static_cast<double>(s.k_ignored));
  c.emplace_back("k_source_changes", static_cast<double>(s.k_source_changes));
  c.emplace_back("misalignments_applied", static_cast<double>(consumer.misalignments_applied));
  c.emplace_back("outputs_on_held_k", static_cast<double>(k.outputs_on_held_k));
  c.emplace_back("outputs_on_held_misalignment", static_cast<double>(k.outputs_on_held_misalignment));
  // The last span of each (event time, s): what the recorder and a monitor can name.
  for (const HeldEstimate e : {HeldEstimate::kScaleFactor, HeldEstimate::kMisalignment}) {
    const std::optional<HeldSpan>& span = core.last_held_span(e);
    if (!span) continue;
    const std::string name = e == HeldEstimate::kScaleFactor ? "held_k" : "held_misalignment";
    c.emplace_back(name + "_first_t_s", span->first_t_s);
    c.emplace_back(name + "_last_t_s", span->last_t_s);
    c.emplace_back(name + "_epoch_t_s", span->estimate_epoch_s);
  }
  const AnchoredPositionCounters& a = component_.anchor().counters();
  c.emplace_back("anchor_fixes_applied", static_cast<double>(a.fixes_applied));
  c.emplace_back("anchor_fixes_rejected_gate", static_cast<double>(a.fixes_rejected_gate));
  c.emplace_back("anchor_gate_restarts", static_cast<double>(a.gate_restarts));
  c.emplace_back("anchor_fixes_no_attitude", static_cast<double>(k.anchor_fixes_no_attitude));
  c.emplace_back("gnss_position_jumps", static_cast<double>(component_.monitor().gnss_jumps().jumps));
  for (auto& counter : lifecycle_.restart().counters()) c.push_back(std::move(counter));
  if (last_output_) {
    c.emplace_back("distance_m", last_output_->distance_m);
    c.emplace_back("k_m_per_pulse", last_output_->k_m_per_pulse);
    if (std::isfinite(last_output_->horizontal_error_m))
      c.emplace_back("horizontal_error_m", last_output_->horizontal_error_m);
  }
}

}  // namespace odonav::dead_reckoning
