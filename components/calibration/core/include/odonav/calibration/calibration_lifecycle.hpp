#pragma once
// The restart policy of odonav-calibration, middleware-free: the shared RestartPolicy
// (odonav/restart_policy.hpp: skipped samples, catch-up, checkpoint period, health notes) with the
// calibration's inputs and margins, around its checkpoint file (calibration_checkpoint.hpp).
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "odonav/calibration/calibration_checkpoint.hpp"
#include "odonav/calibration/misalignment_calibrator.hpp"
#include "odonav/restart_policy.hpp"

namespace odonav::calibration {

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

}  // namespace odonav::calibration
