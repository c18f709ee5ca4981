#pragma once
// Checkpoint of odonav-identification (DDS persistence keeps samples, not the estimator's state): the
// complete state of the identification, so that a restarted one resumes exactly where it stopped
// instead of re-converging from the nominal K. Middleware-free; IdentificationLifecycle
// (identification_lifecycle.hpp) decides when to write.
//
// The state holds inputs taken in but not processed yet (the sample builder buffers odometer and INS
// ahead of the GNSS epochs, and GNSS ahead of the sensors) and the slow state of the gates and the
// GNSS latency estimate (its sums over the whole drive, the latency in force), which no history of
// the producers could rebuild. So the checkpoint keeps, per input, the stamp of the last sample taken
// in; after a restore each input's samples up to it are skipped.
//
// File `<state-dir>/identification-<vehicle>.ckpt` (with --instance: instance.hpp), the shared
// envelope (checkpoint_file.hpp: component "identification", version kIdentificationCheckpointVersion,
// vehicle, configuration hash, checksum) around the payload (checkpoint_state.hpp):
//   estimator                the main estimator's name
//   last_sample_t_s          event time of the last processed GNSS epoch (s)
//   samples_accepted, samples_rejected
//   fed_until_s              per IdentificationInput, the last stamp taken in (null: none)
//   misalignments_applied, held_misalignment_t_s
//   core                     IdentificationCore::save_state()
// A file of another version (the text files before version 3 included) is refused like a corrupt
// one: moved aside, fresh start.
// Written atomically (temporary file in the same directory, fsync, rename, fsync of the directory),
// so a kill -9 at any instant leaves either the previous checkpoint or the new one, never a mix.
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "odonav/checkpoint_file.hpp"
#include "odonav/identification/identification_core.hpp"
#include "odonav/safe_output.hpp"
#include "odonav/scale_factor_estimator.hpp"

namespace odonav::identification {

/// The envelope's component name and version of the identification's checkpoint; the version is
/// bumped whenever anything in the payload (the core's state included) changes.
inline constexpr const char* kIdentificationCheckpointComponent = "identification";
inline constexpr int kIdentificationCheckpointVersion = 4;

/// The inputs of the identification, as the restart policy indexes them.
enum class IdentificationInput { kOdometer, kGnss, kIns, kMisalignment };
inline constexpr std::size_t kIdentificationInputs = 4;

struct IdentificationCheckpoint {
  std::string vehicle_id;         ///< the vehicle whose data made the state (no line breaks).
  std::string config_hash;        ///< config_hash_of() of the run that wrote it.
  std::string estimator_name;     ///< the main estimator's name() (e.g. "vff_lm_rls").
  double last_sample_t_s = 0.0;   ///< event time of the last processed GNSS epoch (s, finite).
  uint64_t samples_accepted = 0;  ///< accepted regression samples up to last_sample_t_s.
  uint64_t samples_rejected = 0;  ///< gated-out epochs up to last_sample_t_s.
  /// Per IdentificationInput, the stamp of the last sample taken in (event time, s).
  std::array<std::optional<double>, kIdentificationInputs> fed_until_s;
  uint64_t misalignments_applied = 0;           ///< converged misalignments given to the core.
  std::optional<double> held_misalignment_t_s;  ///< stamp of the last one (s).
  StateJson core_state;                         ///< IdentificationCore::save_state().
};

// checkpoint_neutral_options() and config_hash_of() (the configuration hash) are shared with the
// calibration: odonav/checkpoint_file.hpp.

/// `<state_dir>/identification-<vehicle_id>.ckpt`. Throws std::invalid_argument when vehicle_id is
/// empty or holds anything but letters, digits, '.', '_' and '-' (it becomes a file name).
std::string checkpoint_path(const std::string& state_dir, const std::string& vehicle_id);

/// The file text (see the file comment). Throws std::invalid_argument when vehicle_id, config_hash or
/// estimator_name is empty, or last_sample_t_s is not finite.
std::string serialize_checkpoint(const IdentificationCheckpoint& checkpoint);
/// Parses serialize_checkpoint's text. Throws CheckpointError naming the first problem: empty,
/// truncated, not a checkpoint, checksum mismatch, another component or version, missing or
/// malformed field.
IdentificationCheckpoint parse_checkpoint(const std::string& text);

// Checkpoints are written with write_file_atomically (odonav/safe_output.hpp); an unusable one is
// moved aside with move_checkpoint_aside (odonav/checkpoint_file.hpp, with CheckpointError and
// CheckpointLoadStatus).

struct CheckpointLoadResult {
  CheckpointLoadStatus status = CheckpointLoadStatus::kNone;
  std::string path;                                    ///< the checkpoint file looked at.
  std::optional<IdentificationCheckpoint> checkpoint;  ///< present iff kRestored.
  std::string reason;                                  ///< why it was moved aside (kMovedAside).
  std::string moved_to;                                ///< its new name (kMovedAside; empty if the move failed).
};

/// Loads `path` and restores `core` from it when it is intact and made by this vehicle, this
/// configuration hash and a main estimator of the same name. Otherwise (truncated, garbage, checksum,
/// an older version, wrong vehicle, other configuration, other estimator, a state the core refuses)
/// the file is moved aside (move_checkpoint_aside with unix_time_s), `core` is left untouched and the
/// reason is returned. Never throws for file contents; an unreadable file is treated like a corrupt one.
CheckpointLoadResult load_identification_checkpoint(const std::string& path, const std::string& vehicle_id,
                                                    const std::string& config_hash, IdentificationCore& core,
                                                    int64_t unix_time_s);

/// One-line description for logs and health: "restored K=0.0125123 m/pulse from checkpoint (t=61.2 s)"
/// or "checkpoint <file> was corrupt (<reason>): moved aside; starting from nominal K".
std::string describe(const CheckpointLoadResult& result, const ScaleFactorEstimator& estimator);

}  // namespace odonav::identification
