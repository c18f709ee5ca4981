#pragma once
// The restart policy of odonav-identification around IdentificationCore, middleware-free so that it
// is testable in one process (the DDS node only subscribes, converts, calls this and publishes):
//  - at start: restore the checkpoint (checkpoint.hpp) or move a bad one aside;
//  - which restored output is published at once, which sensor samples are skipped because they
//    predate the checkpoint, which outputs are published after a restore (with the restored
//    counters added);
//  - the catch-up after a restore: the producers hand a restarted reader their history (30 s), so
//    the data of the downtime is processed from the checkpoint on and its estimates are published
//    late; which outputs were catch-up, and what was lost when the history did not reach back to
//    the checkpoint;
//  - when a checkpoint is due, building and writing it;
//  - the stamp of a commanded K (set_k);
//  - the health decision, as a pure function over the facts the node supplies.
// Time: "event time" is the data's time (sample stamps, s); "steady" is the node's wall clock
// (s, monotonic), used only for how long the restore note stays in the health reason.
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "odonav/component_health.hpp"
#include "odonav/identification/checkpoint.hpp"
#include "odonav/identification/identification_core.hpp"
#include "odonav/identification/instance.hpp"
#include "odonav/restart_policy.hpp"

namespace odonav::identification {

// CheckpointSettings (state directory, period, configuration hash), kRestoreNoteDuration_s and
// kCatchUpSettle_s: odonav/restart_policy.hpp, the restart policy the calibration shares; this
// lifecycle adds what is the identification's (its inputs and margins, its checkpoint file and
// texts, what each input had taken in, the misalignments applied, set_k).

/// Everything identification_health() decides on. The node supplies the input facts; the
/// lifecycle the rest (IdentificationLifecycle::health_facts), the restart notes included
/// (RestartHealthNotes: restore note, checkpoint errors, catch-up note).
struct IdentificationHealthFacts : RestartHealthNotes {
  /// The last published output (nothing before the first epoch or restore).
  std::optional<IdentificationOutput> last_output;
  /// The optional misalignment input: absent (silent past the node's maximum wait) / ever heard.
  bool misalignment_absent = false;
  bool misalignment_heard = false;
  /// Misalignments applied to the core so far (converged ones only, consumer_rules.hpp).
  uint64_t misalignments_applied = 0;
  /// The stamp of the last one applied (event time, s): the core keeps applying it while the
  /// calibration is silent; and how long that is (wall clock, s).
  std::optional<double> held_misalignment_t_s;
  double misalignment_silent_s = 0.0;
  /// Now, steady clock (s).
  double now_s = 0.0;
};

/// The health decision. Precedence of the reason parts: restore note; checkpoint errors first when
/// they raise the level; then waiting / frozen / not converged; then the zero-misalignment part.
/// Reasons (operators and tests rely on the exact texts):
///  - no output: STARTING "waiting for the first GNSS epoch to process";
///  - frozen: "frozen by command: K held"; no valid or converged K: "K not converged yet", with
///    ": GNSS latency not decided (estimate 23.0 +- 8.0 ms from 120 samples, 0.0 ms in force)" (or
///    "(no estimate yet: <why>)") when a valid K waits for the latency search;
///  - misalignment absent: "using zero misalignment: no calibration" when none was ever applied,
///    "holding misalignment of t=40.0 s (calibration silent 5 s)" when the last one applied is
///    held (DEGRADED when RUNNING either way);
///    never heard: "no misalignment received yet: using zero"; heard but none applied:
///    "misalignment not converged yet: using zero" (the level is never raised for these);
///  - "<n> checkpoint writes failed" with WARN when the level was OK;
///  - after a restore, the catch-up note first: "catching up from checkpoint t=40.0 s: 12 estimates
///    t=40.1-41.2 s published late", then "caught up after restart: ..." for 30 s; with a loss
///    (WARN) "lost t=40.0-52.3 s after the checkpoint (older than the producers' history, 30 s):
///    its estimates are missing".
ComponentHealth identification_health(const IdentificationHealthFacts& facts);

/// One identification run's restart policy. Not thread-safe: the node runs it one task at a time.
class IdentificationLifecycle {
 public:
  /// settings.state_dir empty: checkpointing is off (start() does nothing, nothing is skipped,
  /// no checkpoint is written). vehicle_id and instance name the state files (instance.hpp).
  IdentificationLifecycle(CheckpointSettings settings, std::string vehicle_id,
                          std::string instance = kDefaultIdentificationInstance);

