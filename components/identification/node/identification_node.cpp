#include "identification_node.hpp"

#include "odonav/lever_arm_option.hpp"

#include <cmath>
#include <ctime>
#include <filesystem>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <thread>

#include <spdlog/spdlog.h>

#include "odonav/consumer_rules.hpp"
#include "odonav/dds/time.hpp"
#include "odonav/identification/checkpoint.hpp"
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

// How long (wall time) the health reason tells about the restore: long enough for an operator or
// a monitor to see it, short enough not to hide later reasons.
constexpr double kRestoreNoteDuration_s = 30.0;
// Odometer and INS samples this much older than the checkpoint are still fed: the epochs right after
// it interpolate the pulse count and attitude between samples on both sides (max_bracket_s).
constexpr double kSensorMarginBeforeCheckpoint_s = 1.0;
}  // namespace

void add_identification_node_options(Options& o) {
  add_identification_options(o);
  add_lever_arm_option(o);
  o.add_bool("use-ins", true,
             "the vehicle has an INS; false = degraded mode (forward speed = |GNSS velocity|), as "
             "odonav-offline does for a dataset without ins.csv");
  o.add_string("state-dir", "",
               "folder of the checkpoint identification-<vehicle>.ckpt (restored at start, written every "
               "--checkpoint-every-s of event time and at shutdown); empty = no checkpoint");
  o.add_double("checkpoint-every-s", 5.0, "checkpoint period in event time of the processed epochs (s)", 0.1, 1e6);
  o.add_string("instance", kDefaultIdentificationInstance,
               "name of this instance, published as ScaleFactor.source and naming its state files "
               "(e.g. identification/standby for a hot standby; letters, digits, . _ - /)");
  o.add_int("ownership-strength", 10,
            "OWNERSHIP_STRENGTH of the scale-factor writer: readers follow the strongest live instance "
            "(primary e.g. 20, standby 10)",
            0, 1000000);
  o.add_double("nominal-k", 0.0125, "reference K (m/pulse) a set_k command must stay within 0.1x..10x of", 1e-6,
               10.0);
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
  s.nominal_k_m_per_pulse = o.get_double("nominal-k");
  return s;
}

CheckpointSettings checkpoint_settings_from(const Options& o) {
  CheckpointSettings c;
  c.state_dir = o.get_string("state-dir");
  c.every_s = o.get_double("checkpoint-every-s");
  c.config_hash = config_hash_of(o.values_as_text());
  return c;
}

IdentificationParams identification_node_params_from(const Options& o) {
  IdentificationParams p = identification_params_from(o);
  p.builder.use_ins = o.get_bool("use-ins");
  p.builder.lever_arm_body_m = lever_arm_from(o);
  p.run_all_estimators = false;  // the node publishes the main estimator only
  // The pulse-jump gate converts its maximum speed to pulses with the vehicle's nominal K: a fine
  // encoder (small K) must not see real motion as a jump.
  p.builder.odometer_jump_gate.k_m_per_pulse = o.get_double("nominal-k");
  return p;
}

odonav::msg::ScaleFactor scale_factor_message(const IdentificationOutput& out, const std::string& estimator,
                                              const std::string& vehicle_id, const std::string& source) {
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
  m.source(source);
  return m;
}

namespace {
// The scale-factor writer: the profile, plus ownership strength always, plus TRANSIENT with the
// SQLite persistence when there is a state directory (docs/DDS.md §5: plugin, file, fixed GUID).
dds::WriterSettings scale_factor_writer_settings(const std::string& state_dir, const std::string& vehicle_id,
                                                 const InstanceSettings& instance) {
  dds::WriterSettings w;
  w.ownership_strength = instance.ownership_strength;
  if (state_dir.empty()) {
    spdlog::info("scale-factor writer: TRANSIENT_LOCAL (no --state-dir: the last K survives in this process only)");
    return w;
  }
  try {
    std::filesystem::create_directories(state_dir);
    const std::string db = persistence_db_path(state_dir, vehicle_id, instance.instance);
    const std::string guid = persistence_guid(vehicle_id, instance.instance);
    w.transient = true;
    w.properties = {{"dds.persistence.plugin", "builtin.SQLITE3"},
                    {"dds.persistence.sqlite3.filename", db},
                    {"dds.persistence.guid", guid}};
    spdlog::info("scale-factor writer: TRANSIENT, SQLite persistence {} (guid {})", db, guid);
  } catch (const std::exception& e) {
    throw ConfigError("--state-dir '" + state_dir + "': " + e.what());
  }
  return w;
}

bool has_persisted_history(const std::string& state_dir, const std::string& vehicle_id, const InstanceSettings& instance) {
  if (state_dir.empty()) return false;
  try {
    const std::string db = persistence_db_path(state_dir, vehicle_id, instance.instance);
    return std::filesystem::exists(db) && std::filesystem::file_size(db) > 0;
  } catch (const std::exception&) {
    return false;  // scale_factor_writer_settings reports a bad state directory or name
  }
}
}  // namespace

