#include "odonav/identification/checkpoint.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>

namespace odonav {

namespace {

constexpr const char* kMagic = "odonav-identification-checkpoint";
constexpr int kVersion = 1;

bool has_line_break(const std::string& s) { return s.find_first_of("\r\n") != std::string::npos; }

}  // namespace

std::string checkpoint_path(const std::string& state_dir, const std::string& vehicle_id) {
  check_checkpoint_vehicle_id(vehicle_id);
  return (std::filesystem::path(state_dir) / ("identification-" + vehicle_id + ".ckpt")).string();
}

std::string serialize_checkpoint(const IdentificationCheckpoint& c) {
  if (c.vehicle_id.empty() || has_line_break(c.vehicle_id))
    throw std::invalid_argument("checkpoint: vehicle id is empty or holds a line break");
  if (c.estimator_name.empty() || has_line_break(c.estimator_name))
    throw std::invalid_argument("checkpoint: estimator name is empty or holds a line break");
  if (c.config_hash.empty() || has_line_break(c.config_hash))
    throw std::invalid_argument("checkpoint: config hash is empty or holds a line break");
  if (!std::isfinite(c.last_sample_t_s)) throw std::invalid_argument("checkpoint: last_sample_t_s is not finite");
  char t[40];
  std::snprintf(t, sizeof t, "%.17g", c.last_sample_t_s);
  std::ostringstream s;
  s << kMagic << ' ' << kVersion << '\n'
    << "vehicle " << c.vehicle_id << '\n'
    << "config_hash " << c.config_hash << '\n'
    << "estimator " << c.estimator_name << '\n'
    << "last_sample_t_s " << t << '\n'
    << "samples_accepted " << c.samples_accepted << '\n'
    << "samples_rejected " << c.samples_rejected << '\n'
    << "state_chars " << c.estimator_state.size() << '\n'
    << c.estimator_state << '\n';
  return seal_checkpoint(s.str());
}

IdentificationCheckpoint parse_checkpoint(const std::string& text) {
  const std::string body = unseal_checkpoint(text);
  CheckpointReader r(body);
  check_checkpoint_version(r, kMagic, kVersion);
  IdentificationCheckpoint c;
  c.vehicle_id = r.field("vehicle");
  c.config_hash = r.field("config_hash");
  c.estimator_name = r.field("estimator");
  c.last_sample_t_s = r.double_field("last_sample_t_s");
  c.samples_accepted = r.unsigned_field("samples_accepted");
  c.samples_rejected = r.unsigned_field("samples_rejected");
  const uint64_t n = r.unsigned_field("state_chars");
  c.estimator_state = r.block(static_cast<std::size_t>(n), "estimator state");
  if (r.position() != body.size()) throw CheckpointError("unexpected text after the estimator state");
  if (c.vehicle_id.empty() || c.estimator_name.empty() || c.config_hash.empty())
    throw CheckpointError("empty vehicle, estimator or config hash");
  return c;
}

CheckpointLoadResult load_identification_checkpoint(const std::string& path, const std::string& vehicle_id,
                                                    const std::string& config_hash, ScaleFactorEstimator& estimator,
                                                    int64_t unix_time_s) {
  std::optional<IdentificationCheckpoint> restored;
  const CheckpointFileLoad load = load_checkpoint_file(path, unix_time_s, [&](const std::string& text) {
    IdentificationCheckpoint c = parse_checkpoint(text);
    check_checkpoint_identity(c.vehicle_id, c.config_hash, vehicle_id, config_hash);
    if (c.estimator_name != estimator.name())
      throw CheckpointError("made by estimator '" + c.estimator_name + "', this is '" + estimator.name() + "'");
    try {
      estimator.restore_state(c.estimator_state);  // unchanged when it throws
    } catch (const std::exception& e) {
      throw CheckpointError(std::string("estimator state refused: ") + e.what());
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
    case CheckpointLoadStatus::kNone:
      return "no checkpoint " + r.path + ": starting from nominal K";
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
