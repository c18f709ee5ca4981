#include "calibration_node.hpp"

#include <cmath>
#include <ctime>
#include <limits>
#include <stdexcept>

#include <spdlog/spdlog.h>

#include "odonav/calibration/calibration_health.hpp"
#include "odonav/calibration/calibration_options.hpp"
#include "odonav/dds/output_messages.hpp"
#include "odonav/dds/time.hpp"
#include "odonav/topics.hpp"

namespace odonav::calibration {

void add_calibration_node_options(Options& o) {
  add_calibration_options(o);
  dds::add_sensor_node_options(o, "nothing can be calibrated", "calibration-<vehicle>.ckpt");
}

MisalignmentCalibratorParams calibration_node_params_from(const Options& o) {
  MisalignmentCalibratorParams p = calibration_params_from(o);
  p.use_ins = o.get_bool("use-ins");
  return p;
}

odonav::msg::Misalignment misalignment_message(const MisalignmentOutput& out, const std::string& vehicle_id) {
  odonav::msg::Misalignment m = dds::message_of(output_row(out));  // the field table
  m.vehicle_id(vehicle_id);
  return m;
}

CalibrationNode::CalibrationNode(dds::ComponentRuntime& runtime, const MisalignmentCalibratorParams& params,
                                 const CheckpointSettings& checkpoint)
    // An exact estimate late rather than a different one: an input whose samples are declared
    // published but still on their way (a restart's history hand-over) is waited for up to the
    // producers' history length (EventTimeAligner, "Samples in flight").
    : EventTimeNode(runtime, calibration_inputs(params), kInFlightMaxWait_s),
      params_(params),
      core_(dds::make_node_core<MisalignmentCalibrator>("calibration", params)),
      lifecycle_(checkpoint, runtime.settings().vehicle_id, core_.restore_margin_s()),
      gnss_(input("gnss")),
      ins_(find_input("ins")),
      misalignment_(runtime.participant(), topics::kMisalignment.name, topics::kMisalignment.writer_profile) {
  runtime.set_command_handler([this](const odonav::msg::Command& c) { return on_command(c); });
  // Before any reader exists: no sample can reach the core before the restored state.
  lifecycle_.start(core_, static_cast<int64_t>(std::time(nullptr)), dds::steady_now_s());
  if (const auto restored = lifecycle_.take_restored_output()) {
    misalignment_.publish(misalignment_message(*restored, runtime_.settings().vehicle_id), dds::steady_now_s());
    last_output_ = restored;
    count_outputs(1);
  }
  // Resumed from a checkpoint: the sensor readers ask the producers for their history (30 s), so the
  // data of the downtime is processed from the checkpoint on (what predates it is skipped). A fresh
  // start reads like every other consumer: from the moment it matched.
  const char* sensor_profile = dds::sensor_reader_profile(lifecycle_.restored_t_s());

  gnss_reader_ = subscribe<odonav::msg::GnssFix>(
      topics::with_reader_profile(topics::kGnssFix, sensor_profile), gnss_,
      [this](const auto& m, double t_s) {
        if (!gnss_may_pass()) {
          pending_gnss_.emplace_back(t_s, dds::gnss_sample_from(m));
          return;
        }
        if (!lifecycle_.skip_sample(CalibrationInput::kGnss, t_s)) core_.add_gnss(dds::gnss_sample_from(m));
      },
      [this](const odonav::msg::GnssFix& m) {
        if (!ins_) note_live_sample(m.header().stamp());
      });
  if (ins_) {
    // The INS messages declare which GNSS epochs are out: through a GNSS outage the calibration
    // goes on with the INS instead of waiting (and then refusing the first fix after it as late).
    ins_reader_ = subscribe<odonav::msg::InsAttitude>(
        topics::with_reader_profile(topics::kInsAttitude, sensor_profile), *ins_,
        [this](const auto& m, double t_s) {
          const bool skip = lifecycle_.skip_sample(CalibrationInput::kIns, t_s);
          flush_pending_gnss();
          if (skip) return;
          if (!m.valid()) {
            ++ins_->dropped_invalid;  // the stream advanced, but the attitude is not usable
            return;
          }
          core_.add_ins(dds::ins_sample_from(m));
        },
        [this](const odonav::msg::InsAttitude& m) {
          declare_gnss_published(gnss_, m);
          note_live_sample(m.header().stamp());
        });
  }
}

void CalibrationNode::note_live_sample(const builtin_interfaces::msg::Time& stamp) {
  // On arrival, before the aligner holds the sample back for the other input: the live edge is
  // the newest stamp handed over in the first second, not the newest processed.
  try {
    lifecycle_.note_live_sample(dds::to_seconds(stamp), dds::steady_now_s());
  } catch (const std::invalid_argument&) {
    // A bad stamp is counted and told by admit_sample right after this.
  }
}

bool CalibrationNode::gnss_may_pass() const {
  return !lifecycle_.restored_t_s() || !ins_ || lifecycle_.first_sample_seen(CalibrationInput::kIns);
}

void CalibrationNode::flush_pending_gnss() {
  if (pending_gnss_.empty() || !gnss_may_pass()) return;
  // Before any INS sample reaches the core: the watermark needs INS data, so no epoch was processed
  // yet and these go in before the first one.
  for (const auto& [t_s, g] : pending_gnss_)
    if (!lifecycle_.skip_sample(CalibrationInput::kGnss, t_s)) core_.add_gnss(g);
  pending_gnss_.clear();
}

CalibrationNode::~CalibrationNode() { close_inputs(); }

void CalibrationNode::close_inputs() {
  gnss_reader_.reset();
  ins_reader_.reset();
}

void CalibrationNode::publish(const std::vector<MisalignmentOutput>& outputs) {
  const double now = dds::steady_now_s();
  const std::vector<MisalignmentOutput> to_publish = lifecycle_.outputs_to_publish(outputs, now);
  for (const MisalignmentOutput& o : to_publish) {
    misalignment_.publish(misalignment_message(o, runtime_.settings().vehicle_id), now);
    last_output_ = o;
  }
  count_outputs(to_publish.size());
  lifecycle_.checkpoint_if_due(core_);
}

void CalibrationNode::process_until(double watermark_s) { publish(core_.process_until(watermark_s)); }

void CalibrationNode::finish() {
  publish(core_.finish());
  lifecycle_.checkpoint_at_finish(core_);
}

std::vector<dds::detail::WriterBase*> CalibrationNode::output_writers() { return {&misalignment_.writer()}; }

dds::CommandAck CalibrationNode::on_command(const odonav::msg::Command& c) {
  using namespace odonav::msg;
  if (auto ack = dds::run_estimation_command(
          c, core_, {"misalignment calibration restarted", "misalignment frozen", "misalignment unfrozen"}))
    return *ack;
  switch (c.command()) {
    case COMMAND_SET_K:
      return {c.command_id(), COMMAND_RESULT_REJECTED, "set_k is for odonav-dead-reckoning, not calibration"};
    case COMMAND_RELEASE_K:
      return {c.command_id(), COMMAND_RESULT_REJECTED, "release_k is for odonav-dead-reckoning, not calibration"};
    default: break;
  }
  return {c.command_id(), COMMAND_RESULT_REJECTED, "unknown command kind"};
}

dds::EventTimeNode::Status CalibrationNode::node_status(double now_s) {
  CalibrationHealthFacts facts;
  static_cast<RestartHealthNotes&>(facts) = lifecycle_.restart().health_notes();
  facts.use_ins = params_.use_ins;
  if (last_output_) facts.current = core_.current();
  facts.now_s = now_s;
  return status_of(calibration_health(facts));
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
  // Brakings that ended in a standstill and the used epochs they withdrew (braking_stop.hpp).
  c.emplace_back("braking_stops", static_cast<double>(k.braking_stops));
  c.emplace_back("epochs_braking_withdrawn", static_cast<double>(k.braking_withdrawn));
  c.emplace_back("heartbeats", static_cast<double>(misalignment_.heartbeats()));
  for (auto& counter : lifecycle_.restart().counters()) c.push_back(std::move(counter));
  if (last_output_) {
    c.emplace_back("heading_deg", rad_to_deg(last_output_->misalignment.heading_rad));
    c.emplace_back("pitch_deg", rad_to_deg(last_output_->misalignment.pitch_rad));
  }
}

}  // namespace odonav::calibration
