#include "odonav/identification/identification_lifecycle.hpp"

#include <cmath>
#include <cstdio>
#include <limits>
#include <filesystem>
#include <utility>

#include <spdlog/spdlog.h>

#include "odonav/config.hpp"
#include "odonav/consumer_rules.hpp"

namespace odonav {

IdentificationHealth identification_health(const IdentificationHealthFacts& f) {
  using State = IdentificationHealth::State;
  using Level = IdentificationHealth::Level;
  IdentificationHealth s{State::kRunning, Level::kOk, ""};
  if (!f.last_output) {
    s = {State::kStarting, Level::kOk, "waiting for the first GNSS epoch to process"};
  } else if (f.last_output->frozen) {
    s.reason = "frozen by command: K held";
  } else if (!f.last_output->main.valid || !f.last_output->main.converged) {
    s.reason = "K not converged yet";
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
  if (!f.restore_note.empty() && f.now_s < f.restore_note_until_s) {
    s.reason = s.reason.empty() ? f.restore_note : f.restore_note + "; " + s.reason;
    if (f.restore_warn) s.level = Level::kWarn;
  }
  if (!f.catch_up_note.empty() && f.now_s < f.catch_up_note_until_s) {
    s.reason = s.reason.empty() ? f.catch_up_note : f.catch_up_note + "; " + s.reason;
    if (f.catch_up_warn) s.level = Level::kWarn;
  }
  if (f.checkpoint_errors > 0 && s.level == Level::kOk) {
    s.level = Level::kWarn;
    s.reason = std::to_string(f.checkpoint_errors) + " checkpoint writes failed" + (s.reason.empty() ? "" : "; " + s.reason);
  }
  return s;
}

IdentificationLifecycle::IdentificationLifecycle(CheckpointSettings settings, std::string vehicle_id,
                                                 std::string instance)
    : settings_(std::move(settings)), vehicle_id_(std::move(vehicle_id)), instance_(std::move(instance)) {}

void IdentificationLifecycle::start(ScaleFactorEstimator& estimator, int64_t unix_time_s, double steady_now_s) {
  if (settings_.state_dir.empty()) return;
  restore(estimator, unix_time_s, steady_now_s);
  // The producers' histories start with the data of the downtime: what follows is catch-up until
  // the processing is back at the live edge.
  catching_up_ = restored_t_s_.has_value();
}

void IdentificationLifecycle::restore(ScaleFactorEstimator& estimator, int64_t unix_time_s, double steady_now_s) {
  try {
    std::filesystem::create_directories(settings_.state_dir);
    checkpoint_file_ = instance_checkpoint_path(settings_.state_dir, vehicle_id_, instance_);
  } catch (const std::exception& e) {
    throw ConfigError("--state-dir '" + settings_.state_dir + "': " + e.what());
  }
  const CheckpointLoadResult r =
      load_identification_checkpoint(checkpoint_file_, vehicle_id_, settings_.config_hash, estimator, unix_time_s);
  const std::string line = describe(r, estimator);
  restore_note_until_s_ = steady_now_s + kRestoreNoteDuration_s;
  switch (r.status) {
    case CheckpointLoadStatus::kNone:
      spdlog::info("{}", line);
      return;
    case CheckpointLoadStatus::kMovedAside:
      spdlog::error("{}", line);
      // Shorter than the log line (no reason, no new name): the health reason is a summary.
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
  // The restored state is a checkpoint already written: the next one is due every_s later.
  last_checkpoint_t_s_ = c.last_sample_t_s;
  last_processed_t_s_ = c.last_sample_t_s;
  IdentificationOutput o;
  o.t_s = c.last_sample_t_s;
  o.epoch_status = EpochStatus::kAccepted;
  o.main = estimator.estimate();
  o.samples_accepted = c.samples_accepted;
  o.samples_rejected = c.samples_rejected;
  last_output_ = o;
}

std::optional<IdentificationOutput> IdentificationLifecycle::take_restored_output() {
  if (restored_output_taken_ || !restored_t_s_ || !last_output_) return std::nullopt;
  restored_output_taken_ = true;
  return last_output_;
}

bool IdentificationLifecycle::skip_sample(IdentificationInput input, double t_s) {
  if (!restored_t_s_) return false;
  bool& seen = first_seen_[static_cast<int>(input)];
  if (!seen) {
    seen = true;
    // The epoch at the checkpoint restarts the sample chain and needs odometer and INS samples at
    // or before it (interpolation): a history that starts later lost what lies in between.
    constexpr double kStampSlack_s = 1e-6;
    if (t_s > *restored_t_s_ + kStampSlack_s && (!lost_until_t_s_ || t_s > *lost_until_t_s_)) {
      lost_until_t_s_ = t_s;
      spdlog::error("catch-up: the first {} sample after the restart is t={:.3f} s, {:.3f} s after the checkpoint "
                    "(t={:.3f} s): the producers' history (30 s) did not reach back to it; the estimates of "
                    "t={:.3f}-{:.3f} s are missing",
                    input == IdentificationInput::kOdometer ? "odometer"
                    : input == IdentificationInput::kGnss   ? "GNSS"
                                                            : "INS",
                    t_s, t_s - *restored_t_s_, *restored_t_s_, *restored_t_s_, t_s);
    }
  }
  // An epoch before the first odometer / INS sample handed over has no data to be processed with.
  if (input == IdentificationInput::kGnss && lost_until_t_s_ && t_s >= *restored_t_s_ && t_s < *lost_until_t_s_) {
    ++lost_epochs_;
    return true;
  }
  const double margin_s = input == IdentificationInput::kGnss ? 0.0 : kSensorMarginBeforeCheckpoint_s;
  if (t_s >= *restored_t_s_ - margin_s) return false;
  ++skipped_before_checkpoint_;
  return true;
}

std::vector<IdentificationOutput> IdentificationLifecycle::outputs_to_publish(
    std::vector<IdentificationOutput> outputs, double steady_now_s) {
  std::vector<IdentificationOutput> kept;
  kept.reserve(outputs.size());
  for (IdentificationOutput& o : outputs) {
    // The epoch at the checkpoint time was published (by the previous run and at restore) already.
    if (restored_t_s_ && o.t_s <= *restored_t_s_) continue;
    if (catching_up_) {
      // Up to the live edge, or while it is not known yet (then the output is older than an
      // odometer sample received in the settling time, so it is below the edge anyway).
      if (!live_edge_fixed_ || (live_edge_t_s_ && o.t_s <= *live_edge_t_s_)) {
        ++catch_up_outputs_;
        if (!catch_up_first_t_s_) catch_up_first_t_s_ = o.t_s;
        catch_up_last_t_s_ = o.t_s;
      } else {
        catching_up_ = false;
        catch_up_ended_steady_s_ = steady_now_s;
        if (catch_up_outputs_ > 0)
          spdlog::info("caught up after the restart: {} estimates of t={:.3f}-{:.3f} s published late", catch_up_outputs_,
                       *catch_up_first_t_s_, *catch_up_last_t_s_);
      }
    }
    o.samples_accepted += restored_accepted_;
    o.samples_rejected += restored_rejected_;
    last_output_ = o;
    last_processed_t_s_ = o.t_s;
    kept.push_back(std::move(o));
  }
  return kept;
}

void IdentificationLifecycle::note_odometer_received(double t_s, double steady_now_s) {
  if (!catching_up_ || live_edge_fixed_) return;
  if (!first_received_steady_s_) first_received_steady_s_ = steady_now_s;
  if (steady_now_s - *first_received_steady_s_ > kCatchUpSettle_s) {
    live_edge_fixed_ = true;
    if (live_edge_t_s_)
      spdlog::info("catch-up: live edge t={:.3f} s (the producers' history ends there); restored checkpoint t={:.3f} s",
                   *live_edge_t_s_, *restored_t_s_);
    return;
  }
  if (!live_edge_t_s_ || t_s > *live_edge_t_s_) live_edge_t_s_ = t_s;
}

IdentificationOutput IdentificationLifecycle::commanded_output(IdentificationOutput o) {
  o.samples_accepted += restored_accepted_;
  o.samples_rejected += restored_rejected_;
  last_output_ = o;
  return o;
}

double IdentificationLifecycle::set_k_stamp_s(double aligner_processed_s) const {
  const double t_s = last_processed_t_s_.value_or(aligner_processed_s);
  return std::isfinite(t_s) ? t_s : 0.0;
}

bool IdentificationLifecycle::checkpoint_due() const {
  return checkpointing() && last_processed_t_s_ &&
         (!last_checkpoint_t_s_ || *last_processed_t_s_ >= *last_checkpoint_t_s_ + settings_.every_s);
}

IdentificationCheckpoint IdentificationLifecycle::make_checkpoint(const ScaleFactorEstimator& estimator,
                                                                  double t_s) const {
  IdentificationCheckpoint c;
  c.vehicle_id = vehicle_id_;
  c.config_hash = settings_.config_hash;
  c.estimator_name = estimator.name();
  c.last_sample_t_s = t_s;
  c.samples_accepted = last_output_ ? last_output_->samples_accepted : 0;
  c.samples_rejected = last_output_ ? last_output_->samples_rejected : 0;
  c.estimator_state = estimator.save_state();
  return c;
}

void IdentificationLifecycle::checkpoint_if_due(const ScaleFactorEstimator& estimator) {
  // The estimator state now is the one after the last processed epoch.
  if (checkpoint_due()) write_checkpoint(estimator, *last_processed_t_s_);
}

void IdentificationLifecycle::checkpoint_at_finish(const ScaleFactorEstimator& estimator) {
  if (checkpointing() && last_processed_t_s_ && last_checkpoint_t_s_ != last_processed_t_s_)
    write_checkpoint(estimator, *last_processed_t_s_);
}

void IdentificationLifecycle::write_checkpoint(const ScaleFactorEstimator& estimator, double t_s) {
  try {
    write_file_atomically(checkpoint_file_, serialize_checkpoint(make_checkpoint(estimator, t_s)));
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

IdentificationHealthFacts IdentificationLifecycle::health_facts(double steady_now_s) const {
  IdentificationHealthFacts f;
  f.last_output = last_output_;
  f.restore_note = restore_note_;
  f.restore_warn = restore_warn_;
  f.restore_note_until_s = restore_note_until_s_;
  f.now_s = steady_now_s;
  f.checkpoint_errors = checkpoint_errors_;
  if (restored_t_s_ && (catch_up_outputs_ > 0 || lost_until_t_s_)) {
    char buf[256];
    std::string note;
    if (lost_until_t_s_) {
      std::snprintf(buf, sizeof buf,
                    "lost t=%.1f-%.1f s after the checkpoint (older than the producers' 30 s history): its estimates "
                    "are missing",
                    *restored_t_s_, *lost_until_t_s_);
      note = buf;
    }
    if (catch_up_outputs_ > 0) {
      std::snprintf(buf, sizeof buf, "%s: %llu estimates t=%.1f-%.1f s published late",
                    catching_up_ ? "catching up from the checkpoint" : "caught up after restart",
                    static_cast<unsigned long long>(catch_up_outputs_), *catch_up_first_t_s_, *catch_up_last_t_s_);
      note = note.empty() ? std::string(buf) : note + "; " + buf;
    }
    f.catch_up_note = note;
    f.catch_up_warn = lost_until_t_s_.has_value();
    f.catch_up_note_until_s = catching_up_ ? std::numeric_limits<double>::infinity()
                                           : catch_up_ended_steady_s_ + kRestoreNoteDuration_s;
  }
  return f;
}

}  // namespace odonav
