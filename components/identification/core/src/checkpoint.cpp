#include "odonav/identification/checkpoint.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <sstream>

namespace odonav {

namespace {

constexpr const char* kMagic = "odonav-identification-checkpoint";
constexpr int kVersion = 2;
constexpr double kNone = std::numeric_limits<double>::quiet_NaN();

bool has_line_break(const std::string& s) { return s.find_first_of("\r\n") != std::string::npos; }

}  // namespace

std::string checkpoint_path(const std::string& state_dir, const std::string& vehicle_id) {
  check_checkpoint_vehicle_id(vehicle_id);
  return (std::filesystem::path(state_dir) / ("identification-" + vehicle_id + ".ckpt")).string();
}

std::string serialize_checkpoint(const IdentificationCheckpoint& c) {
  if (c.estimator_name.empty() || has_line_break(c.estimator_name))
    throw std::invalid_argument("checkpoint: estimator name is empty or holds a line break");
  std::vector<double> fed;
  for (const auto& f : c.fed_until_s) fed.push_back(f.value_or(kNone));
  std::ostringstream s;
  s << checkpoint_head(kMagic, kVersion, c.vehicle_id, c.config_hash) << "estimator " << c.estimator_name << '\n'
    << checkpoint_time_line("last_sample_t_s", c.last_sample_t_s) << "samples_accepted " << c.samples_accepted << '\n'
    << "samples_rejected " << c.samples_rejected << '\n'
    << checkpoint_value_list("inputs_fed_until_s", fed) << "misalignments_applied " << c.misalignments_applied << '\n'
    << checkpoint_value_list("held_misalignment_t_s", c.held_misalignment_t_s
                                                          ? std::vector<double>{*c.held_misalignment_t_s}
                                                          : std::vector<double>{})
    << checkpoint_state_block(c.core_state);
  return seal_checkpoint(s.str());
}

IdentificationCheckpoint parse_checkpoint(const std::string& text) {
  const std::string body = unseal_checkpoint(text);
  CheckpointReader r(body);
  const CheckpointHead head = read_checkpoint_head(r, kMagic, kVersion);
  IdentificationCheckpoint c;
  c.vehicle_id = head.vehicle_id;
  c.config_hash = head.config_hash;
  c.estimator_name = r.field("estimator");
  c.last_sample_t_s = r.double_field("last_sample_t_s");
  c.samples_accepted = r.unsigned_field("samples_accepted");
  c.samples_rejected = r.unsigned_field("samples_rejected");
  const std::vector<double> fed = r.value_list("inputs_fed_until_s", kIdentificationInputs, kIdentificationInputs);
  if (fed.size() != kIdentificationInputs)
    throw CheckpointError("field 'inputs_fed_until_s' does not hold " + std::to_string(kIdentificationInputs) +
                          " values");
  for (std::size_t i = 0; i < kIdentificationInputs; ++i)
    if (!std::isnan(fed[i])) c.fed_until_s[i] = fed[i];
  c.misalignments_applied = r.unsigned_field("misalignments_applied");
  const std::vector<double> held = r.value_list("held_misalignment_t_s", 1, 1);
  if (!held.empty()) c.held_misalignment_t_s = held[0];
  c.core_state = read_checkpoint_state_block(r, "identification state");
  if (!r.at_end()) throw CheckpointError("unexpected text after the identification state");
  if (c.estimator_name.empty()) throw CheckpointError("empty estimator");
  return c;
}

CheckpointLoadResult load_identification_checkpoint(const std::string& path, const std::string& vehicle_id,
                                                    const std::string& config_hash, IdentificationCore& core,
                                                    int64_t unix_time_s) {
  std::optional<IdentificationCheckpoint> restored;
  const CheckpointFileLoad load = load_checkpoint_file(path, unix_time_s, [&](const std::string& text) {
    IdentificationCheckpoint c = parse_checkpoint(text);
    check_checkpoint_identity(c.vehicle_id, c.config_hash, vehicle_id, config_hash);
    if (c.estimator_name != core.main_estimator_name())
      throw CheckpointError("made by estimator '" + c.estimator_name + "', this is '" + core.main_estimator_name() +
                            "'");
    try {
      core.restore_state(c.core_state);  // unchanged when it throws
    } catch (const std::exception& e) {
      throw CheckpointError(std::string("identification state refused: ") + e.what());
    }
    restored = std::move(c);
  });
  CheckpointLoadResult result;
  result.status = load.status;
  result.path = load.path;
  result.reason = load.reason;
  result.moved_to = load.moved_to;
  if (load.status == CheckpointLoadStatus::kRestored) result.checkpoint = std::move(restored);
  return result;
}

std::string describe(const CheckpointLoadResult& r, const ScaleFactorEstimator& estimator) {
  switch (r.status) {
    case CheckpointLoadStatus::kNone: return "no checkpoint " + r.path + ": starting from nominal K";
    case CheckpointLoadStatus::kRestored: {
      const ScaleFactorEstimate e = estimator.estimate();
      char buf[160];
      if (e.valid)
        std::snprintf(buf, sizeof buf, "restored K=%.9g m/pulse from checkpoint (t=%.3f s)", e.k_m_per_pulse,
                      r.checkpoint->last_sample_t_s);
      else
        std::snprintf(buf, sizeof buf, "restored estimator (no K yet) from checkpoint (t=%.3f s)",
                      r.checkpoint->last_sample_t_s);
      return buf;
    }
    case CheckpointLoadStatus::kMovedAside:
      return "checkpoint " + r.path + " was corrupt (" + r.reason + "): moved aside" +
             (r.moved_to.empty() ? std::string(" FAILED") : " to " + r.moved_to) + "; starting from nominal K";
  }
  return {};
}

}  // namespace odonav
