#pragma once
// Checkpoint and restart of odonav-calibration, middleware-free: the calibrator's state in a file
// (so a restarted calibration resumes instead of starting from nothing) and its restart policy, the
// shared RestartPolicy (odonav/restart_policy.hpp: skipped samples, catch-up, checkpoint period,
// health notes) with the calibration's inputs and margins.
//
// File `<state-dir>/calibration-<vehicle>.ckpt`, versioned text (envelope: odonav/checkpoint_file.hpp):
//   odonav-calibration-checkpoint 1
//   vehicle <vehicle id>
//   config_hash <16 hex digits>          (config_hash_of: the options that change the estimate)
//   last_sample_t_s <%.17g: exact round trip>      (event time of the last processed GNSS epoch, s)
//   state_chars <n>
//   <n characters: MisalignmentCalibrator::save_state() text>
//   checksum <16 hex digits>             (FNV-1a 64 of every byte before this line)
// Written atomically (write_file_atomically), every --checkpoint-every-s of event time and at shutdown.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "odonav/calibration/misalignment_calibrator.hpp"
#include "odonav/checkpoint_file.hpp"
#include "odonav/restart_policy.hpp"

namespace odonav {

struct CalibrationCheckpoint {
  std::string vehicle_id;        ///< the vehicle whose data made the state (no line breaks).
  std::string config_hash;       ///< config_hash_of() of the run that wrote it.
  double last_sample_t_s = 0.0;  ///< event time of the last processed GNSS epoch (s, finite).
  std::string calibrator_state;  ///< MisalignmentCalibrator::save_state() text.
};

/// `<state_dir>/calibration-<vehicle_id>.ckpt`. Throws std::invalid_argument for a vehicle id that
/// cannot be part of a file name (check_checkpoint_vehicle_id).
std::string calibration_checkpoint_path(const std::string& state_dir, const std::string& vehicle_id);
/// The file text. Throws std::invalid_argument when the vehicle or hash is empty or holds a line
/// break, or last_sample_t_s is not finite.
std::string serialize_calibration_checkpoint(const CalibrationCheckpoint& checkpoint);
/// Parses it. Throws CheckpointError naming the first problem: empty, truncated, checksum mismatch,
/// unknown version, missing or malformed field.
CalibrationCheckpoint parse_calibration_checkpoint(const std::string& text);

/// Loads `path` into `calibrator` when it is intact and made for this vehicle and configuration
/// hash; otherwise the file is moved aside (named in reason and moved_to), the calibrator is left
/// untouched. restored_t_s: the checkpoint's time when restored. Never throws for file contents.
struct CalibrationCheckpointLoad : CheckpointFileLoad {
  std::optional<double> restored_t_s;
};
CalibrationCheckpointLoad load_calibration_checkpoint(const std::string& path, const std::string& vehicle_id,
                                                      const std::string& config_hash,
                                                      MisalignmentCalibrator& calibrator, int64_t unix_time_s);

/// The inputs whose samples may predate a restored checkpoint (CalibrationLifecycle::skip_sample).
enum class CalibrationInput { kGnss, kIns };

/// One calibration run's restart policy. Not thread-safe: the node runs it one task at a time.
class CalibrationLifecycle {
 public:
  /// settings.state_dir empty: checkpointing is off (start() does nothing, nothing is skipped, no
  /// checkpoint is written). ins_margin_s: MisalignmentCalibrator::restore_margin_s().
  CalibrationLifecycle(CheckpointSettings settings, std::string vehicle_id, double ins_margin_s);

  /// At start, before any input reaches the calibrator. With a state directory: creates it
  /// (ConfigError "--state-dir '<dir>': ..."), restores the checkpoint into `calibrator` (or moves an
  /// unusable one aside, logged as ERROR and WARN in the health for 30 s: fresh start from nothing)
  /// and logs what it did.
  void start(MisalignmentCalibrator& calibrator, int64_t unix_time_s, double steady_now_s);
  /// The restored output to publish at once (the calibrator's current() at the checkpoint's epoch),
  /// at most once; nothing without a restore.
  std::optional<MisalignmentOutput> take_restored_output();
  /// True when a sample must not reach the calibrator after a restore: GNSS at or before the
  /// checkpoint (processed already) or inside a span the producers' history no longer held (lost),
  /// INS more than ins_margin_s before it (RestartPolicy::skip_sample).
  bool skip_sample(CalibrationInput input, double t_s);
  bool first_sample_seen(CalibrationInput input) const {
    return restart_.first_sample_seen(static_cast<std::size_t>(input));
  }
  /// The calibrator's outputs to publish: after a restore none at or before the checkpoint; the
  /// outputs up to the live edge are counted as catch-up (RestartPolicy::keep_output).
  std::vector<MisalignmentOutput> outputs_to_publish(std::vector<MisalignmentOutput> outputs, double steady_now_s);
  /// Each INS sample as it arrives (GNSS without INS), before any alignment: the live edge after a
  /// restore (RestartPolicy::note_live_sample).
  void note_live_sample(double t_s, double steady_now_s) { restart_.note_live_sample(t_s, steady_now_s); }
  /// The checkpoint of the calibrator after its last processed epoch, when due / at shutdown
  /// (failures logged and counted, never thrown).
  void checkpoint_if_due(const MisalignmentCalibrator& calibrator);
  void checkpoint_at_finish(const MisalignmentCalibrator& calibrator);

  const RestartPolicy& restart() const { return restart_; }
  const std::optional<double>& restored_t_s() const { return restart_.restored_t_s(); }

 private:
  std::string text_of(const MisalignmentCalibrator& calibrator, double t_s) const;

  std::string vehicle_id_;
  RestartPolicy restart_;
  std::optional<MisalignmentOutput> restored_output_;
};

}  // namespace odonav
