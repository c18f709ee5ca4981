#pragma once
// The restart policy of odonav-dead-reckoning, middleware-free: the shared RestartPolicy
// (odonav/restart_policy.hpp: skipped samples, catch-up, checkpoint period, health notes) with the
// dead reckoning's inputs, around its checkpoint file (dead_reckoning_checkpoint.hpp).
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "odonav/dead_reckoning/dead_reckoning_checkpoint.hpp"
#include "odonav/restart_policy.hpp"

namespace odonav::dead_reckoning {

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

}  // namespace odonav::dead_reckoning
