#include "identification_node.hpp"

#include "odonav/lever_arm_option.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

#include "odonav/consumer_rules.hpp"
#include "odonav/dds/time.hpp"
#include "odonav/identification/identification_options.hpp"
#include "odonav/topics.hpp"

namespace odonav::nodes {

namespace {
IdentificationCore make_core(const IdentificationParams& p) {
  try {
    return IdentificationCore(p);
  } catch (const std::invalid_argument& e) {
    throw ConfigError(std::string("identification parameters: ") + e.what());
  }
}

uint32_t clamp_u32(uint64_t v) { return static_cast<uint32_t>(std::min<uint64_t>(v, std::numeric_limits<uint32_t>::max())); }
}  // namespace

void add_identification_node_options(Options& o) {
  add_identification_options(o);
  add_lever_arm_option(o);
  o.add_bool("use-ins", true,
             "the vehicle has an INS; false = degraded mode (forward speed = |GNSS velocity|), as "
             "odonav-offline does for a dataset without ins.csv");
}

IdentificationParams identification_node_params_from(const Options& o) {
  IdentificationParams p = identification_params_from(o);
  p.builder.use_ins = o.get_bool("use-ins");
  p.builder.lever_arm_body_m = lever_arm_from(o);
  p.run_all_estimators = false;  // the node publishes the main estimator only
  return p;
}

odonav::msg::ScaleFactor scale_factor_message(const IdentificationOutput& out, const std::string& estimator,
                                              const std::string& vehicle_id) {
  odonav::msg::ScaleFactor m;
  m.header(dds::make_header(out.t_s, "odometer"));
  m.vehicle_id(vehicle_id);
  const ScaleFactorEstimate& e = out.main;
  const bool has_value = e.valid && std::isfinite(e.k_m_per_pulse);
  m.k_m_per_pulse(has_value ? e.k_m_per_pulse : 0.0);
  m.sigma_m_per_pulse(has_value && std::isfinite(e.sigma_m_per_pulse) && e.sigma_m_per_pulse > 0.0
                          ? e.sigma_m_per_pulse
                          : -1.0);
  m.forgetting_factor(e.forgetting_factor);
  m.window_fill(e.window_fill);
  m.estimator(estimator);
  m.converged(has_value && e.converged);
  m.samples_accepted(clamp_u32(out.samples_accepted));
  m.samples_rejected(clamp_u32(out.samples_rejected));
  m.frozen(out.frozen);
  return m;
}

IdentificationNode::IdentificationNode(dds::ComponentRuntime& runtime, const IdentificationParams& params)
    : EventTimeNode(runtime),
      params_(params),
      core_(make_core(params)),
      odometer_(add_input("odometer", true)),
      gnss_(add_input("gnss", true)),
      misalignment_(add_input("misalignment", false, &gnss_)),
      scale_factor_(runtime.participant(), topics::kScaleFactor.name, topics::kScaleFactor.writer_profile) {
  if (params_.builder.use_ins) ins_ = &add_input("ins", true);
  runtime.set_command_handler([this](const odonav::msg::Command& c) { return on_command(c); });

  const std::string& vehicle = runtime.settings().vehicle_id;
  auto& p = runtime.participant();
  odometer_reader_ = std::make_unique<dds::Reader<odonav::msg::Odometer>>(
      p, topics::kOdometer.name, topics::kOdometer.reader_profile, [this, vehicle](const odonav::msg::Odometer& m) {
        if (m.vehicle_id() != vehicle) return;
        runtime_.post([this, m] {
          dds::admit_sample(aligner_, odometer_, m.header().stamp(), dds::steady_now_s(),
                            [&](double) { core_.add_odometer(dds::odometer_sample_from(m)); });
        });
      });
  gnss_reader_ = std::make_unique<dds::Reader<odonav::msg::GnssFix>>(
      p, topics::kGnssFix.name, topics::kGnssFix.reader_profile, [this, vehicle](const odonav::msg::GnssFix& m) {
        if (m.vehicle_id() != vehicle) return;
        runtime_.post([this, m] {
          dds::admit_sample(aligner_, gnss_, m.header().stamp(), dds::steady_now_s(),
                            [&](double) { core_.add_gnss(dds::gnss_sample_from(m)); });
        });
      });
  if (ins_) {
    ins_reader_ = std::make_unique<dds::Reader<odonav::msg::InsAttitude>>(
        p, topics::kInsAttitude.name, topics::kInsAttitude.reader_profile,
        [this, vehicle](const odonav::msg::InsAttitude& m) {
          if (m.vehicle_id() != vehicle) return;
          runtime_.post([this, m] {
            dds::admit_sample(aligner_, *ins_, m.header().stamp(), dds::steady_now_s(), [&](double) {
              if (!m.valid()) {
                ++ins_->dropped_invalid;
                return;
              }
              core_.add_ins(dds::ins_sample_from(m));
            });
          });
        });
  }
  misalignment_reader_ = std::make_unique<dds::Reader<odonav::msg::Misalignment>>(
      p, topics::kMisalignment.name, topics::kMisalignment.reader_profile,
      [this, vehicle](const odonav::msg::Misalignment& m) {
        if (m.vehicle_id() != vehicle) return;
        runtime_.post([this, m] {
          dds::admit_sample(aligner_, misalignment_, m.header().stamp(), dds::steady_now_s(),
                            [&](double t_s) { on_misalignment(m, t_s); });
        });
      });
}

IdentificationNode::~IdentificationNode() { close_inputs(); }

void IdentificationNode::close_inputs() {
  odometer_reader_.reset();
  gnss_reader_.reset();
  ins_reader_.reset();
  misalignment_reader_.reset();
}

void IdentificationNode::on_misalignment(const odonav::msg::Misalignment& m, double t_s) {
  // Same rule as odonav-offline (consumer_rules.hpp).
  if (!misalignment_applicable(m.converged(), m.samples_used())) return;
  if (!std::isfinite(m.heading_rad()) || !std::isfinite(m.pitch_rad()))
    throw StreamInputError("misalignment: angles are not finite");
  core_.add_misalignment(t_s, Misalignment{m.heading_rad(), m.pitch_rad()});
  ++misalignments_applied_;
}

void IdentificationNode::publish(const std::vector<IdentificationOutput>& outputs) {
  const double now = dds::steady_now_s();
  for (const IdentificationOutput& o : outputs) {
    scale_factor_.publish(scale_factor_message(o, core_.main_estimator_name(), runtime_.settings().vehicle_id), now);
    last_output_ = o;
  }
  count_outputs(outputs.size());
}

void IdentificationNode::process_until(double watermark_s) { publish(core_.process_until(watermark_s)); }

void IdentificationNode::finish() { publish(core_.finish()); }

std::vector<dds::detail::WriterBase*> IdentificationNode::output_writers() { return {&scale_factor_.writer()}; }

dds::CommandAck IdentificationNode::on_command(const odonav::msg::Command& c) {
  using namespace odonav::msg;
  switch (c.command()) {
    case COMMAND_RESET_CALIBRATION:
      core_.reset();
      return {c.command_id(), COMMAND_RESULT_ACCEPTED, "scale-factor estimator reset"};
    case COMMAND_FREEZE_IDENTIFICATION:
      core_.freeze();
      return {c.command_id(), COMMAND_RESULT_ACCEPTED, "identification frozen: K held"};
    case COMMAND_UNFREEZE_IDENTIFICATION:
      core_.unfreeze();
      return {c.command_id(), COMMAND_RESULT_ACCEPTED, "identification resumed"};
    case COMMAND_SET_K:
      // ScaleFactor carries no source: a commanded K published here would look identified.
      return {c.command_id(), COMMAND_RESULT_REJECTED,
              "set_k is executed by odonav-dead-reckoning (the K it navigates with); identification goes on"};
  }
  return {c.command_id(), COMMAND_RESULT_REJECTED, "unknown command kind"};
}

dds::EventTimeNode::Status IdentificationNode::node_status(double now_s) {
  using namespace odonav::msg;
  Status s{HEALTH_STATE_RUNNING, HEALTH_LEVEL_OK, ""};
  if (!last_output_) {
    s = {HEALTH_STATE_STARTING, HEALTH_LEVEL_OK, "waiting for the first GNSS epoch to process"};
  } else if (last_output_->frozen) {
    s.reason = "frozen by command: K held";
  } else if (!last_output_->main.valid || !last_output_->main.converged) {
    s.reason = "K not converged yet";
  }
  // The misalignment is optional: say why zero is used, without raising the level.
  std::string mis;
  if (input_absent(misalignment_, now_s))
    mis = "using zero misalignment: no calibration";
  else if (!input_heard(misalignment_, now_s))
    mis = "no misalignment received yet: using zero";
  else if (misalignments_applied_ == 0)
    mis = "misalignment not converged yet: using zero";
  if (!mis.empty()) {
    s.reason = s.reason.empty() ? mis : s.reason + "; " + mis;
    if (s.state == HEALTH_STATE_RUNNING && input_absent(misalignment_, now_s)) s.state = HEALTH_STATE_DEGRADED;
  }
  return s;
}

void IdentificationNode::append_counters(dds::HealthCounters& c) {
  const SampleBuilderCounters& b = core_.builder_counters();
  c.emplace_back("epochs", static_cast<double>(b.epochs));
  c.emplace_back("samples_accepted", static_cast<double>(b.accepted));
  c.emplace_back("rejected_innovation", static_cast<double>(b.innovation));
  c.emplace_back("rejected_min_speed", static_cast<double>(b.min_speed));
  c.emplace_back("rejected_invalid_fix", static_cast<double>(b.invalid_fix));
  c.emplace_back("rejected_yaw_rate", static_cast<double>(b.yaw_rate));
  c.emplace_back("misalignments_applied", static_cast<double>(misalignments_applied_));
  c.emplace_back("heartbeats", static_cast<double>(scale_factor_.heartbeats()));
  if (last_output_ && last_output_->main.valid) {
    c.emplace_back("k_m_per_pulse", last_output_->main.k_m_per_pulse);
    c.emplace_back("sigma_k_m_per_pulse", last_output_->main.sigma_m_per_pulse);
  }
}

}  // namespace odonav::nodes
