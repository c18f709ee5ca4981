#include "odonav/identification/identification_lifecycle.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include <spdlog/spdlog.h>

#include "odonav/consumer_rules.hpp"
#include "odonav/printf_text.hpp"

namespace odonav::identification {

namespace {
// Why K cannot be converged yet when the latency search has not decided (SampleBuilder::
// latency_decided): its estimate against the value in force, or why there is none.
std::string latency_not_decided_text(const GnssLatencyEstimate& l) {
  if (l.sigma_s < 0.0) {
    return "GNSS latency not decided (no estimate yet" + (l.reason.empty() ? std::string() : ": " + l.reason) + ")";
  }
  return printf_text("GNSS latency not decided (estimate %.1f +- %.1f ms from %llu samples, %.1f ms in force)",
                     1000.0 * l.estimate_s, 1000.0 * l.sigma_s, static_cast<unsigned long long>(l.samples),
                     1000.0 * l.applied_s);
}
}  // namespace

ComponentHealth identification_health(const IdentificationHealthFacts& f) {
  using State = ComponentHealth::State;
  using Level = ComponentHealth::Level;
  ComponentHealth s{State::kRunning, Level::kOk, ""};
  if (!f.last_output) {
    s = {State::kStarting, Level::kOk, "waiting for the first GNSS epoch to process"};
  } else if (f.last_output->frozen) {
    s.reason = "frozen by command: K held";
  } else if (!f.last_output->main.valid || !f.last_output->main.converged) {
    s.reason = "K not converged yet";
    if (f.last_output->main.valid && !f.last_output->latency_decided) {
      s.reason += ": " + latency_not_decided_text(f.last_output->latency);
    }
  }
  // The misalignment is optional: say why zero is used, without raising the level.
  std::string mis;
  if (f.misalignment_absent && f.misalignments_applied > 0 && f.held_misalignment_t_s)
    mis = held_misalignment_text(*f.held_misalignment_t_s, f.misalignment_silent_s);
  else if (f.misalignment_absent)
    mis = "using zero misalignment: no calibration";
  else if (!f.misalignment_heard)
    mis = "no misalignment received yet: using zero";
  else if (f.misalignments_applied == 0)
    mis = "misalignment not converged yet: using zero";
  if (!mis.empty()) {
    s.reason = s.reason.empty() ? mis : s.reason + "; " + mis;
    if (s.state == State::kRunning && f.misalignment_absent) s.state = State::kDegraded;
  }
  bool warn = false;
  apply_restart_notes(f, f.now_s, s.reason, warn);
  if (warn) s.level = Level::kWarn;
  return s;
}

namespace {
// Indexed by IdentificationInput. Every input is skipped up to its last stamp in the checkpoint
// (fed_until), so margins do not apply; GNSS makes the outputs.
std::vector<RestartInput> identification_inputs() {
  return {{"odometer", 0.0, true, false},
          {"GNSS", 0.0, true, true},
          {"INS", 0.0, true, false},
          {"misalignment", 0.0, true, false}};
}
}  // namespace

IdentificationLifecycle::IdentificationLifecycle(CheckpointSettings settings, std::string vehicle_id,
                                                 std::string instance)
    : vehicle_id_(std::move(vehicle_id)),
      instance_(std::move(instance)),
      restart_(std::move(settings), identification_inputs()) {}

void IdentificationLifecycle::start(IdentificationCore& core, int64_t unix_time_s, double steady_now_s) {
  if (restart_.settings().state_dir.empty()) return;
  restore(core, unix_time_s, steady_now_s);
}

void IdentificationLifecycle::restore(IdentificationCore& core, int64_t unix_time_s, double steady_now_s) {
  const std::string& file = restart_.open_state_dir(
      [&](const std::string& dir) { return instance_checkpoint_path(dir, vehicle_id_, instance_); });
  const CheckpointLoadResult r =
      load_identification_checkpoint(file, vehicle_id_, restart_.settings().config_hash, core, unix_time_s);
  const std::string line = describe(r, core.main_estimator());
  switch (r.status) {
    case CheckpointLoadStatus::kNone: restart_.note_fresh_start(line, steady_now_s); return;
    case CheckpointLoadStatus::kMovedAside:
      // Shorter than the log line (no reason, no new name): the health reason is a summary.
      restart_.note_moved_aside(line, "checkpoint " + file + " was corrupt: moved aside; starting from nominal K",
                                steady_now_s);
      return;
    case CheckpointLoadStatus::kRestored: break;
  }
  const IdentificationCheckpoint& c = *r.checkpoint;
  misalignments_applied_ = c.misalignments_applied;
  held_misalignment_t_s_ = c.held_misalignment_t_s;
  restart_.note_restored(line, c.last_sample_t_s, steady_now_s,
                         std::vector<std::optional<double>>(c.fed_until_s.begin(), c.fed_until_s.end()));
  IdentificationOutput o;
  o.t_s = c.last_sample_t_s;
  o.epoch_status = EpochStatus::kAccepted;
  o.main = core.main_estimator().estimate();
  o.samples_accepted = c.samples_accepted;
  o.samples_rejected = c.samples_rejected;
  o.latency = core.latency();
  o.turn_slip = core.turn_slip_estimate();
  o.turn_slip_threshold_radps = core.turn_slip_threshold_radps();
  last_output_ = o;
}

std::optional<IdentificationOutput> IdentificationLifecycle::take_restored_output() {
  if (restored_output_taken_ || !restart_.restored_t_s() || !last_output_) return std::nullopt;
  restored_output_taken_ = true;
  return last_output_;
}

bool IdentificationLifecycle::skip_sample(IdentificationInput input, double t_s) {
  return restart_.skip_sample(static_cast<std::size_t>(input), t_s);
}

void IdentificationLifecycle::note_misalignment_applied(double t_s) {
  ++misalignments_applied_;
  held_misalignment_t_s_ = t_s;
}

std::vector<IdentificationOutput> IdentificationLifecycle::outputs_to_publish(std::vector<IdentificationOutput> outputs,
                                                                              double steady_now_s) {
  std::vector<IdentificationOutput> kept;
  kept.reserve(outputs.size());
  for (IdentificationOutput& o : outputs) {
    if (!restart_.keep_output(o.t_s, steady_now_s)) continue;
    last_output_ = o;
    kept.push_back(std::move(o));
  }
  return kept;
}

void IdentificationLifecycle::note_odometer_received(double t_s, double steady_now_s) {
  restart_.note_live_sample(t_s, steady_now_s);
}

IdentificationOutput IdentificationLifecycle::commanded_output(IdentificationOutput o) {
  last_output_ = o;
  return o;
}

double IdentificationLifecycle::set_k_stamp_s(double aligner_processed_s) const {
  const double t_s = restart_.last_processed_t_s().value_or(aligner_processed_s);
  return std::isfinite(t_s) ? t_s : 0.0;
}

bool IdentificationLifecycle::checkpoint_due() const { return restart_.checkpoint_due(); }

IdentificationCheckpoint IdentificationLifecycle::make_checkpoint(const IdentificationCore& core, double t_s) const {
  IdentificationCheckpoint c;
  c.vehicle_id = vehicle_id_;
  c.config_hash = restart_.settings().config_hash;
  c.estimator_name = core.main_estimator_name();
  c.last_sample_t_s = t_s;
  c.samples_accepted = last_output_ ? last_output_->samples_accepted : 0;
  c.samples_rejected = last_output_ ? last_output_->samples_rejected : 0;
  const auto& taken = restart_.taken_until_t_s();
  std::copy(taken.begin(), taken.end(), c.fed_until_s.begin());
  c.misalignments_applied = misalignments_applied_;
  c.held_misalignment_t_s = held_misalignment_t_s_;
  c.core_state = core.save_state();
  return c;
}

void IdentificationLifecycle::checkpoint_if_due(const IdentificationCore& core) {
  restart_.checkpoint_if_due([&](double t_s) { return serialize_checkpoint(make_checkpoint(core, t_s)); });
}

void IdentificationLifecycle::checkpoint_at_finish(const IdentificationCore& core) {
  restart_.checkpoint_at_finish([&](double t_s) { return serialize_checkpoint(make_checkpoint(core, t_s)); });
}

IdentificationHealthFacts IdentificationLifecycle::health_facts(double steady_now_s) const {
  IdentificationHealthFacts f;
  static_cast<RestartHealthNotes&>(f) = restart_.health_notes();
  f.last_output = last_output_;
  f.misalignments_applied = misalignments_applied_;
  f.held_misalignment_t_s = held_misalignment_t_s_;
  f.now_s = steady_now_s;
  return f;
}

}  // namespace odonav::identification
