#include "odonav/identification/checkpoint.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

#include "odonav/printf_text.hpp"

namespace odonav::identification {

ODONAV_STATE_FIELDS(IdentificationCheckpoint) {
  a("estimator", s.estimator_name)("last_sample_t_s", s.last_sample_t_s)("samples_accepted", s.samples_accepted)(
      "samples_rejected", s.samples_rejected)("fed_until_s", s.fed_until_s)(
      "misalignments_applied", s.misalignments_applied)("held_misalignment_t_s", s.held_misalignment_t_s)("core",
                                                                                                          s.core_state);
  a.check("estimator", !s.estimator_name.empty(), "is empty");
  a.check("last_sample_t_s", std::isfinite(s.last_sample_t_s), "is not finite");
}

namespace {
constexpr CheckpointKind kKind{kIdentificationCheckpointComponent, kIdentificationCheckpointVersion};
}  // namespace

std::string checkpoint_path(const std::string& state_dir, const std::string& vehicle_id) {
  return kKind.path(state_dir, vehicle_id);
}

std::string serialize_checkpoint(const IdentificationCheckpoint& c) {
  if (c.estimator_name.empty()) throw std::invalid_argument("checkpoint: estimator name is empty");
  if (!std::isfinite(c.last_sample_t_s)) throw std::invalid_argument("checkpoint: last_sample_t_s is not finite");
  return kKind.seal(c);
}

IdentificationCheckpoint parse_checkpoint(const std::string& text) {
  return kKind.parse<IdentificationCheckpoint>(text);
}

CheckpointLoadResult load_identification_checkpoint(const std::string& path, const std::string& vehicle_id,
                                                    const std::string& config_hash, IdentificationCore& core,
                                                    int64_t unix_time_s) {
  const CheckpointIdentity expected = kKind.identity(vehicle_id, config_hash);
  std::optional<IdentificationCheckpoint> restored;
  const CheckpointFileLoad load = load_checkpoint_file(path, unix_time_s, expected, [&](const StateJson& payload) {
    IdentificationCheckpoint c = checkpoint_from_payload<IdentificationCheckpoint>(expected, payload);
    if (c.estimator_name != core.main_estimator_name())
      throw CheckpointError("made by estimator '" + c.estimator_name + "', this is '" + core.main_estimator_name() +
                            "'");
    restore_or_refuse("identification", core, c.core_state);  // unchanged when it throws
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
      if (e.valid)
        return printf_text("restored K=%.9g m/pulse from checkpoint (t=%.3f s)", e.k_m_per_pulse,
                           r.checkpoint->last_sample_t_s);
      return printf_text("restored estimator (no K yet) from checkpoint (t=%.3f s)", r.checkpoint->last_sample_t_s);
    }
    case CheckpointLoadStatus::kMovedAside:
      return "checkpoint " + r.path + " was corrupt (" + r.reason + "): moved aside" +
             (r.moved_to.empty() ? std::string(" FAILED") : " to " + r.moved_to) + "; starting from nominal K";
  }
  return {};
}

}  // namespace odonav::identification