  /// At start, before any input reaches the core. With a state directory: creates the directory
  /// (ConfigError "--state-dir '<dir>': ..." when it cannot, or the vehicle or instance cannot name
  /// a file), loads the checkpoint into `core` (restored, or none, or moved aside when corrupt, of an
  /// older version, another vehicle, configuration or estimator: fresh start from nominal K) and logs
  /// what it did. unix_time_s names a moved-aside file; steady_now_s starts the restore note's 30 s.
  void start(IdentificationCore& core, int64_t unix_time_s, double steady_now_s);

  /// The restored output to publish at once (stamp = the checkpoint's time, restored counters), so
  /// that a consumer that lost it, or a late reader (the writer is TRANSIENT_LOCAL), has it before
  /// any new sample. Nothing without a restore. Returns it at most once.
  std::optional<IdentificationOutput> take_restored_output();

  /// True (and counted in skipped_before_checkpoint) when a sample of `input` stamped t_s (event
  /// time, s) was taken in before the restart and must not reach the core again: stamped at or
  /// before that input's last stamp in the checkpoint (the restored state holds it, processed or
  /// buffered). Otherwise the sample is recorded as taken in (the next checkpoint's fed_until).
  /// Always false without a restore but for that bookkeeping.
  /// After a restore the first sample of each input (the oldest of the producer's history, which is
  /// handed over oldest first) tells whether the history reached back to the checkpoint: when it
  /// starts after it, the data in between is lost (logged once, in the health as WARN, and in
  /// catch_up_lost_s()). GNSS epochs inside the lost span are skipped too (counted in
  /// catch_up_lost_epochs()): without odometer and INS data they cannot be processed, and no
  /// estimate is published for them. The node holds GNSS back until the first odometer and INS
  /// samples are known (first_sample_seen), so that the span is known before any epoch.
  bool skip_sample(IdentificationInput input, double t_s);
  /// After a restore: whether a sample of `input` was offered to skip_sample yet.
  bool first_sample_seen(IdentificationInput input) const {
    return restart_.first_sample_seen(static_cast<std::size_t>(input));
  }
  /// GNSS epochs skipped because they fell in the lost span.
  uint64_t catch_up_lost_epochs() const { return restart_.lost_epochs(); }

  /// The outputs of the core to publish, in order: after a restore those at or before the
  /// checkpoint time are dropped (the previous run and take_restored_output published them). The
  /// counters (accepted, rejected) go on across restarts: they are part of the restored core. The
  /// last one becomes last_output() and last_processed_t_s().
  /// After a restore, the outputs up to the live edge (note_odometer_received) are counted as
  /// catch-up; the first one past it ends the catch-up. steady_now_s (monotonic wall clock, s) dates
  /// that end, for the health note only.
  std::vector<IdentificationOutput> outputs_to_publish(std::vector<IdentificationOutput> outputs,
                                                       double steady_now_s = 0.0);
  /// Each odometer sample received (event time t_s, steady clock steady_now_s): after a restore,
  /// sets the live edge (kCatchUpSettle_s). Nothing otherwise.
  void note_odometer_received(double t_s, double steady_now_s);

  /// The output of a commanded K (IdentificationCore::set_k); becomes last_output(). The processed
  /// event time is unchanged: the command adds no epoch.
  IdentificationOutput commanded_output(IdentificationOutput output);
  /// The event time (s) to stamp a commanded K with: the last processed epoch (the output it
  /// replaces), else aligner_processed_s (what the node's aligner has released), else 0 when that
  /// is not finite (nothing processed yet). So it sorts after everything already published and
  /// before the next epoch.
  double set_k_stamp_s(double aligner_processed_s) const;

