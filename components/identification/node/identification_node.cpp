#include "identification_node.hpp"

#include "odonav/defaults.hpp"
#include "odonav/dds/output_messages.hpp"

#include "odonav/lever_arm_option.hpp"
#include "odonav/nominal_k_option.hpp"

#include <cmath>
#include <ctime>
#include <filesystem>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <spdlog/spdlog.h>

#include "odonav/consumer_rules.hpp"
#include "odonav/dds/time.hpp"
#include "odonav/identification/checkpoint.hpp"
#include "odonav/identification/identification_options.hpp"
#include "odonav/topics.hpp"

namespace odonav::identification {

void add_identification_node_options(Options& o) {
  add_identification_options(o);
  dds::add_sensor_node_options(o, "forward speed = |GNSS velocity|", "identification-<vehicle>.ckpt");
  o.add_string("instance", kDefaultIdentificationInstance,
               "name of this instance, published as ScaleFactor.source and naming its state files "
               "(e.g. identification/standby for a hot standby; letters, digits, . _ - /)");
  o.add_int("ownership-strength", 10,
            "priority of this instance, published as ScaleFactor.source_priority: consumers follow the "
            "highest-priority live instance (primary e.g. 20, standby 10)",
            0, 1000000);
  add_nominal_k_option(o);
}

InstanceSettings instance_settings_from(const Options& o) {
  InstanceSettings s;
  s.instance = o.get_string("instance");
  try {
    validate_identification_instance(s.instance);
  } catch (const std::invalid_argument& e) {
    throw ConfigError(std::string("--instance: ") + e.what());
  }
  s.ownership_strength = static_cast<uint32_t>(o.get_int("ownership-strength"));
  s.nominal_k_m_per_pulse = resolve_nominal_k(nominal_k_option_from(o));
  return s;
}

CheckpointSettings checkpoint_settings_from(const Options& o) { return checkpoint_settings_from_options(o); }

IdentificationParams identification_node_params_from(const Options& o) {
  IdentificationVehicleFacts facts;
  facts.use_ins = o.get_bool("use-ins");
  facts.lever_arm_body_m = lever_arm_from(o);
  facts.nominal_k_m_per_pulse = resolve_nominal_k(nominal_k_option_from(o));
  facts.run_all_estimators = false;  // the node publishes the main estimator only
  return identification_params_for(o, facts);
}

odonav::msg::ScaleFactor scale_factor_message(const IdentificationOutput& out, const std::string& estimator,
                                              const std::string& vehicle_id, const std::string& source,
                                              uint32_t source_priority) {
  odonav::msg::ScaleFactor m = dds::message_of(output_row(out, estimator, {}));  // the field table
  m.vehicle_id(vehicle_id);
  m.frozen(out.frozen);
  m.source(source);
  m.source_priority(source_priority);
  m.turn_slip_threshold_radps(out.turn_slip_threshold_radps);
  return m;
}

namespace {
// The scale-factor writer: the profile (TRANSIENT_LOCAL, so a late reader gets the latest
// estimates), plus the ownership strength. No Fast DDS persistence: the checkpoint restores the
// estimator, and the restored K is published at once.
dds::WriterSettings scale_factor_writer_settings(const InstanceSettings& instance) {
  dds::WriterSettings w;
  w.ownership_strength = instance.ownership_strength;
  return w;
}

}  // namespace

IdentificationNode::IdentificationNode(dds::ComponentRuntime& runtime, const IdentificationParams& params,
                                       const CheckpointSettings& checkpoint, const InstanceSettings& instance)
    // An exact estimate late rather than a different one: an input whose samples are declared
    // published but still on their way (a restart's history hand-over) is waited for up to the
    // producers' history length (EventTimeAligner, "Samples in flight").
    : EventTimeNode(runtime, identification_inputs(params), kInFlightMaxWait_s),
      params_(params),
      instance_(instance),
      core_(dds::make_node_core<IdentificationCore>("identification", params)),
      lifecycle_(checkpoint, runtime.settings().vehicle_id, instance.instance),
      odometer_(input("odometer")),
      gnss_(input("gnss")),
      ins_(find_input("ins")),
      misalignment_(input("misalignment")) {
  runtime.set_command_handler([this](const odonav::msg::Command& c) { return on_command(c); });
  // Before any reader exists: no sample can reach the core before the restored state.
  lifecycle_.start(core_, static_cast<int64_t>(std::time(nullptr)), dds::steady_now_s());
  scale_factor_ = std::make_unique<dds::EstimatePublisher<odonav::msg::ScaleFactor>>(
      runtime.participant(), topics::kScaleFactor.name, topics::kScaleFactor.writer_profile,
      instance_.heartbeat_period_s, scale_factor_writer_settings(instance_));
  if (const auto restored = lifecycle_.take_restored_output()) {
    write_scale_factor(*restored, dds::steady_now_s());
    count_outputs(1);
  }
  // Resumed from a checkpoint: the sensor readers ask the producers for their history (30 s), so
  // the data of the downtime is processed from the checkpoint on (what predates it is skipped).
  // A fresh start reads like every other consumer: from the moment it matched.
  const char* sensor_profile = dds::sensor_reader_profile(lifecycle_.restored_t_s());

  odometer_reader_ = subscribe<odonav::msg::Odometer>(
      topics::with_reader_profile(topics::kOdometer, sensor_profile), odometer_,
      [this](const auto& m, double t_s) {
        lifecycle_.note_odometer_received(t_s, dds::steady_now_s());
        const bool skip = lifecycle_.skip_sample(IdentificationInput::kOdometer, t_s);
        flush_pending_gnss();
        if (!skip) core_.add_odometer(dds::odometer_sample_from(m));
      },
      [this](const odonav::msg::Odometer& m) { declare_gnss_published(gnss_, m); });
  gnss_reader_ = subscribe<odonav::msg::GnssFix>(
      topics::with_reader_profile(topics::kGnssFix, sensor_profile), gnss_, [this](const auto& m, double t_s) {
        // After a restore, GNSS waits until the first odometer (and INS) sample of the handed-over
        // history is known: epochs older than those histories cannot be processed and are lost.
        if (lifecycle_.restored_t_s() && !sensor_history_start_known()) {
          pending_gnss_.emplace_back(t_s, dds::gnss_sample_from(m));
          return;
        }
        if (!lifecycle_.skip_sample(IdentificationInput::kGnss, t_s)) core_.add_gnss(dds::gnss_sample_from(m));
      });
  if (ins_) {
    ins_reader_ = subscribe<odonav::msg::InsAttitude>(
        topics::with_reader_profile(topics::kInsAttitude, sensor_profile), *ins_, [this](const auto& m, double t_s) {
          const bool skip = lifecycle_.skip_sample(IdentificationInput::kIns, t_s);
          flush_pending_gnss();
          if (skip) return;
          if (!m.valid()) {
            ++ins_->dropped_invalid;
            return;
          }
          core_.add_ins(dds::ins_sample_from(m));
        });
  }
  misalignment_reader_ = subscribe<odonav::msg::Misalignment>(
      topics::kMisalignment, misalignment_, [this](const auto& m, double t_s) { on_misalignment(m, t_s); });
}

IdentificationNode::~IdentificationNode() { close_inputs(); }

bool IdentificationNode::sensor_history_start_known() const {
  return lifecycle_.first_sample_seen(IdentificationInput::kOdometer) &&
         (!ins_ || lifecycle_.first_sample_seen(IdentificationInput::kIns));
}

void IdentificationNode::flush_pending_gnss() {
  if (pending_gnss_.empty() || !sensor_history_start_known()) return;
  // Before any GNSS sample reaches the core: the watermark needs odometer (and INS) data, so no
  // epoch was processed yet and these go in before the first one.
  for (const auto& [t_s, g] : pending_gnss_)
    if (!lifecycle_.skip_sample(IdentificationInput::kGnss, t_s)) core_.add_gnss(g);
  pending_gnss_.clear();
}

void IdentificationNode::close_inputs() {
  odometer_reader_.reset();
  gnss_reader_.reset();
  ins_reader_.reset();
  misalignment_reader_.reset();
}

void IdentificationNode::on_misalignment(const odonav::msg::Misalignment& m, double t_s) {
  // After a restore the calibration's history comes again: what the restored core holds is skipped.
  if (lifecycle_.skip_sample(IdentificationInput::kMisalignment, t_s)) return;
  if (core_.apply_misalignment(dds::published_misalignment_from(m, t_s))) lifecycle_.note_misalignment_applied(t_s);
}

void IdentificationNode::publish(const std::vector<IdentificationOutput>& outputs) {
  const double now = dds::steady_now_s();
  const std::vector<IdentificationOutput> to_publish = lifecycle_.outputs_to_publish(outputs, now);
  for (const IdentificationOutput& o : to_publish) {
    write_scale_factor(o, now);
    log_turn_slip_change(o);
  }
  count_outputs(to_publish.size());
  lifecycle_.checkpoint_if_due(core_);
}

void IdentificationNode::log_turn_slip_change(const IdentificationOutput& o) {
  if (turn_slip_applies_ && *turn_slip_applies_ == o.turn_slip.applies) return;
  if (o.turn_slip.applies)
    spdlog::info("turn slip applied from t={:.3f} s: g = {:.4f} +- {:.4f} s/rad beyond {:.3f} rad/s ({} turn samples)",
                 o.t_s, o.turn_slip.g_s_per_rad, o.turn_slip.sigma_s_per_rad, o.turn_slip_threshold_radps,
                 o.turn_slip.samples);
  else if (turn_slip_applies_)
    spdlog::warn("turn slip no longer applied at t={:.3f} s: {}", o.t_s, o.turn_slip.reason);
  turn_slip_applies_ = o.turn_slip.applies;
}

void IdentificationNode::finish() {
  publish(core_.finish());
  lifecycle_.checkpoint_at_finish(core_);
  if (const auto& last = lifecycle_.last_output(); last && !last->turn_slip.applies)
    spdlog::info("turn slip not applied at the end (t={:.3f} s): {}", last->t_s, last->turn_slip.reason);
}

void IdentificationNode::write_scale_factor(const IdentificationOutput& o, double now_s) {
  scale_factor_->publish(scale_factor_message(o, core_.main_estimator_name(), runtime_.settings().vehicle_id,
                                              instance_.instance, instance_.ownership_strength),
                         now_s);
}

void IdentificationNode::on_tick(double now_s) {
  // The heartbeat keeps the writer's offered 300 ms deadline while nothing new is published (GNSS
  // outage; gated epochs are published anyway), so readers' deadlines mean "producer gone". Same
  // stamp: consumers take it as a repeat (the standby hand-over itself is decided on event time by
  // the consumers' SourceArbiter, not by this).
  scale_factor_->heartbeat_if_due(now_s);
}

void IdentificationNode::process_until(double watermark_s) { publish(core_.process_until(watermark_s)); }

std::vector<dds::detail::WriterBase*> IdentificationNode::output_writers() { return {&scale_factor_->writer()}; }

dds::CommandAck IdentificationNode::on_command(const odonav::msg::Command& c) {
  using namespace odonav::msg;
  // After a reset the next checkpoint (at most --checkpoint-every-s later) stores the reset state.
  if (auto ack = dds::run_estimation_command(
          c, core_, {"scale-factor estimator reset", "identification frozen: K held", "identification resumed"}))
    return *ack;
  switch (c.command()) {
    case COMMAND_RELEASE_K:
      return {c.command_id(), COMMAND_RESULT_REJECTED, "release_k is for odonav-dead-reckoning, not identification"};
    case COMMAND_SET_K: {
      const double k = c.value();
      if (const auto problem = IdentificationCore::commanded_k_problem(k, instance_.nominal_k_m_per_pulse))
        return {c.command_id(), COMMAND_RESULT_REJECTED, "set_k: " + *problem};
      // Stamped with the last event time processed (the output it replaces), so it sorts after
      // everything already published and before the next epoch.
      const double t_s = lifecycle_.set_k_stamp_s(aligner_.processed_s());
      const IdentificationOutput o = lifecycle_.commanded_output(core_.set_k(k, t_s));
      write_scale_factor(o, dds::steady_now_s());
      count_outputs(1);
      ++k_commands_;
      std::ostringstream m;
      m.precision(10);
      m << "K set to " << k << " m/pulse by command; identification continues from it";
      spdlog::info("{}", m.str());
      return {c.command_id(), COMMAND_RESULT_ACCEPTED, m.str()};
    }
    default: break;
  }
  return {c.command_id(), COMMAND_RESULT_REJECTED, "unknown command kind"};
}

dds::EventTimeNode::Status IdentificationNode::node_status(double now_s) {
  IdentificationHealthFacts facts = lifecycle_.health_facts(now_s);
  facts.misalignment_absent = input_absent(misalignment_, now_s);
  facts.misalignment_heard = input_heard(misalignment_, now_s);
  facts.misalignment_silent_s = aligner_.status(misalignment_.id, now_s).silent_for_s;
  return status_of(identification_health(facts));
}

void IdentificationNode::append_counters(dds::HealthCounters& c) {
  const SampleBuilderCounters& b = core_.builder_counters();
  c.emplace_back("epochs", static_cast<double>(b.epochs));
  c.emplace_back("samples_accepted", static_cast<double>(b.accepted));
  c.emplace_back("rejected_innovation", static_cast<double>(b.innovation));
  c.emplace_back("rejected_cross_track", static_cast<double>(b.cross_track));
  c.emplace_back("samples_reversing", static_cast<double>(b.reversing_accepted));
  // Brakings that ended in a standstill and the samples they withdrew from K (braking_stop.hpp).
  c.emplace_back("braking_stops", static_cast<double>(core_.braking_stop_counters().stops));
  c.emplace_back("braking_samples_withdrawn", static_cast<double>(core_.braking_stop_counters().samples_withdrawn));
  // The GNSS latency in force and its one-sigma when it was applied (0 when fixed, -1 while none
  // was applied).
  const GnssLatencyEstimate& latency = core_.latency();
  c.emplace_back("gnss_latency_s", latency.applied_s);
  c.emplace_back("gnss_latency_sigma_s", latency.applied_sigma_s >= 0.0 ? latency.applied_sigma_s : -1.0);
  c.emplace_back("rejected_min_speed", static_cast<double>(b.min_speed));
  c.emplace_back("rejected_invalid_fix", static_cast<double>(b.invalid_fix));
  c.emplace_back("rejected_yaw_rate", static_cast<double>(b.yaw_rate));
  c.emplace_back("odometer_jumps_rejected", static_cast<double>(b.odometer_jumps_rejected));
  c.emplace_back("odometer_rebases", static_cast<double>(b.odometer_rebases));
  c.emplace_back("misalignments_applied", static_cast<double>(lifecycle_.misalignments_applied()));
  c.emplace_back("heartbeats", static_cast<double>(scale_factor_->heartbeats()));
  c.emplace_back("k_commands", static_cast<double>(k_commands_));
  c.emplace_back("ownership_strength", static_cast<double>(instance_.ownership_strength));
  for (auto& counter : lifecycle_.restart_counters()) c.push_back(std::move(counter));
  const auto& last = lifecycle_.last_output();
  if (last && last->main.valid) {
    c.emplace_back("k_m_per_pulse", last->main.k_m_per_pulse);
    c.emplace_back("sigma_k_m_per_pulse", last->main.sigma_m_per_pulse);
  }
  if (last) {
    // 1 while the K published is the latency search's K of the drive's start, not the estimator's.
    c.emplace_back("k_from_start_latency", last->k_from_start_latency ? 1.0 : 0.0);
    c.emplace_back("turn_slip_s_per_rad", last->turn_slip.g_s_per_rad);
    c.emplace_back("turn_slip_sigma_s_per_rad", last->turn_slip.sigma_s_per_rad);
    c.emplace_back("turn_slip_samples", static_cast<double>(last->turn_slip.samples));
    c.emplace_back("turn_slip_outliers", static_cast<double>(last->turn_slip.outliers));
    c.emplace_back("turn_slip_applies", last->turn_slip.applies ? 1.0 : 0.0);
  }
}

}  // namespace odonav::identification
