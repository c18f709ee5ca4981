// The dead reckoning's restart policy (dead_reckoning_lifecycle.hpp).
#include "odonav/dead_reckoning/dead_reckoning_lifecycle.hpp"

#include <algorithm>
#include <cstdio>
#include <utility>

#include "odonav/frames.hpp"

namespace odonav::dead_reckoning {

DeadReckoningLifecycle::DeadReckoningLifecycle(CheckpointSettings settings, std::string vehicle_id)
    : vehicle_id_(std::move(vehicle_id)),
      // Indexed by DeadReckoningInput. Every input is skipped up to its last stamp in the checkpoint
      // (fed_until), so margins do not apply; the odometer makes the outputs.
      restart_(std::move(settings), {{"odometer", 0.0, true, true},
                                     {"GNSS", 0.0, true, false},
                                     {"INS", 0.0, true, false},
                                     {"misalignment", 0.0, true, false},
                                     {"scale factor", 0.0, true, false}}) {}

void DeadReckoningLifecycle::start(const DeadReckoningStateRefs& state, int64_t unix_time_s, double steady_now_s) {
  if (restart_.settings().state_dir.empty()) return;
  const std::string& file =
      restart_.open_state_dir([&](const std::string& dir) { return dead_reckoning_checkpoint_path(dir, vehicle_id_); });
  const DeadReckoningCheckpointLoad r =
      load_dead_reckoning_checkpoint(file, vehicle_id_, restart_.settings().config_hash, state, unix_time_s);
  if (!restart_.note_load(
          r,
          r.status == CheckpointLoadStatus::kNone ? "starting at the first GNSS fix" : "starting at the next GNSS fix",
          steady_now_s))
    return;
  const DeadReckoningCheckpoint& c = *r.checkpoint;
  char line[300];
  if (const std::optional<Geodetic> origin = state.core.origin()) {
    std::snprintf(line, sizeof line,
                  "restored the dead reckoning from checkpoint (t=%.3f s): origin %.7f deg, %.7f deg, %.2f m, "
                  "%llu outputs",
                  c.last_output_t_s, rad_to_deg(origin->lat_rad), rad_to_deg(origin->lon_rad), origin->height_m,
                  static_cast<unsigned long long>(state.core.counters().outputs));
  } else {
    std::snprintf(line, sizeof line, "restored the dead reckoning from checkpoint (t=%.3f s): not started yet",
                  c.last_output_t_s);
  }
  restart_.note_restored(line, c.last_output_t_s, steady_now_s,
                         std::vector<std::optional<double>>(c.fed_until_s.begin(), c.fed_until_s.end()));
}

bool DeadReckoningLifecycle::take_sample(DeadReckoningInput input, double t_s) {
  return !restart_.skip_sample(static_cast<std::size_t>(input), t_s);
}

std::vector<DeadReckoningOutput> DeadReckoningLifecycle::outputs_to_publish(std::vector<DeadReckoningOutput> outputs,
                                                                            double steady_now_s) {
  return restart_.keep_outputs(std::move(outputs), steady_now_s);
}

std::string DeadReckoningLifecycle::text_of(const DeadReckoningStateRefs& state, double t_s) const {
  DeadReckoningCheckpoint c;
  c.vehicle_id = vehicle_id_;
  c.config_hash = restart_.settings().config_hash;
  c.last_output_t_s = t_s;
  const auto& taken = restart_.taken_until_t_s();
  std::copy(taken.begin(), taken.end(), c.fed_until_s.begin());
  save_state_into(c, state);
  return serialize_dead_reckoning_checkpoint(c);
}

void DeadReckoningLifecycle::checkpoint_if_due(const DeadReckoningStateRefs& state) {
  restart_.checkpoint_if_due([&](double t_s) { return text_of(state, t_s); });
}

void DeadReckoningLifecycle::checkpoint_at_finish(const DeadReckoningStateRefs& state) {
  restart_.checkpoint_at_finish([&](double t_s) { return text_of(state, t_s); });
}

}  // namespace odonav::dead_reckoning
