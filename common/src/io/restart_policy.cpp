#include "odonav/restart_policy.hpp"

#include <algorithm>
#include <filesystem>
#include <limits>
#include <utility>

#include <spdlog/spdlog.h>

#include "odonav/checkpoint_file.hpp"
#include "odonav/config.hpp"
#include "odonav/printf_text.hpp"
#include "odonav/safe_output.hpp"

namespace odonav {

void add_checkpoint_options(Options& o, const std::string& file) {
  o.add_string("state-dir", "",
               "folder of the checkpoint " + file +
                   " (restored at start, written every --checkpoint-every-s of "
                   "event time and at shutdown); empty = no checkpoint");
  o.add_double("checkpoint-every-s", 5.0, "checkpoint period in event time of the processed epochs (s)", 0.1, 1e6);
}

CheckpointSettings checkpoint_settings_from_options(const Options& o) {
  CheckpointSettings c;
  c.state_dir = o.get_string("state-dir");
  c.every_s = o.get_double("checkpoint-every-s");
  c.config_hash = config_hash_of(o.values_as_text());
  return c;
}

void apply_restart_notes(const RestartHealthNotes& n, double now_s, std::string& reason, bool& warn) {
  if (!n.restore_note.empty() && now_s < n.restore_note_until_s) {
    reason = reason.empty() ? n.restore_note : n.restore_note + "; " + reason;
    if (n.restore_warn) warn = true;
  }
  if (!n.catch_up_note.empty() && now_s < n.catch_up_note_until_s) {
    reason = reason.empty() ? n.catch_up_note : n.catch_up_note + "; " + reason;
    if (n.catch_up_warn) warn = true;
  }
  if (n.checkpoint_errors > 0 && !warn) {
    warn = true;
    reason = std::to_string(n.checkpoint_errors) + " checkpoint writes failed" + (reason.empty() ? "" : "; " + reason);
  }
}

RestartPolicy::RestartPolicy(CheckpointSettings settings, std::vector<RestartInput> inputs)
    : settings_(std::move(settings)),
      inputs_(std::move(inputs)),
      first_seen_(inputs_.size(), false),
      taken_until_t_s_(inputs_.size()) {}

const std::string& RestartPolicy::open_state_dir(
    const std::function<std::string(const std::string& state_dir)>& path_of) {
  try {
    std::filesystem::create_directories(settings_.state_dir);
    checkpoint_file_ = path_of(settings_.state_dir);
  } catch (const std::exception& e) {
    throw ConfigError("--state-dir '" + settings_.state_dir + "': " + e.what());
  }
  return checkpoint_file_;
}

void RestartPolicy::note_fresh_start(const std::string& line, double steady_now_s) {
  spdlog::info("{}", line);
  restore_note_until_s_ = steady_now_s + kRestoreNoteDuration_s;
}

void RestartPolicy::note_moved_aside(const std::string& line, const std::string& note, double steady_now_s) {
  spdlog::error("{}", line);
  restore_note_ = note;
  restore_warn_ = true;
  checkpoint_moved_aside_ = true;
  restore_note_until_s_ = steady_now_s + kRestoreNoteDuration_s;
}

bool RestartPolicy::note_load(const CheckpointFileLoad& r, const std::string& fresh_start, double steady_now_s) {
  switch (r.status) {
    case CheckpointLoadStatus::kNone:
      note_fresh_start("no checkpoint " + r.path + ": " + fresh_start, steady_now_s);
      return false;
    case CheckpointLoadStatus::kMovedAside:
      note_moved_aside("checkpoint " + r.path + " was corrupt (" + r.reason + "): moved aside" +
                           (r.moved_to.empty() ? std::string(" FAILED") : " to " + r.moved_to) + "; " + fresh_start,
                       "checkpoint " + r.path + " was corrupt: moved aside; " + fresh_start, steady_now_s);
      return false;
    case CheckpointLoadStatus::kRestored: break;
  }
  return true;
}

void RestartPolicy::note_restored(const std::string& line, double checkpoint_t_s, double steady_now_s,
                                  std::vector<std::optional<double>> fed_until_t_s) {
  spdlog::info("{}", line);
  fed_until_t_s_ = std::move(fed_until_t_s);
  fed_until_t_s_.resize(inputs_.size());
  taken_until_t_s_ = fed_until_t_s_;
  restore_note_ = line;
  restore_note_until_s_ = steady_now_s + kRestoreNoteDuration_s;
  restored_t_s_ = checkpoint_t_s;
  // The restored state is a checkpoint already written: the next one is due every_s later.
  last_checkpoint_t_s_ = checkpoint_t_s;
  last_processed_t_s_ = checkpoint_t_s;
  // The producers' histories start with the data of the downtime: what follows is catch-up until
  // the processing is back at the live edge.
  catching_up_ = true;
}

bool RestartPolicy::skip_sample(std::size_t input, double t_s) {
  if (skip_restored(input, t_s)) return true;
  std::optional<double>& taken = taken_until_t_s_.at(input);
  if (!taken || t_s > *taken) taken = t_s;
  return false;
}

bool RestartPolicy::skip_restored(std::size_t input, double t_s) {
  if (!restored_t_s_) return false;
  const RestartInput& in = inputs_.at(input);
  const std::optional<double>& fed_until = fed_until_t_s_.at(input);
  if (!first_seen_[input]) {
    first_seen_[input] = true;
    // The first outputs after the checkpoint need samples at or before it (or at or before the
    // last one the restored state holds): a history that starts later lost what lies in between.
    constexpr double kStampSlack_s = 1e-6;
    const double complete_from_s = fed_until ? std::max(*fed_until, *restored_t_s_) : *restored_t_s_;
    if (t_s > complete_from_s + kStampSlack_s && (!lost_until_t_s_ || t_s > *lost_until_t_s_)) {
      lost_until_t_s_ = t_s;
      spdlog::error(
          "catch-up: the first {} sample after the restart is t={:.3f} s, {:.3f} s after the checkpoint "
          "(t={:.3f} s): the producers' history (30 s) did not reach back to it; the estimates of "
          "t={:.3f}-{:.3f} s are missing",
          in.name, t_s, t_s - *restored_t_s_, *restored_t_s_, *restored_t_s_, t_s);
    }
  }
  // An output-making sample before the first samples of the other inputs has no data to be
  // processed with.
  if (in.makes_outputs && lost_until_t_s_ && t_s >= *restored_t_s_ && t_s < *lost_until_t_s_) {
    ++lost_epochs_;
    return true;
  }
  if (fed_until) {
    if (t_s > *fed_until) return false;
  } else {
    const double from_s = *restored_t_s_ - in.margin_before_checkpoint_s;
    if (in.skip_at_checkpoint ? t_s > from_s : t_s >= from_s) return false;
  }
  ++skipped_before_checkpoint_;
  return true;
}

bool RestartPolicy::keep_output(double t_s, double steady_now_s) {
  // The output at the checkpoint time was published (by the previous run and at restore) already.
  if (restored_t_s_ && t_s <= *restored_t_s_) return false;
  if (catching_up_) {
    // Up to the live edge, or while it is not known yet (then the output is older than a sample
    // received in the settling time, so it is below the edge anyway).
    if (!live_edge_fixed_ || (live_edge_t_s_ && t_s <= *live_edge_t_s_)) {
      ++catch_up_outputs_;
      if (!catch_up_first_t_s_) catch_up_first_t_s_ = t_s;
      catch_up_last_t_s_ = t_s;
    } else {
      catching_up_ = false;
      catch_up_ended_steady_s_ = steady_now_s;
      if (catch_up_outputs_ > 0)
        spdlog::info("caught up after the restart: {} estimates of t={:.3f}-{:.3f} s published late", catch_up_outputs_,
                     *catch_up_first_t_s_, *catch_up_last_t_s_);
    }
  }
  last_processed_t_s_ = t_s;
  return true;
}

void RestartPolicy::note_live_sample(double t_s, double steady_now_s) {
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

bool RestartPolicy::checkpoint_due() const {
  return checkpointing() && last_processed_t_s_ &&
         (!last_checkpoint_t_s_ || *last_processed_t_s_ >= *last_checkpoint_t_s_ + settings_.every_s);
}

void RestartPolicy::checkpoint_if_due(const std::function<std::string(double t_s)>& text) {
  // The state now is the one after the last processed output.
  if (checkpoint_due()) write(*last_processed_t_s_, text);
}

void RestartPolicy::checkpoint_at_finish(const std::function<std::string(double t_s)>& text) {
  if (checkpointing() && last_processed_t_s_ && last_checkpoint_t_s_ != last_processed_t_s_)
    write(*last_processed_t_s_, text);
}

void RestartPolicy::write(double t_s, const std::function<std::string(double t_s)>& text) {
  try {
    write_file_atomically(checkpoint_file_, text(t_s));
    ++checkpoints_written_;
    last_checkpoint_t_s_ = t_s;
    spdlog::debug("checkpoint written at t={} s: {}", t_s, checkpoint_file_);
  } catch (const std::exception& e) {
    // Retry at the next period, not at the next output: a full disk must not be hammered.
    last_checkpoint_t_s_ = t_s;
    ++checkpoint_errors_;
    spdlog::error("checkpoint at t={} s not written: {}", t_s, e.what());
  }
}

RestartHealthNotes RestartPolicy::health_notes() const {
  RestartHealthNotes n;
  n.restore_note = restore_note_;
  n.restore_warn = restore_warn_;
  n.restore_note_until_s = restore_note_until_s_;
  n.checkpoint_errors = checkpoint_errors_;
  if (restored_t_s_ && (catch_up_outputs_ > 0 || lost_until_t_s_)) {
    std::string note;
    if (lost_until_t_s_) {
      note = printf_text(
          "lost t=%.1f-%.1f s after the checkpoint (older than the producers' 30 s history): its estimates are missing",
          *restored_t_s_, *lost_until_t_s_);
    }
    if (catch_up_outputs_ > 0) {
      const std::string late =
          printf_text("%s: %llu estimates t=%.1f-%.1f s published late",
                      catching_up_ ? "catching up from the checkpoint" : "caught up after restart",
                      static_cast<unsigned long long>(catch_up_outputs_), *catch_up_first_t_s_, *catch_up_last_t_s_);
      note = note.empty() ? late : note + "; " + late;
    }
    n.catch_up_note = note;
    n.catch_up_warn = lost_until_t_s_.has_value();
    n.catch_up_note_until_s =
        catching_up_ ? std::numeric_limits<double>::infinity() : catch_up_ended_steady_s_ + kRestoreNoteDuration_s;
  }
  return n;
}

std::vector<std::pair<std::string, double>> RestartPolicy::counters() const {
  std::vector<std::pair<std::string, double>> c;
  if (!checkpointing()) return c;
  c.emplace_back("checkpoint_restored", restored_t_s_ ? 1.0 : 0.0);
  if (restored_t_s_) c.emplace_back("checkpoint_restored_t_s", *restored_t_s_);
  c.emplace_back("checkpoint_moved_aside", checkpoint_moved_aside_ ? 1.0 : 0.0);
  c.emplace_back("checkpoints_written", static_cast<double>(checkpoints_written_));
  c.emplace_back("checkpoint_errors", static_cast<double>(checkpoint_errors_));
  c.emplace_back("skipped_before_checkpoint", static_cast<double>(skipped_before_checkpoint_));
  if (restored_t_s_) {
    // The catch-up of the downtime's data: estimates published late, and event time lost.
    c.emplace_back("catch_up_outputs", static_cast<double>(catch_up_outputs_));
    c.emplace_back("catching_up", catching_up_ ? 1.0 : 0.0);
    if (catch_up_first_t_s_) c.emplace_back("catch_up_first_t_s", *catch_up_first_t_s_);
    if (catch_up_last_t_s_) c.emplace_back("catch_up_last_t_s", *catch_up_last_t_s_);
    c.emplace_back("catch_up_lost_s", catch_up_lost_s());
    c.emplace_back("catch_up_lost_epochs", static_cast<double>(lost_epochs_));
  }
  return c;
}

}  // namespace odonav
