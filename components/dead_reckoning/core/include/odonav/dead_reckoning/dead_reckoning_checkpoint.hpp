#pragma once
// Checkpoint and restart of odonav-dead-reckoning, middleware-free: the complete state of the dead
// reckoning (DeadReckoner, AnchoredPositionFilter and what the node's event-time logic keeps) in a
// file, so a restarted dead reckoning resumes its track (same origin, position, anchored filter)
// instead of starting again at the next fix, and the shared RestartPolicy
// (odonav/restart_policy.hpp: skipped samples, catch-up, checkpoint period, health notes) with the
// dead reckoning's inputs.
//
// Unlike the estimators', the dead reckoner's state holds inputs it has taken in but not processed
// yet (an odometer sample waits for the attitude after it, GNSS and estimates arrive ahead of the
// odometer): the checkpoint keeps them, and the stamp of the last sample of each input taken in;
// after a restore each input's samples up to that stamp are skipped (RestartPolicy fed_until).
//
// File `<state-dir>/dead-reckoning-<vehicle>.ckpt`, versioned text (envelope: odonav/checkpoint_file.hpp):
//   odonav-dead-reckoning-checkpoint 2
//   vehicle <vehicle id>
//   config_hash <16 hex digits>
//   last_output_t_s <%.17g>             (event time of the last published output, s)
//   inputs_fed_until_s 5 <hex doubles>  (per DeadReckoningInput, the last stamp taken in; NaN none)
//   k_selection <commanded 0/1> <last K stamp or NaN> <k_applied> <k_ignored> <k_source_changes>
//   k_source <ScaleFactor.source followed, may be empty>
//   k_in_force_source <ScaleFactor.source of the identified K in force, may be empty>
//   applied_misalignment <n> <t heading pitch>...  (the misalignments given, for the messages)
//   misalignments_applied <n>
//   held_misalignment_t_s <0|1> <t>
//   state_chars <n> + DeadReckoner::save_state() text
//   state_chars <n> + AnchoredPositionFilter::save_state() text
//   checksum <16 hex digits>
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
#include "odonav/restart_policy.hpp"
#include "odonav/stream_buffers.hpp"

namespace odonav {

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
  std::string dead_reckoner_state;  ///< DeadReckoner::save_state()
  std::string anchor_state;         ///< AnchoredPositionFilter::save_state()
};

/// `<state_dir>/dead-reckoning-<vehicle_id>.ckpt` (std::invalid_argument for a bad vehicle id).
std::string dead_reckoning_checkpoint_path(const std::string& state_dir, const std::string& vehicle_id);
/// The file text (std::invalid_argument for an empty vehicle / hash or a non-finite time).
std::string serialize_dead_reckoning_checkpoint(const DeadReckoningCheckpoint& checkpoint);
/// Parses it. Throws CheckpointError naming the first problem (empty, truncated, checksum, version,
/// field).
DeadReckoningCheckpoint parse_dead_reckoning_checkpoint(const std::string& text);

/// Loads `path` into `state` when intact and made for this vehicle and configuration; otherwise
/// moves it aside (reason, moved_to) and leaves `state` untouched. Never throws for file contents.
struct DeadReckoningCheckpointLoad : CheckpointFileLoad {
  std::optional<DeadReckoningCheckpoint> checkpoint;  ///< when restored
};
DeadReckoningCheckpointLoad load_dead_reckoning_checkpoint(const std::string& path, const std::string& vehicle_id,
                                                           const std::string& config_hash,
                                                           const DeadReckoningStateRefs& state, int64_t unix_time_s);

/// One dead-reckoning run's restart policy. Not thread-safe: the node runs it one task at a time.
class DeadReckoningLifecycle {
 public:
  /// settings.state_dir empty: checkpointing off (nothing restored, skipped or written).
  DeadReckoningLifecycle(CheckpointSettings settings, std::string vehicle_id);

  /// At start, before any input reaches the cores: creates the state directory (ConfigError), restores
  /// the checkpoint into `state` (or moves an unusable one aside: ERROR, WARN for 30 s, fresh start)
  /// and logs what it did.
  void start(const DeadReckoningStateRefs& state, int64_t unix_time_s, double steady_now_s);
  /// True when a sample must not reach the cores after a restore: taken in before the checkpoint
  /// (stamped at or before the input's last stamp in it), or an odometer sample in a lost span.
  /// Otherwise the sample is recorded as taken in (the next checkpoint's fed_until).
  bool take_sample(DeadReckoningInput input, double t_s);
  /// The outputs to publish: after a restore none at or before the checkpoint; catch-up counted.
  std::vector<DeadReckoningOutput> outputs_to_publish(std::vector<DeadReckoningOutput> outputs, double steady_now_s);
  /// Each odometer sample as it arrives: the live edge after a restore.
  void note_live_sample(double t_s, double steady_now_s) { restart_.note_live_sample(t_s, steady_now_s); }
  void checkpoint_if_due(const DeadReckoningStateRefs& state);
  void checkpoint_at_finish(const DeadReckoningStateRefs& state);

  const RestartPolicy& restart() const { return restart_; }
  const std::optional<double>& restored_t_s() const { return restart_.restored_t_s(); }

 private:
  std::string text_of(const DeadReckoningStateRefs& state, double t_s) const;

  std::string vehicle_id_;
  RestartPolicy restart_;
};

}  // namespace odonav
