// The calibration's checkpoint file (calibration_checkpoint.hpp).
#include "odonav/calibration/calibration_checkpoint.hpp"

#include <cmath>
#include <stdexcept>
#include <utility>

namespace odonav::calibration {

ODONAV_STATE_FIELDS(CalibrationCheckpoint) {
  a("last_sample_t_s", s.last_sample_t_s)("calibrator", s.calibrator_state);
  a.check("last_sample_t_s", std::isfinite(s.last_sample_t_s), "is not finite");
}

namespace {
constexpr CheckpointKind kKind{kCalibrationCheckpointComponent, kCalibrationCheckpointVersion};
}  // namespace

std::string calibration_checkpoint_path(const std::string& state_dir, const std::string& vehicle_id) {
  return kKind.path(state_dir, vehicle_id);
}

std::string serialize_calibration_checkpoint(const CalibrationCheckpoint& c) {
  if (!std::isfinite(c.last_sample_t_s)) throw std::invalid_argument("checkpoint: last_sample_t_s is not finite");
  return kKind.seal(c);
}

CalibrationCheckpoint parse_calibration_checkpoint(const std::string& text) {
  return kKind.parse<CalibrationCheckpoint>(text);
}

CalibrationCheckpointLoad load_calibration_checkpoint(const std::string& path, const std::string& vehicle_id,
                                                      const std::string& config_hash,
                                                      MisalignmentCalibrator& calibrator, int64_t unix_time_s) {
  const CheckpointIdentity expected = kKind.identity(vehicle_id, config_hash);
  CalibrationCheckpointLoad result;
  std::optional<double> t_s;
  static_cast<CheckpointFileLoad&>(result) =
      load_checkpoint_file(path, unix_time_s, expected, [&](const StateJson& payload) {
        const CalibrationCheckpoint c = checkpoint_from_payload<CalibrationCheckpoint>(expected, payload);
        restore_or_refuse("calibrator", calibrator, c.calibrator_state);  // unchanged when it throws
        t_s = c.last_sample_t_s;
      });
  if (result.status == CheckpointLoadStatus::kRestored) result.restored_t_s = t_s;
  return result;
}

}  // namespace odonav::calibration
