#include "calibration_node.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

#include "odonav/calibration/calibration_options.hpp"
#include "odonav/dds/time.hpp"
#include "odonav/topics.hpp"

namespace odonav::nodes {

namespace {
odonav::msg::MisalignmentState to_message_state(CalibrationState s) {
  switch (s) {
    case CalibrationState::kWaiting: return odonav::msg::MISALIGNMENT_WAITING;
    case CalibrationState::kCalibrating: return odonav::msg::MISALIGNMENT_CALIBRATING;
    case CalibrationState::kConverged: return odonav::msg::MISALIGNMENT_CONVERGED;
    case CalibrationState::kFrozen: return odonav::msg::MISALIGNMENT_FROZEN;
  }
  return odonav::msg::MISALIGNMENT_WAITING;
}

MisalignmentCalibrator make_calibrator(const MisalignmentCalibratorParams& p) {
  try {
    return MisalignmentCalibrator(p);
  } catch (const std::invalid_argument& e) {
    throw ConfigError(std::string("calibration parameters: ") + e.what());
  }
}
}  // namespace

void add_calibration_node_options(Options& o) {
  add_calibration_options(o);
  add_lever_arm_option(o);
  o.add_bool("use-ins", true,
             "the vehicle has an INS; false = degraded mode (nothing can be calibrated), as odonav-offline "
             "does for a dataset without ins.csv");
}

MisalignmentCalibratorParams calibration_node_params_from(const Options& o) {
  MisalignmentCalibratorParams p = calibration_params_from(o);
  p.use_ins = o.get_bool("use-ins");
  return p;
}

odonav::msg::Misalignment misalignment_message(const MisalignmentOutput& out, const std::string& vehicle_id) {
  odonav::msg::Misalignment m;
  m.header(dds::make_header(out.t_s, "body"));
  m.vehicle_id(vehicle_id);
  m.heading_rad(out.misalignment.heading_rad);
  m.pitch_rad(out.misalignment.pitch_rad);
  m.heading_std_rad(std::isfinite(out.sigma_heading_rad) ? out.sigma_heading_rad : -1.0);
  m.pitch_std_rad(std::isfinite(out.sigma_pitch_rad) ? out.sigma_pitch_rad : -1.0);
  m.samples_used(static_cast<uint32_t>(std::min<uint64_t>(out.samples_used, std::numeric_limits<uint32_t>::max())));
  m.converged(out.converged);
  m.state(to_message_state(out.state));
  return m;
}

CalibrationNode::CalibrationNode(dds::ComponentRuntime& runtime, const MisalignmentCalibratorParams& params)
    : EventTimeNode(runtime),
      params_(params),
      core_(make_calibrator(params)),
      gnss_(add_input("gnss", true)),
      misalignment_(runtime.participant(), topics::kMisalignment.name, topics::kMisalignment.writer_profile) {
  if (params_.use_ins) ins_ = &add_input("ins", true);
  runtime.set_command_handler([this](const odonav::msg::Command& c) { return on_command(c); });

  gnss_reader_ = subscribe<odonav::msg::GnssFix>(topics::kGnssFix, gnss_, [this](const auto& m, double) {
    core_.add_gnss(dds::gnss_sample_from(m));
  });
  if (ins_) {
    // The INS messages declare which GNSS epochs are out: through a GNSS outage the calibration
    // goes on with the INS instead of waiting (and then refusing the first fix after it as late).
    ins_reader_ = subscribe<odonav::msg::InsAttitude>(
        topics::kInsAttitude, *ins_,
        [this](const auto& m, double) {
          if (!m.valid()) {
            ++ins_->dropped_invalid;  // the stream advanced, but the attitude is not usable
            return;
          }
          core_.add_ins(dds::ins_sample_from(m));
        },
        [this](const odonav::msg::InsAttitude& m) { declare_gnss_published(gnss_, m); });
  }
}

CalibrationNode::~CalibrationNode() { close_inputs(); }

void CalibrationNode::close_inputs() {
  gnss_reader_.reset();
  ins_reader_.reset();
}

void CalibrationNode::publish(const std::vector<MisalignmentOutput>& outputs) {
  const double now = dds::steady_now_s();
  for (const MisalignmentOutput& o : outputs) {
    misalignment_.publish(misalignment_message(o, runtime_.settings().vehicle_id), now);
    last_output_ = o;
  }
  count_outputs(outputs.size());
}

void CalibrationNode::process_until(double watermark_s) { publish(core_.process_until(watermark_s)); }

void CalibrationNode::finish() { publish(core_.finish()); }

std::vector<dds::detail::WriterBase*> CalibrationNode::output_writers() { return {&misalignment_.writer()}; }

dds::CommandAck CalibrationNode::on_command(const odonav::msg::Command& c) {
  using namespace odonav::msg;
  switch (c.command()) {
    case COMMAND_RESET_ESTIMATION:
      core_.reset();
      return {c.command_id(), COMMAND_RESULT_ACCEPTED, "misalignment calibration restarted"};
    case COMMAND_FREEZE_ESTIMATION:
      core_.freeze();
      return {c.command_id(), COMMAND_RESULT_ACCEPTED, "misalignment frozen"};
    case COMMAND_UNFREEZE_ESTIMATION:
      core_.unfreeze();
      return {c.command_id(), COMMAND_RESULT_ACCEPTED, "misalignment unfrozen"};
    case COMMAND_SET_K:
      return {c.command_id(), COMMAND_RESULT_REJECTED, "set_k is for odonav-dead-reckoning, not calibration"};
    case COMMAND_RELEASE_K:
      return {c.command_id(), COMMAND_RESULT_REJECTED, "release_k is for odonav-dead-reckoning, not calibration"};
  }
  return {c.command_id(), COMMAND_RESULT_REJECTED, "unknown command kind"};
}

dds::EventTimeNode::Status CalibrationNode::node_status(double /*now_s*/) {
  using namespace odonav::msg;
  if (!params_.use_ins) return {HEALTH_STATE_DEGRADED, HEALTH_LEVEL_WARN, "no INS: the misalignment cannot be calibrated"};
  if (!last_output_) return {HEALTH_STATE_STARTING, HEALTH_LEVEL_OK, "waiting for the first GNSS epoch to process"};
  const MisalignmentOutput cur = core_.current();
  switch (cur.state) {
    case CalibrationState::kConverged: return {HEALTH_STATE_RUNNING, HEALTH_LEVEL_OK, ""};
    case CalibrationState::kFrozen: return {HEALTH_STATE_RUNNING, HEALTH_LEVEL_OK, "frozen by command"};
    case CalibrationState::kWaiting:
    case CalibrationState::kCalibrating: return {HEALTH_STATE_RUNNING, HEALTH_LEVEL_OK, "not converged yet: " + cur.reason};
  }
  return {HEALTH_STATE_RUNNING, HEALTH_LEVEL_OK, cur.reason};
}

void CalibrationNode::append_counters(dds::HealthCounters& c) {
  const MisalignmentCounters& k = core_.counters();
  c.emplace_back("epochs", static_cast<double>(k.epochs));
  c.emplace_back("epochs_used", static_cast<double>(k.used));
  c.emplace_back("epochs_turning", static_cast<double>(k.turning));
  c.emplace_back("epochs_outlier", static_cast<double>(k.outlier));
  c.emplace_back("epochs_low_speed", static_cast<double>(k.low_speed));
  c.emplace_back("epochs_invalid_fix", static_cast<double>(k.invalid_fix));
  c.emplace_back("epochs_no_attitude", static_cast<double>(k.no_attitude));
  c.emplace_back("heartbeats", static_cast<double>(misalignment_.heartbeats()));
  if (last_output_) {
    c.emplace_back("heading_deg", rad_to_deg(last_output_->misalignment.heading_rad));
    c.emplace_back("pitch_deg", rad_to_deg(last_output_->misalignment.pitch_rad));
  }
}

}  // namespace odonav::nodes
