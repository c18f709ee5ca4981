#pragma once
// The restart policy of a checkpointing component (odonav-identification, odonav-calibration),
// middleware-free and independent of what the state is (the component serialises it,
// checkpoint_file.hpp gives the file's envelope):
//  - at start: the state directory, what the restore did (note for the health, for 30 s);
//  - which input samples are skipped because they predate the checkpoint (per input, with the
//    margin the component's windows need), and what was lost when the producers' history did not
//    reach back to the checkpoint;
//  - which outputs are published after a restore (none at or before the checkpoint), and the
//    catch-up: the producers hand a restarted reader their history (30 s), so the data of the
//    downtime is processed from the checkpoint on and its outputs are published late; up to the
//    live edge they are counted as catch-up;
//  - when a checkpoint is due, writing it atomically, counting failures;
//  - the health notes and counters of all this.
// Time: "event time" is the data's time (sample stamps, s); "steady" is the node's wall clock
// (s, monotonic), used only for how long notes stay in the health reason. Worker thread only.
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace odonav {

class Options;
struct CheckpointFileLoad;

/// Where and how often a component checkpoints its state.
struct CheckpointSettings {
  /// Folder of the checkpoint file; empty = no checkpoint (nothing read or written).
  std::string state_dir;
  /// A checkpoint is written once the event time of the processed outputs has advanced by this
  /// much (s, > 0) since the last one, and at shutdown. Event time, not wall time: a replay writes
  /// the same checkpoints whatever its speed.
  double every_s = 5.0;
  /// config_hash_of(Options::values_as_text()): a checkpoint of another configuration is refused.
  std::string config_hash;
};

/// --state-dir and --checkpoint-every-s (default 5 s of event time); `file` names the checkpoint
/// file in the help text (e.g. "calibration-<vehicle>.ckpt").
void add_checkpoint_options(Options& options, const std::string& file);
/// Reads them and hashes the configuration (config_hash_of, checkpoint_file.hpp).
CheckpointSettings checkpoint_settings_from_options(const Options& options);

/// How long (steady clock) the health reason tells about the restore: long enough for an operator
/// or a monitor to see it, short enough not to hide later reasons.
inline constexpr double kRestoreNoteDuration_s = 30.0;
/// After a restore, the producers hand over their history at once, then the live data follows. The
/// live edge at the restart is taken as the newest stamp of the live-edge input received within this
/// long (steady clock, s) after the first one; the outputs up to it are catch-up (published late).
/// It only labels outputs (health, counters), it never changes a number: at real time it may count
/// up to this much of live data as catch-up.
inline constexpr double kCatchUpSettle_s = 1.0;

/// One input of a checkpointing component, as the restart policy treats it.
struct RestartInput {
  std::string name;  ///< in logs ("odometer", "GNSS", "INS").
  /// Samples this much older than the checkpoint (s, >= 0) are still fed: the component's windows
  /// and interpolations right after the checkpoint need them.
  double margin_before_checkpoint_s = 0.0;
  /// A sample stamped exactly at the checkpoint time is skipped too (it was processed already)
  /// rather than fed again (it restarts a chain exactly where the checkpoint left it).
  bool skip_at_checkpoint = false;
  /// The input whose samples make outputs (GNSS epochs): those inside a lost span are skipped and
  /// counted (lost_epochs): without the other inputs' data they cannot be processed.
  bool makes_outputs = false;
};

/// What the health reason says about the restart, and for how long. Precedence when applied
/// (apply_restart_notes): restore note, then catch-up note, before the component's own reason;
/// checkpoint errors first when they raise the level.
struct RestartHealthNotes {
  /// What the restore did, shown until restore_note_until_s (steady, s); "" = nothing to say.
  std::string restore_note;
  /// The checkpoint was unusable: WARN while the note shows.
  bool restore_warn = false;
  double restore_note_until_s = 0.0;
  /// Checkpoint writes that failed since start: any makes the health WARN (if it is not already).
  uint64_t checkpoint_errors = 0;
  /// The catch-up after a restore: "" = nothing to say; shown while active or until
  /// catch_up_note_until_s (steady, s); WARN when data was lost. Texts:
  /// "catching up from the checkpoint: 12 estimates t=40.1-41.2 s published late", then "caught up
  /// after restart: ..."; with a loss "lost t=40.0-52.3 s after the checkpoint (older than the
  /// producers' 30 s history): its estimates are missing".
  std::string catch_up_note;
  bool catch_up_warn = false;
  double catch_up_note_until_s = 0.0;
};

/// Adds the notes that show at now_s (steady, s) to a health reason ("; "-joined) and raises warn.
void apply_restart_notes(const RestartHealthNotes& notes, double now_s, std::string& reason, bool& warn);

class RestartPolicy {
 public:
  /// inputs: the component's inputs, indexed as in skip_sample. settings.state_dir empty:
  /// checkpointing is off (nothing is skipped, no checkpoint is due).
  RestartPolicy(CheckpointSettings settings, std::vector<RestartInput> inputs);

  /// Creates the state directory and returns path_of(state_dir), the checkpoint file. Throws
  /// ConfigError "--state-dir '<dir>': ..." when the directory cannot be created or path_of throws
  /// (a vehicle or instance that cannot name a file). Only with a state directory.
  const std::string& open_state_dir(const std::function<std::string(const std::string& state_dir)>& path_of);

  /// What the restore did; call one, once, after open_state_dir. `line` is logged (info; error when
  /// moved aside), `note` goes to the health for kRestoreNoteDuration_s from steady_now_s.
  void note_fresh_start(const std::string& line, double steady_now_s);
  void note_moved_aside(const std::string& line, const std::string& note, double steady_now_s);
  /// note_fresh_start / note_moved_aside for a load that did not restore, with the usual lines
  /// ("no checkpoint <file>: <fresh_start>"; "checkpoint <file> was corrupt (<why>): moved aside to
  /// <new name>; <fresh_start>", the health note without the reason and new name). Returns true when
  /// the load restored (then call note_restored with the component's own line).
  bool note_load(const CheckpointFileLoad& load, const std::string& fresh_start, double steady_now_s);
  /// Restored the state of the output at checkpoint_t_s (event time, s): that is the last processed
  /// output and the last checkpoint; outputs until the live edge are catch-up.
  /// fed_until_t_s (per input, as indexed in skip_sample; optional): for a component whose state
  /// also holds inputs not processed yet (buffered ahead of the last output), the stamp of the last
  /// sample of each input the restored state had taken in: that input's samples stamped at or before
  /// it are skipped instead of the margin rule, and its history is complete when it starts there.
  void note_restored(const std::string& line, double checkpoint_t_s, double steady_now_s,
                     std::vector<std::optional<double>> fed_until_t_s = {});

  /// True (and counted in skipped_before_checkpoint, or in lost_epochs) when a sample of input
  /// `input` stamped t_s (event time, s) must not reach the core: processed before the restart
  /// (older than the checkpoint by more than the input's margin, or at it when skip_at_checkpoint;
  /// at or before the input's fed_until_t_s when note_restored had one),
  /// or an output-making sample inside the lost span. Always false without a restore.
  /// The first sample of each input after a restore (the oldest of the producer's history, which is
  /// handed over oldest first) tells whether the history reached back to the checkpoint: when it
  /// starts after it, the data in between is lost (logged once as ERROR, WARN in the health, and in
  /// catch_up_lost_s()).
  /// A sample not skipped is recorded as taken in (taken_until_t_s).
  bool skip_sample(std::size_t input, double t_s);
  /// Per input (as indexed in skip_sample), the stamp of the last sample not skipped, or the
  /// restored fed_until while none came since: what a checkpoint written now must name as taken in.
  const std::vector<std::optional<double>>& taken_until_t_s() const { return taken_until_t_s_; }
  /// After a restore: whether a sample of `input` was offered to skip_sample yet.
  bool first_sample_seen(std::size_t input) const { return first_seen_.at(input); }

  /// Whether an output stamped t_s is published: not after a restore when at or before the
  /// checkpoint (the previous run and the restored output published it). A kept output becomes the
  /// last processed one. After a restore the outputs up to the live edge (note_live_sample) are
  /// counted as catch-up; the first one past it ends the catch-up (steady_now_s dates that end, for
  /// the health note only).
  bool keep_output(double t_s, double steady_now_s);
  /// keep_output for each of a batch of outputs (anything with a t_s member, s), in order.
  template <class Output>
  std::vector<Output> keep_outputs(std::vector<Output> outputs, double steady_now_s) {
    std::vector<Output> kept;
    kept.reserve(outputs.size());
    for (Output& o : outputs)
      if (keep_output(o.t_s, steady_now_s)) kept.push_back(std::move(o));
    return kept;
  }
  /// Each sample of the live-edge input received (event time t_s, steady clock steady_now_s): after a
  /// restore, sets the live edge (kCatchUpSettle_s). Nothing otherwise.
  void note_live_sample(double t_s, double steady_now_s);

  /// A checkpoint is due: checkpointing on, an output processed, and none written yet or the last
  /// processed event time at least every_s past the last checkpoint (written or failed).
  bool checkpoint_due() const;
  /// Writes text() (atomically) as the checkpoint of the last processed output when due. A failure
  /// is logged and counted, never thrown: a full disk must not stop the component. It is retried at
  /// the next period, not at the next output, so a full disk is not hammered.
  void checkpoint_if_due(const std::function<std::string(double t_s)>& text);
  /// At shutdown: writes it unless the last processed output is already the last checkpoint.
  void checkpoint_at_finish(const std::function<std::string(double t_s)>& text);

  /// The health notes (each with the steady time until which it shows).
  RestartHealthNotes health_notes() const;
  /// The counters of the restart (only with checkpointing): checkpoint_restored, _restored_t_s,
  /// _moved_aside, checkpoints_written, checkpoint_errors, skipped_before_checkpoint, and after a
  /// restore catch_up_outputs, catching_up, catch_up_first_t_s, catch_up_last_t_s, catch_up_lost_s,
  /// catch_up_lost_epochs.
  std::vector<std::pair<std::string, double>> counters() const;

  const CheckpointSettings& settings() const { return settings_; }
  bool checkpointing() const { return !checkpoint_file_.empty(); }
  const std::string& checkpoint_file() const { return checkpoint_file_; }
  const std::optional<double>& restored_t_s() const { return restored_t_s_; }
  bool checkpoint_moved_aside() const { return checkpoint_moved_aside_; }
  const std::optional<double>& last_processed_t_s() const { return last_processed_t_s_; }
  uint64_t checkpoints_written() const { return checkpoints_written_; }
  uint64_t checkpoint_errors() const { return checkpoint_errors_; }
  uint64_t skipped_before_checkpoint() const { return skipped_before_checkpoint_; }
  uint64_t lost_epochs() const { return lost_epochs_; }
  uint64_t catch_up_outputs() const { return catch_up_outputs_; }
  const std::optional<double>& catch_up_first_t_s() const { return catch_up_first_t_s_; }
  const std::optional<double>& catch_up_last_t_s() const { return catch_up_last_t_s_; }
  bool catching_up() const { return catching_up_; }
  /// Event time (s) lost after the checkpoint because the producers' history did not reach back to
  /// it (0 when nothing was lost): the span [restored_t_s, lost_until_t_s].
  double catch_up_lost_s() const { return lost_until_t_s_ ? *lost_until_t_s_ - *restored_t_s_ : 0.0; }
  const std::optional<double>& lost_until_t_s() const { return lost_until_t_s_; }

 private:
  void write(double t_s, const std::function<std::string(double t_s)>& text);
  /// skip_sample's decision, without the bookkeeping of what was taken in.
  bool skip_restored(std::size_t input, double t_s);

  CheckpointSettings settings_;
  std::vector<RestartInput> inputs_;
  std::vector<bool> first_seen_;
  std::vector<std::optional<double>> fed_until_t_s_;    ///< per input (note_restored)
  std::vector<std::optional<double>> taken_until_t_s_;  ///< per input: last stamp not skipped
  std::string checkpoint_file_;
  std::optional<double> restored_t_s_;
  std::string restore_note_;
  bool restore_warn_ = false;
  double restore_note_until_s_ = 0.0;  ///< steady (s)
  bool checkpoint_moved_aside_ = false;
  std::optional<double> lost_until_t_s_;
  uint64_t lost_epochs_ = 0;
  bool catching_up_ = false;
  std::optional<double> first_received_steady_s_;
  std::optional<double> live_edge_t_s_;
  bool live_edge_fixed_ = false;
  uint64_t catch_up_outputs_ = 0;
  std::optional<double> catch_up_first_t_s_;
  std::optional<double> catch_up_last_t_s_;
  double catch_up_ended_steady_s_ = 0.0;
  std::optional<double> last_checkpoint_t_s_;  ///< event time (s) of the last checkpoint written or failed
  std::optional<double> last_processed_t_s_;   ///< event time (s) of the last published output
  uint64_t checkpoints_written_ = 0;
  uint64_t checkpoint_errors_ = 0;
  uint64_t skipped_before_checkpoint_ = 0;
};

}  // namespace odonav