IdentificationNode::IdentificationNode(dds::ComponentRuntime& runtime, const IdentificationParams& params,
                                       const CheckpointSettings& checkpoint, const InstanceSettings& instance)
    : EventTimeNode(runtime),
      params_(params),
      instance_(instance),
      core_(make_core(params)),
      checkpoint_(checkpoint),
      odometer_(add_input("odometer", true)),
      gnss_(add_input("gnss", true)),
      misalignment_(add_input("misalignment", false, &gnss_)),
      persisted_history_(has_persisted_history(checkpoint.state_dir, runtime.settings().vehicle_id, instance)) {
  if (params_.builder.use_ins) ins_ = &add_input("ins", true);
  runtime.set_command_handler([this](const odonav::msg::Command& c) { return on_command(c); });
  // Before any reader exists: no sample can reach the core before the restored state.
  if (!checkpoint_.state_dir.empty()) restore_checkpoint();
  // The persistence database holds the previous run's last published K. It is served (TRANSIENT)
  // only together with the estimator state it came from: without a restored checkpoint (none,
  // corrupt, mismatched) the estimator starts from nominal K, and an old K stamped in another
  // run's time would mislead every late reader. So it is moved aside, never deleted.
  if (persisted_history_ && !restored_t_s_) {
    const std::string db = persistence_db_path(checkpoint_.state_dir, runtime.settings().vehicle_id, instance_.instance);
    const std::string aside = db + ".discarded-" + std::to_string(static_cast<long long>(std::time(nullptr)));
    std::error_code ec;
    std::filesystem::rename(db, aside, ec);
    if (ec)
      spdlog::error("persistence database {} kept: could not move it aside ({}); late readers may get its old K", db,
                    ec.message());
    else
      spdlog::warn("persistence database {} moved aside to {}: no checkpoint restored, so its K is not served", db,
                   aside);
    persisted_history_ = static_cast<bool>(ec);
  }
  scale_factor_ = std::make_unique<dds::Writer<odonav::msg::ScaleFactor>>(
      runtime.participant(), topics::kScaleFactor.name, topics::kScaleFactor.writer_profile,
      scale_factor_writer_settings(checkpoint_.state_dir, runtime.settings().vehicle_id, instance_));
  if (restored_t_s_ && last_output_) {
    if (persisted_history_) {
      // The TRANSIENT writer already serves the last estimate the previous run published (the
      // checkpoint is written after publishing, so that one is as new or newer): publishing the
      // restored K would step a late reader back to the checkpoint time.
      spdlog::info("restored K not republished: the scale-factor writer serves the previous run's last estimate "
                   "from its SQLite persistence");
    } else {
      // Publish the restored K at once (TRANSIENT_LOCAL): a consumer that lost it, or a late
      // reader, has it before any new sample arrives.
      write_scale_factor(*last_output_, dds::steady_now_s());
      count_outputs(1);
    }
  }

  odometer_reader_ = subscribe<odonav::msg::Odometer>(topics::kOdometer, odometer_, [this](const auto& m, double t_s) {
    if (!before_checkpoint(t_s, kSensorMarginBeforeCheckpoint_s)) core_.add_odometer(dds::odometer_sample_from(m));
  });
  gnss_reader_ = subscribe<odonav::msg::GnssFix>(topics::kGnssFix, gnss_, [this](const auto& m, double t_s) {
    // The epoch AT the checkpoint time is fed again: it re-starts the sample chain exactly where the
    // checkpoint left it (its output is not republished, see publish()).
    if (!before_checkpoint(t_s, 0.0)) core_.add_gnss(dds::gnss_sample_from(m));
  });
  if (ins_) {
    ins_reader_ = subscribe<odonav::msg::InsAttitude>(topics::kInsAttitude, *ins_, [this](const auto& m, double t_s) {
      if (before_checkpoint(t_s, kSensorMarginBeforeCheckpoint_s)) return;
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

bool IdentificationNode::before_checkpoint(double t_s, double margin_s) {
  if (!restored_t_s_ || t_s >= *restored_t_s_ - margin_s) return false;
  ++skipped_before_checkpoint_;
  return true;
}

void IdentificationNode::publish(const std::vector<IdentificationOutput>& outputs) {
  const double now = dds::steady_now_s();
  std::size_t published = 0;
  for (IdentificationOutput o : outputs) {
    // The epoch at the checkpoint time was published (by the previous run and at restore) already.
    if (restored_t_s_ && o.t_s <= *restored_t_s_) continue;
    o.samples_accepted += restored_accepted_;
    o.samples_rejected += restored_rejected_;
    write_scale_factor(o, now);
    last_output_ = o;
    last_processed_t_s_ = o.t_s;
    ++published;
  }
  count_outputs(published);
  // The estimator state now is the one after the last processed epoch: checkpoint it when due.
  if (!checkpoint_file_.empty() && last_processed_t_s_ &&
      (!last_checkpoint_t_s_ || *last_processed_t_s_ >= *last_checkpoint_t_s_ + checkpoint_.every_s))
    write_checkpoint(*last_processed_t_s_);
}

void IdentificationNode::write_scale_factor(const IdentificationOutput& o, double now_s) {
  odonav::msg::ScaleFactor m =
      scale_factor_message(o, core_.main_estimator_name(), runtime_.settings().vehicle_id, instance_.instance);
  if (!scale_factor_->write(m)) {
    ++write_failures_;
    spdlog::warn("{}: write refused by the middleware ({} so far)", scale_factor_->topic_name(), write_failures_);
  }
  last_scale_factor_ = std::move(m);
  last_scale_factor_write_s_ = now_s;
  // KEEP_LAST 1: a burst (catching up, the drain) must give the transport time to deliver.
  if (++scale_factors_written_ % 100 == 0) std::this_thread::sleep_for(std::chrono::milliseconds(2));
}

void IdentificationNode::on_tick(double now_s) {
  // The heartbeat keeps the 300 ms deadline of the EXCLUSIVE scale-factor topic while nothing new
  // is published (GNSS outage, gated epochs are published anyway): a silent owner is one that died,
  // and readers then switch to the standby. Same stamp: consumers take it as a repeat.
  if (!last_scale_factor_ || now_s - last_scale_factor_write_s_ < instance_.heartbeat_period_s) return;
  scale_factor_->write(*last_scale_factor_);
  last_scale_factor_write_s_ = now_s;
  ++heartbeats_;
}

void IdentificationNode::process_until(double watermark_s) { publish(core_.process_until(watermark_s)); }

void IdentificationNode::finish() {
  publish(core_.finish());
  if (!checkpoint_file_.empty() && last_processed_t_s_ && last_checkpoint_t_s_ != last_processed_t_s_)
    write_checkpoint(*last_processed_t_s_);
}

void IdentificationNode::restore_checkpoint() {
  const std::string& vehicle = runtime_.settings().vehicle_id;
  try {
    std::filesystem::create_directories(checkpoint_.state_dir);
    checkpoint_file_ = instance_checkpoint_path(checkpoint_.state_dir, vehicle, instance_.instance);
  } catch (const std::exception& e) {
    throw ConfigError("--state-dir '" + checkpoint_.state_dir + "': " + e.what());
  }
  const CheckpointLoadResult r = load_identification_checkpoint(
      checkpoint_file_, vehicle, checkpoint_.config_hash, core_.main_estimator(), static_cast<int64_t>(std::time(nullptr)));
  const std::string line = describe(r, core_.main_estimator());
  restore_note_until_s_ = dds::steady_now_s() + kRestoreNoteDuration_s;
  switch (r.status) {
    case CheckpointLoadStatus::kNone:
      spdlog::info("{}", line);
      return;
    case CheckpointLoadStatus::kMovedAside:
      spdlog::error("{}", line);
      restore_note_ = "checkpoint " + checkpoint_file_ + " was corrupt: moved aside; starting from nominal K";
      restore_warn_ = true;
      checkpoint_moved_aside_ = true;
      return;
    case CheckpointLoadStatus::kRestored:
      break;
  }
  spdlog::info("{}", line);
  restore_note_ = line;
  const IdentificationCheckpoint& c = *r.checkpoint;
  restored_t_s_ = c.last_sample_t_s;
  restored_accepted_ = c.samples_accepted;
  restored_rejected_ = c.samples_rejected;
  last_checkpoint_t_s_ = c.last_sample_t_s;
  last_processed_t_s_ = c.last_sample_t_s;
  IdentificationOutput o;
  o.t_s = c.last_sample_t_s;
  o.epoch_status = EpochStatus::kAccepted;
  o.main = core_.main_estimator().estimate();
  o.samples_accepted = c.samples_accepted;
  o.samples_rejected = c.samples_rejected;
  last_output_ = o;
}

void IdentificationNode::write_checkpoint(double t_s) {
  IdentificationCheckpoint c;
  c.vehicle_id = runtime_.settings().vehicle_id;
  c.config_hash = checkpoint_.config_hash;
  c.estimator_name = core_.main_estimator().name();
  c.last_sample_t_s = t_s;
  c.samples_accepted = last_output_ ? last_output_->samples_accepted : 0;
  c.samples_rejected = last_output_ ? last_output_->samples_rejected : 0;
  c.estimator_state = core_.main_estimator().save_state();
  try {
    write_file_atomically(checkpoint_file_, serialize_checkpoint(c));
    ++checkpoints_written_;
    last_checkpoint_t_s_ = t_s;
    spdlog::debug("checkpoint written at t={} s: {}", t_s, checkpoint_file_);
  } catch (const std::exception& e) {
    // Retry at the next period, not at the next epoch: a full disk must not be hammered.
    last_checkpoint_t_s_ = t_s;
    ++checkpoint_errors_;
    spdlog::error("checkpoint at t={} s not written: {}", t_s, e.what());
  }
}

std::vector<dds::detail::WriterBase*> IdentificationNode::output_writers() { return {scale_factor_.get()}; }

dds::CommandAck IdentificationNode::on_command(const odonav::msg::Command& c) {
  using namespace odonav::msg;
  switch (c.command()) {
    case COMMAND_RESET_CALIBRATION:
      // The next checkpoint (at most --checkpoint-every-s later) stores the reset state.
      core_.reset();
      return {c.command_id(), COMMAND_RESULT_ACCEPTED, "scale-factor estimator reset"};
    case COMMAND_FREEZE_IDENTIFICATION:
      core_.freeze();
      return {c.command_id(), COMMAND_RESULT_ACCEPTED, "identification frozen: K held"};
    case COMMAND_UNFREEZE_IDENTIFICATION:
      core_.unfreeze();
      return {c.command_id(), COMMAND_RESULT_ACCEPTED, "identification resumed"};
    case COMMAND_SET_K: {
      const double k = c.value();
      if (const auto problem = IdentificationCore::commanded_k_problem(k, instance_.nominal_k_m_per_pulse))
        return {c.command_id(), COMMAND_RESULT_REJECTED, "set_k: " + *problem};
      // Stamped with the last event time processed (the output it replaces), so it sorts after
      // everything already published and before the next epoch.
      double t_s = last_processed_t_s_.value_or(aligner_.processed_s());
      if (!std::isfinite(t_s)) t_s = 0.0;
      IdentificationOutput o = core_.set_k(k, t_s);
      o.samples_accepted += restored_accepted_;
      o.samples_rejected += restored_rejected_;
      write_scale_factor(o, dds::steady_now_s());
      last_output_ = o;
      count_outputs(1);
      ++k_commands_;
      std::ostringstream m;
      m.precision(10);
      m << "K set to " << k << " m/pulse by command; identification continues from it";
      spdlog::info("{}", m.str());
      return {c.command_id(), COMMAND_RESULT_ACCEPTED, m.str()};
    }
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
  if (!restore_note_.empty() && now_s < restore_note_until_s_) {
    s.reason = s.reason.empty() ? restore_note_ : restore_note_ + "; " + s.reason;
    if (restore_warn_) s.level = HEALTH_LEVEL_WARN;
  }
  if (checkpoint_errors_ > 0 && s.level == HEALTH_LEVEL_OK) {
    s.level = HEALTH_LEVEL_WARN;
    s.reason = std::to_string(checkpoint_errors_) + " checkpoint writes failed" + (s.reason.empty() ? "" : "; " + s.reason);
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
  c.emplace_back("odometer_jumps_rejected", static_cast<double>(b.odometer_jumps_rejected));
  c.emplace_back("odometer_rebases", static_cast<double>(b.odometer_rebases));
  c.emplace_back("misalignments_applied", static_cast<double>(misalignments_applied_));
  c.emplace_back("heartbeats", static_cast<double>(heartbeats_));
  c.emplace_back("k_commands", static_cast<double>(k_commands_));
  c.emplace_back("ownership_strength", static_cast<double>(instance_.ownership_strength));
  if (!checkpoint_file_.empty()) {
    c.emplace_back("checkpoint_restored", restored_t_s_ ? 1.0 : 0.0);
    if (restored_t_s_) c.emplace_back("checkpoint_restored_t_s", *restored_t_s_);
    c.emplace_back("checkpoint_moved_aside", checkpoint_moved_aside_ ? 1.0 : 0.0);
    c.emplace_back("checkpoints_written", static_cast<double>(checkpoints_written_));
    c.emplace_back("checkpoint_errors", static_cast<double>(checkpoint_errors_));
    c.emplace_back("skipped_before_checkpoint", static_cast<double>(skipped_before_checkpoint_));
  }
  if (last_output_ && last_output_->main.valid) {
    c.emplace_back("k_m_per_pulse", last_output_->main.k_m_per_pulse);
    c.emplace_back("sigma_k_m_per_pulse", last_output_->main.sigma_m_per_pulse);
  }
}

}  // namespace odonav::nodes
