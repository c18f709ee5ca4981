#include "odonav/dead_reckoning/dead_reckoning_checkpoint.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <stdexcept>

#include "odonav/frames.hpp"

namespace odonav {

namespace {
constexpr const char* kMagic = "odonav-dead-reckoning-checkpoint";
constexpr int kVersion = 2;  // 2: k_in_force_source
constexpr double kNone = std::numeric_limits<double>::quiet_NaN();

double or_none(const std::optional<double>& v) { return v.value_or(kNone); }
std::optional<double> of_none(double v) { return std::isnan(v) ? std::nullopt : std::optional<double>(v); }
}  // namespace

std::string dead_reckoning_checkpoint_path(const std::string& state_dir, const std::string& vehicle_id) {
  check_checkpoint_vehicle_id(vehicle_id);
  return (std::filesystem::path(state_dir) / ("dead-reckoning-" + vehicle_id + ".ckpt")).string();
}

std::string serialize_dead_reckoning_checkpoint(const DeadReckoningCheckpoint& c) {
  std::vector<double> fed;
  for (const auto& f : c.fed_until_s) fed.push_back(or_none(f));
  const ScaleFactorSelection::State& k = c.k_selection;
  std::vector<double> applied;
  for (const auto& [t, m] : c.applied_misalignment.entries)
    applied.insert(applied.end(), {t, m.heading_rad, m.pitch_rad});
  if (k.k_source.find('\n') != std::string::npos || k.in_force_source.find('\n') != std::string::npos)
    throw std::invalid_argument("dead-reckoning checkpoint: the K source holds a line break");
  return seal_checkpoint(
      checkpoint_head(kMagic, kVersion, c.vehicle_id, c.config_hash) +
      checkpoint_time_line("last_output_t_s", c.last_output_t_s) + checkpoint_value_list("inputs_fed_until_s", fed) +
      checkpoint_value_list(
          "k_selection",
          {k.commanded ? 1.0 : 0.0, or_none(k.last_k_stamp_s), static_cast<double>(k.counters.k_applied),
           static_cast<double>(k.counters.k_ignored), static_cast<double>(k.counters.k_source_changes)}) +
      "k_source " + k.k_source + "\n" + "k_in_force_source " + k.in_force_source + "\n" +
      checkpoint_value_list("applied_misalignment", applied) +
      checkpoint_value_list("applied_misalignment_last_t_s", {or_none(c.applied_misalignment.last_t_s)}) +
      "misalignments_applied " + std::to_string(c.misalignments_applied) + "\n" +
      checkpoint_value_list("held_misalignment_t_s", {or_none(c.held_misalignment_t_s)}) +
      checkpoint_state_block(c.dead_reckoner_state) + checkpoint_state_block(c.anchor_state));
}

DeadReckoningCheckpoint parse_dead_reckoning_checkpoint(const std::string& text) {
  const std::string body = unseal_checkpoint(text);
  CheckpointReader r(body);
  const CheckpointHead head = read_checkpoint_head(r, kMagic, kVersion);
  DeadReckoningCheckpoint c;
  c.vehicle_id = head.vehicle_id;
  c.config_hash = head.config_hash;
  c.last_output_t_s = r.double_field("last_output_t_s");
  auto exactly = [&](const char* key, std::size_t n) { return r.exact_values(key, n); };
  std::vector<double> v = exactly("inputs_fed_until_s", kDeadReckoningInputs);
  for (std::size_t i = 0; i < kDeadReckoningInputs; ++i) c.fed_until_s[i] = of_none(v[i]);
  v = exactly("k_selection", 5);
  if (v[0] != 0.0 && v[0] != 1.0) throw CheckpointError("field 'k_selection' has a bad commanded flag");
  c.k_selection.commanded = v[0] == 1.0;
  c.k_selection.last_k_stamp_s = of_none(v[1]);
  c.k_selection.counters = ScaleFactorSelectionCounters{static_cast<uint64_t>(v[2]), static_cast<uint64_t>(v[3]),
                                                        static_cast<uint64_t>(v[4])};
  c.k_selection.k_source = r.field("k_source");
  c.k_selection.in_force_source = r.field("k_in_force_source");
  v = r.value_list("applied_misalignment", 3);
  for (std::size_t i = 0; i < v.size(); i += 3)
    c.applied_misalignment.entries.emplace_back(v[i], Misalignment{v[i + 1], v[i + 2]});
  c.applied_misalignment.last_t_s = of_none(exactly("applied_misalignment_last_t_s", 1)[0]);
  c.misalignments_applied = r.unsigned_field("misalignments_applied");
  c.held_misalignment_t_s = of_none(exactly("held_misalignment_t_s", 1)[0]);
  c.dead_reckoner_state = read_checkpoint_state_block(r, "dead reckoner state");
  c.anchor_state = read_checkpoint_state_block(r, "anchored position state");
  if (!r.at_end()) throw CheckpointError("unexpected text after the anchored position state");
  return c;
}

DeadReckoningCheckpointLoad load_dead_reckoning_checkpoint(const std::string& path, const std::string& vehicle_id,
                                                           const std::string& config_hash,
                                                           const DeadReckoningStateRefs& state, int64_t unix_time_s) {
  DeadReckoningCheckpointLoad result;
  std::optional<DeadReckoningCheckpoint> loaded;
  static_cast<CheckpointFileLoad&>(result) = load_checkpoint_file(path, unix_time_s, [&](const std::string& text) {
    DeadReckoningCheckpoint c = parse_dead_reckoning_checkpoint(text);
    check_checkpoint_identity(c.vehicle_id, c.config_hash, vehicle_id, config_hash);
    // Both cores parsed into copies first: nothing changes unless both are usable.
    DeadReckoner core = state.core;
    AnchoredPositionFilter anchor = state.anchor;
    try {
      core.restore_state(c.dead_reckoner_state);
    } catch (const std::exception& e) {
      throw CheckpointError(std::string("dead reckoner state refused: ") + e.what());
    }
    try {
      anchor.restore_state(c.anchor_state);
    } catch (const std::exception& e) {
      throw CheckpointError(std::string("anchored position state refused: ") + e.what());
    }
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
  c.k_selection = state.consumer.k_selection.state();
  c.applied_misalignment = state.consumer.applied_misalignment.state();
  c.misalignments_applied = state.consumer.misalignments_applied;
  c.held_misalignment_t_s = state.consumer.held_misalignment_t_s;
  c.dead_reckoner_state = state.core.save_state();
  c.anchor_state = state.anchor.save_state();
  return serialize_dead_reckoning_checkpoint(c);
}

void DeadReckoningLifecycle::checkpoint_if_due(const DeadReckoningStateRefs& state) {
  restart_.checkpoint_if_due([&](double t_s) { return text_of(state, t_s); });
}

void DeadReckoningLifecycle::checkpoint_at_finish(const DeadReckoningStateRefs& state) {
  restart_.checkpoint_at_finish([&](double t_s) { return text_of(state, t_s); });
}

}  // namespace odonav
