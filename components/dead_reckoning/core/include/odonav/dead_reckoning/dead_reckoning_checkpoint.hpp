#pragma once
// Checkpoint of odonav-dead-reckoning, middleware-free: the complete state of the dead reckoning
// (DeadReckoner, AnchoredPositionFilter and what the node's event-time logic keeps) in a file, so a
// restarted dead reckoning resumes its track (same origin, position, anchored filter) instead of
// starting again at the next fix. When to write and how a restart goes on: DeadReckoningLifecycle
// (dead_reckoning_lifecycle.hpp).
//
// Unlike the estimators', the dead reckoner's state holds inputs it has taken in but not processed
// yet (an odometer sample waits for the attitude after it, GNSS and estimates arrive ahead of the
// odometer): the checkpoint keeps them, and the stamp of the last sample of each input taken in;
// after a restore each input's samples up to that stamp are skipped (RestartPolicy fed_until).
//
// File `<state-dir>/dead-reckoning-<vehicle>.ckpt`: the shared envelope (checkpoint_file.hpp:
// component "dead-reckoning", version kDeadReckoningCheckpointVersion, vehicle, configuration hash,
// checksum) around the payload (checkpoint_state.hpp):
//   last_output_t_s          event time of the last published output (s)
//   fed_until_s              per DeadReckoningInput, the last stamp taken in (null: none)
//   k_selection              ScaleFactorSelection::State (commanded, last K stamp, sources, counters)
//   applied_misalignment     the misalignments given (for the messages), misalignments_applied,
//   held_misalignment_t_s
//   dead_reckoner            DeadReckoner::save_state()
//   anchored_position        AnchoredPositionFilter::save_state()
// A file of another version (the text files before version 3 included) is moved aside: fresh start.
// Written atomically, every --checkpoint-every-s of event time and at shutdown.
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "odonav/checkpoint_file.hpp"
#include "odonav/dead_reckoning/anchored_position.hpp"
#include "odonav/dead_reckoning/dead_reckoner.hpp"
#include "odonav/dead_reckoning/scale_factor_selection.hpp"
#include "odonav/stream_buffers.hpp"

namespace odonav::dead_reckoning {

/// The envelope's component name and version of the dead reckoning's checkpoint; the version is
/// bumped whenever anything in the payload (the cores' states included) changes.
inline constexpr const char* kDeadReckoningCheckpointComponent = "dead-reckoning";
inline constexpr int kDeadReckoningCheckpointVersion = 3;

/// The inputs of the dead reckoning, as the restart policy indexes them.
enum class DeadReckoningInput { kOdometer, kGnss, kIns, kMisalignment, kScaleFactor };
inline constexpr std::size_t kDeadReckoningInputs = 5;

/// What the dead-reckoning node keeps besides the cores, in event time: the K policy, the
/// misalignments given to the core (to report the one applied in each output) and their count.
struct DeadReckoningConsumerState {
  explicit DeadReckoningConsumerState(double nominal_k_m_per_pulse,
                                      double nominal_k_rel_sigma = kDefaultNominalKRelSigma)
      : k_selection(nominal_k_m_per_pulse, nominal_k_rel_sigma) {}
  ScaleFactorSelection k_selection;
  StepHistory<Misalignment> applied_misalignment{"misalignment"};
  uint64_t misalignments_applied = 0;
  std::optional<double> held_misalignment_t_s;  ///< stamp of the last misalignment applied
};

/// The state a checkpoint restores into (all owned by the node).
struct DeadReckoningStateRefs {
  DeadReckoner& core;
  AnchoredPositionFilter& anchor;
  DeadReckoningConsumerState& consumer;
};

struct DeadReckoningCheckpoint {
  std::string vehicle_id;
  std::string config_hash;
  double last_output_t_s = 0.0;  ///< event time of the last published output (s, finite)
  std::array<std::optional<double>, kDeadReckoningInputs> fed_until_s;  ///< last stamp taken in, per input
  ScaleFactorSelection::State k_selection;
  StepHistory<Misalignment>::State applied_misalignment;
  uint64_t misalignments_applied = 0;
  std::optional<double> held_misalignment_t_s;
  StateJson dead_reckoner_state;  ///< DeadReckoner::save_state()
  StateJson anchor_state;         ///< AnchoredPositionFilter::save_state()
};

/// Copies the saved state of `state` (core, anchored filter, consumer rules) into `checkpoint`'s
/// state fields, the counterpart of what load_dead_reckoning_checkpoint restores; identity, times and
/// input marks are left as they are.
void save_state_into(DeadReckoningCheckpoint& checkpoint, const DeadReckoningStateRefs& state);

/// `<state_dir>/dead-reckoning-<vehicle_id>.ckpt` (std::invalid_argument for a bad vehicle id).
std::string dead_reckoning_checkpoint_path(const std::string& state_dir, const std::string& vehicle_id);
/// The file text (std::invalid_argument for an empty vehicle / hash or a non-finite time).
std::string serialize_dead_reckoning_checkpoint(const DeadReckoningCheckpoint& checkpoint);
/// Parses it. Throws CheckpointError naming the first problem (empty, truncated, not a checkpoint,
/// checksum, another component or version, field).
DeadReckoningCheckpoint parse_dead_reckoning_checkpoint(const std::string& text);

/// Loads `path` into `state` when intact and made for this vehicle and configuration; otherwise
/// moves it aside (reason, moved_to) and leaves `state` untouched. Never throws for file contents.
struct DeadReckoningCheckpointLoad : CheckpointFileLoad {
  std::optional<DeadReckoningCheckpoint> checkpoint;  ///< when restored
};
DeadReckoningCheckpointLoad load_dead_reckoning_checkpoint(const std::string& path, const std::string& vehicle_id,
                                                           const std::string& config_hash,
                                                           const DeadReckoningStateRefs& state, int64_t unix_time_s);

}  // namespace odonav::dead_reckoning
