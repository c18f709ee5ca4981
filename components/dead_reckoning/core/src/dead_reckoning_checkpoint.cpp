// The dead reckoning's checkpoint file (dead_reckoning_checkpoint.hpp).
#include "odonav/dead_reckoning/dead_reckoning_checkpoint.hpp"

#include <cmath>
#include <stdexcept>
#include <utility>

#include "odonav/stream_state.hpp"

namespace odonav::dead_reckoning {

ODONAV_STATE_FIELDS(ScaleFactorSelectionCounters) {
  a("k_applied", s.k_applied)("k_ignored", s.k_ignored)("k_source_changes", s.k_source_changes);
}

ODONAV_STATE_FIELDS(ScaleFactorSelection::State) {
  a("commanded", s.commanded)("last_k_stamp_s", s.last_k_stamp_s)("k_source", s.k_source)(
      "in_force_source", s.in_force_source)("counters", s.counters);
}

ODONAV_STATE_FIELDS(DeadReckoningCheckpoint) {
  a("last_output_t_s", s.last_output_t_s)("fed_until_s", s.fed_until_s)("k_selection", s.k_selection)(
      "applied_misalignment", s.applied_misalignment)("misalignments_applied", s.misalignments_applied)(
      "held_misalignment_t_s", s.held_misalignment_t_s)("dead_reckoner", s.dead_reckoner_state)("anchored_position",
                                                                                                s.anchor_state);
  a.check("last_output_t_s", std::isfinite(s.last_output_t_s), "is not finite");
}

namespace {
constexpr CheckpointKind kKind{kDeadReckoningCheckpointComponent, kDeadReckoningCheckpointVersion};
}  // namespace

std::string dead_reckoning_checkpoint_path(const std::string& state_dir, const std::string& vehicle_id) {
  return kKind.path(state_dir, vehicle_id);
}

std::string serialize_dead_reckoning_checkpoint(const DeadReckoningCheckpoint& c) {
  if (!std::isfinite(c.last_output_t_s)) throw std::invalid_argument("checkpoint: last_output_t_s is not finite");
  return kKind.seal(c);
}

void save_state_into(DeadReckoningCheckpoint& checkpoint, const DeadReckoningStateRefs& state) {
  checkpoint.k_selection = state.consumer.k_selection.state();
  checkpoint.applied_misalignment = state.consumer.applied_misalignment.state();
  checkpoint.misalignments_applied = state.consumer.misalignments_applied;
  checkpoint.held_misalignment_t_s = state.consumer.held_misalignment_t_s;
  checkpoint.dead_reckoner_state = state.core.save_state();
  checkpoint.anchor_state = state.anchor.save_state();
}

DeadReckoningCheckpoint parse_dead_reckoning_checkpoint(const std::string& text) {
  return kKind.parse<DeadReckoningCheckpoint>(text);
}

DeadReckoningCheckpointLoad load_dead_reckoning_checkpoint(const std::string& path, const std::string& vehicle_id,
                                                           const std::string& config_hash,
                                                           const DeadReckoningStateRefs& state, int64_t unix_time_s) {
  const CheckpointIdentity expected = kKind.identity(vehicle_id, config_hash);
  DeadReckoningCheckpointLoad result;
  std::optional<DeadReckoningCheckpoint> loaded;
  static_cast<CheckpointFileLoad&>(result) =
      load_checkpoint_file(path, unix_time_s, expected, [&](const StateJson& payload) {
        DeadReckoningCheckpoint c = checkpoint_from_payload<DeadReckoningCheckpoint>(expected, payload);
        // Both cores restored into copies first: nothing changes unless both are usable.
        DeadReckoner core = state.core;
        AnchoredPositionFilter anchor = state.anchor;
        restore_or_refuse("dead reckoner", core, c.dead_reckoner_state);
        restore_or_refuse("anchored position", anchor, c.anchor_state);
        state.core = std::move(core);
        state.anchor = std::move(anchor);
        state.consumer.k_selection.restore_state(c.k_selection);
        state.consumer.applied_misalignment.restore_state(c.applied_misalignment);
        state.consumer.misalignments_applied = c.misalignments_applied;
        state.consumer.held_misalignment_t_s = c.held_misalignment_t_s;
        loaded = std::move(c);
      });
  if (result.status == CheckpointLoadStatus::kRestored) result.checkpoint = std::move(loaded);
  return result;
}

}  // namespace odonav::dead_reckoning
