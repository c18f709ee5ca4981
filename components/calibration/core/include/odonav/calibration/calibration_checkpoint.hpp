#pragma once
// Checkpoint of odonav-calibration, middleware-free: the calibrator's state in a file, so a
// restarted calibration resumes instead of starting from nothing. When to write and how a restart
// goes on: CalibrationLifecycle (calibration_lifecycle.hpp).
//
// File `<state-dir>/calibration-<vehicle>.ckpt`: the shared envelope (checkpoint_file.hpp: component
// "calibration", version kCalibrationCheckpointVersion, vehicle, configuration hash, checksum) around
// the payload (checkpoint_state.hpp):
//   last_sample_t_s   event time of the last processed GNSS epoch (s)
//   calibrator        MisalignmentCalibrator::save_state()
// A file of another version (the text files before version 2 included) is moved aside: fresh start.
// Written atomically (write_file_atomically), every --checkpoint-every-s of event time and at shutdown.
#include <cstdint>
#include <optional>
#include <string>

#include "odonav/calibration/misalignment_calibrator.hpp"
#include "odonav/checkpoint_file.hpp"

namespace odonav::calibration {

/// The envelope's component name and version of the calibration's checkpoint; the version is
/// bumped whenever anything in the payload (the calibrator's state included) changes.
inline constexpr const char* kCalibrationCheckpointComponent = "calibration";
inline constexpr int kCalibrationCheckpointVersion = 3;

struct CalibrationCheckpoint {
  std::string vehicle_id;        ///< the vehicle whose data made the state.
  std::string config_hash;       ///< config_hash_of() of the run that wrote it.
  double last_sample_t_s = 0.0;  ///< event time of the last processed GNSS epoch (s, finite).
  StateJson calibrator_state;    ///< MisalignmentCalibrator::save_state().
};

/// `<state_dir>/calibration-<vehicle_id>.ckpt`. Throws std::invalid_argument for a vehicle id that
/// cannot be part of a file name (check_checkpoint_vehicle_id).
std::string calibration_checkpoint_path(const std::string& state_dir, const std::string& vehicle_id);
/// The file text. Throws std::invalid_argument when the vehicle or hash is empty, or
/// last_sample_t_s is not finite.
std::string serialize_calibration_checkpoint(const CalibrationCheckpoint& checkpoint);
/// Parses it. Throws CheckpointError naming the first problem: empty, truncated, not a checkpoint,
/// checksum mismatch, another component or version, missing or malformed field.
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

}  // namespace odonav::calibration