  /// A checkpoint is due: checkpointing on, an epoch processed, and none written yet or the last
  /// processed event time at least every_s past the last checkpoint (written or failed).
  bool checkpoint_due() const;
  /// A converged misalignment stamped t_s (its GNSS epoch, s) was given to the core: counted and
  /// held for the health, and kept in the checkpoint.
  void note_misalignment_applied(double t_s);
  uint64_t misalignments_applied() const { return misalignments_applied_; }
  const std::optional<double>& held_misalignment_t_s() const { return held_misalignment_t_s_; }

  /// The checkpoint of `core` after the epoch at t_s: vehicle, configuration hash, estimator name,
  /// the core's complete state, the counters of last_output(), what each input had taken in.
  IdentificationCheckpoint make_checkpoint(const IdentificationCore& core, double t_s) const;
  /// Writes the checkpoint (atomically) when due. A failure is logged and counted, never thrown: a
  /// full disk must not stop the identification. It is retried at the next period, not at the next
  /// epoch, so a full disk is not hammered.
  void checkpoint_if_due(const IdentificationCore& core);
  /// At shutdown: writes the checkpoint of the last processed epoch unless it is already the last one.
  void checkpoint_at_finish(const IdentificationCore& core);

  /// The health facts this lifecycle knows (last output, restore note, checkpoint errors, the
  /// misalignments applied), with the node's input facts left at their defaults for the node to
  /// fill in.
  IdentificationHealthFacts health_facts(double steady_now_s) const;

  bool checkpointing() const { return restart_.checkpointing(); }
  const std::string& checkpoint_file() const { return restart_.checkpoint_file(); }
  /// Event time (s) of the restored checkpoint's last epoch; nothing without a restore.
  const std::optional<double>& restored_t_s() const { return restart_.restored_t_s(); }
  bool checkpoint_moved_aside() const { return restart_.checkpoint_moved_aside(); }
  const std::optional<IdentificationOutput>& last_output() const { return last_output_; }
  const std::optional<double>& last_processed_t_s() const { return restart_.last_processed_t_s(); }
  uint64_t checkpoints_written() const { return restart_.checkpoints_written(); }
  uint64_t checkpoint_errors() const { return restart_.checkpoint_errors(); }
  uint64_t skipped_before_checkpoint() const { return restart_.skipped_before_checkpoint(); }
  /// Catch-up after a restore: outputs published late (from the producers' history), the first
  /// and last of their stamps (event time, s), and whether it is still going on.
  uint64_t catch_up_outputs() const { return restart_.catch_up_outputs(); }
  const std::optional<double>& catch_up_first_t_s() const { return restart_.catch_up_first_t_s(); }
  const std::optional<double>& catch_up_last_t_s() const { return restart_.catch_up_last_t_s(); }
  bool catching_up() const { return restart_.catching_up(); }
  /// Event time (s) lost after the checkpoint because the producers' history did not reach back to
  /// it (0 when nothing was lost): the span [restored_t_s, lost_until_t_s].
  double catch_up_lost_s() const { return restart_.catch_up_lost_s(); }
  const std::optional<double>& lost_until_t_s() const { return restart_.lost_until_t_s(); }
  /// The restart counters for the health (RestartPolicy::counters).
  std::vector<std::pair<std::string, double>> restart_counters() const { return restart_.counters(); }

 private:
  void restore(IdentificationCore& core, int64_t unix_time_s, double steady_now_s);

  std::string vehicle_id_;
  std::string instance_;
  RestartPolicy restart_;
  uint64_t misalignments_applied_ = 0;
  std::optional<double> held_misalignment_t_s_;
  bool restored_output_taken_ = false;
  std::optional<IdentificationOutput> last_output_;
};

}  // namespace odonav::identification
