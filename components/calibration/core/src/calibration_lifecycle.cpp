// The calibration's restart policy (calibration_lifecycle.hpp).
#include "odonav/calibration/calibration_lifecycle.hpp"

#include <utility>

#include "odonav/frames.hpp"
#include "odonav/printf_text.hpp"

namespace odonav::calibration {

CalibrationLifecycle::CalibrationLifecycle(CheckpointSettings settings, std::string vehicle_id, double ins_margin_s)
    : vehicle_id_(std::move(vehicle_id)),
      // Indexed by CalibrationInput. The GNSS epoch at the checkpoint was processed: skipped, not
      // fed again (it would enter the regressions twice).
      restart_(std::move(settings), {{"GNSS", 0.0, true, true}, {"INS", ins_margin_s, false, false}}) {}

void CalibrationLifecycle::start(MisalignmentCalibrator& calibrator, int64_t unix_time_s, double steady_now_s) {
  if (restart_.settings().state_dir.empty()) return;
  const std::string& file =
      restart_.open_state_dir([&](const std::string& dir) { return calibration_checkpoint_path(dir, vehicle_id_); });
  const CalibrationCheckpointLoad r =
      load_calibration_checkpoint(file, vehicle_id_, restart_.settings().config_hash, calibrator, unix_time_s);
  if (!restart_.note_load(r, "starting from nothing", steady_now_s)) return;
  restored_output_ = calibrator.current();
  const MisalignmentOutput& o = *restored_output_;
  const std::string line = printf_text(
      "restored misalignment heading %.6f deg, pitch %.6f deg (%llu epochs used, %s) from checkpoint (t=%.3f s)",
      rad_to_deg(o.misalignment.heading_rad), rad_to_deg(o.misalignment.pitch_rad),
      static_cast<unsigned long long>(o.samples_used), to_string(o.state), *r.restored_t_s);
  restart_.note_restored(line, *r.restored_t_s, steady_now_s);
}

std::optional<MisalignmentOutput> CalibrationLifecycle::take_restored_output() {
  return std::exchange(restored_output_, std::nullopt);
}

bool CalibrationLifecycle::skip_sample(CalibrationInput input, double t_s) {
  return restart_.skip_sample(static_cast<std::size_t>(input), t_s);
}

std::vector<MisalignmentOutput> CalibrationLifecycle::outputs_to_publish(std::vector<MisalignmentOutput> outputs,
                                                                         double steady_now_s) {
  return restart_.keep_outputs(std::move(outputs), steady_now_s);
}

std::string CalibrationLifecycle::text_of(const MisalignmentCalibrator& calibrator, double t_s) const {
  return serialize_calibration_checkpoint(
      CalibrationCheckpoint{vehicle_id_, restart_.settings().config_hash, t_s, calibrator.save_state()});
}

void CalibrationLifecycle::checkpoint_if_due(const MisalignmentCalibrator& calibrator) {
  restart_.checkpoint_if_due([&](double t_s) { return text_of(calibrator, t_s); });
}

void CalibrationLifecycle::checkpoint_at_finish(const MisalignmentCalibrator& calibrator) {
  restart_.checkpoint_at_finish([&](double t_s) { return text_of(calibrator, t_s); });
}

}  // namespace odonav::calibration
