#pragma once
// Braking to a standstill (docs/ALGORITHM.md §2 "Braking to a standstill"): the estimates a drive
// ends with must not be the braking's. Every timing error between GNSS and odometer (a latency not
// decided yet, a receiver's velocity filter) puts tau times the speed change into a sample, the same
// sign through the whole braking, and near a stop nothing comes after those samples to balance
// them: a windowed estimator then holds the braking alone. So the identification and the
// calibration keep their state as it was when the speed started to fall, and go back to it when the
// braking ends in a standstill; a braking that ends in driving (a turn, a slower road) keeps its
// samples.
//
// Both components classify each GNSS epoch by its forward speed (m/s, GNSS) against the speed of an
// epoch at least baseline_s earlier, so the decision depends on stamps only and needs nothing after
// the epoch.
#include <cstdint>
#include <deque>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace odonav {

struct BrakingStopParams {
  /// Withdraw the samples of a braking that ends in a standstill. Default on.
  bool enabled = true;
  /// Braking: the speed fell by more than this (m/s^2, > 0) on average since the epoch baseline_s
  /// earlier. Default 0.3: 4 sigma of a 0.05 m/s GNSS velocity noise over 1 s, and well below the
  /// 1-1.5 m/s^2 of a vehicle braking; the slow wander of a cruise stays under 0.1.
  double braking_mps2 = 0.3;
  /// Baseline of the deceleration (s, > 0). Default 1: over 0.1 s (one 10 Hz interval) the velocity
  /// noise alone is 0.7 m/s^2.
  double baseline_s = 1.0;
  /// Standstill: |speed| below this (m/s, > 0). Default 0.3: 6 sigma of a 0.05 m/s GNSS velocity
  /// noise, and below the identification's minimum sample speed (0.5 m/s), so no sample ends at
  /// a standstill epoch.
  double standstill_speed_mps = 0.3;
  /// A reference epoch older than this (s) is no reference (an outage): the phase is unknown.
  /// Default 3.
  double max_reference_age_s = 3.0;
};

enum class MotionPhase {
  kUnknown,     ///< no speed at the epoch, or no reference epoch in the baseline.
  kDriving,     ///< moving, speed not falling faster than braking_mps2.
  kBraking,     ///< moving, speed falling faster than braking_mps2.
  kStandstill,  ///< |speed| below standstill_speed_mps.
};
const char* to_string(MotionPhase phase);

/// The phase of an epoch with forward speed speed_now_mps, given the speed speed_before_mps of an
/// epoch dt_s earlier (s): standstill by the speed alone, else braking when |speed| fell faster than
/// braking_mps2. Pure function; unknown when a speed is not finite or dt_s is not > 0 (standstill
/// still wins when the speed now is known).
MotionPhase classify_motion(double speed_before_mps, double speed_now_mps, double dt_s,
                            const BrakingStopParams& params);

/// Throws std::invalid_argument naming the field when a parameter is out of range.
void validate(const BrakingStopParams& params);

/// What a component does with its braking snapshot (its estimates as they were when the current
/// braking began) at an epoch: the one rule both the identification and the calibration follow.
enum class BrakingStopStep {
  kKeep,      ///< nothing changes: the phase is unknown, or the braking goes on with its snapshot taken.
  kDrop,      ///< drop the snapshot, if any: the vehicle drives on, a braking that used no sample
              ///< ended in a standstill, or the rule is off or the estimates frozen.
  kSnapshot,  ///< a braking began: keep the estimates as they are now, count the samples used from now on.
  kRollBack,  ///< a braking with used samples ended in a standstill: go back to the snapshot, drop it.
};

/// The step for an epoch of phase `phase` (call it before the epoch's sample is used). active:
/// the rule is on and the estimates are not frozen. used_since: the samples used since the
/// snapshot was taken (count), nullopt without a snapshot.
BrakingStopStep braking_stop_step(MotionPhase phase, bool active, std::optional<uint64_t> used_since);

/// braking_stop_step applied to a component's braking snapshot (nullopt: none), for an epoch of
/// phase `phase` (call it before the epoch's sample is used; active as for braking_stop_step).
/// Snapshot has a member `used_since`: the samples used since it was taken (the component counts
/// them). take() gives the snapshot to keep when a braking begins (nullopt: none yet);
/// restore(snapshot) puts the component's estimates back. Returns the samples a rollback withdrew
/// (> 0), 0 when nothing was rolled back.
template <class Snapshot, class Take, class Restore>
uint64_t apply_braking_stop(std::optional<Snapshot>& snapshot, MotionPhase phase, bool active, Take take,
                            Restore restore) {
  const std::optional<uint64_t> used_since = snapshot ? std::optional<uint64_t>(snapshot->used_since) : std::nullopt;
  switch (braking_stop_step(phase, active, used_since)) {
    case BrakingStopStep::kKeep: return 0;
    case BrakingStopStep::kDrop: snapshot.reset(); return 0;
    case BrakingStopStep::kSnapshot: snapshot = take(); return 0;
    case BrakingStopStep::kRollBack: {
      restore(*snapshot);
      const uint64_t withdrawn = snapshot->used_since;
      snapshot.reset();
      return withdrawn;
    }
  }
  return 0;
}

/// The phase of each epoch in turn (classify_motion against the latest epoch at least baseline_s
/// earlier). Memory: the epochs of the last max_reference_age_s.
class MotionPhaseTracker {
 public:
  explicit MotionPhaseTracker(const BrakingStopParams& params = {});
  /// The epoch at t_s (increasing) with forward speed speed_mps (NaN: no speed, unknown; kept out of
  /// the references).
  MotionPhase add(double t_s, double speed_mps);
  /// The epochs kept, as (t, speed) pairs flattened, for a checkpoint; restore() takes them back.
  std::vector<double> state() const;
  /// Throws std::invalid_argument when the list is not pairs in increasing time with finite values.
  void restore(const std::vector<double>& state);

 private:
  BrakingStopParams params_;
  std::deque<std::pair<double, double>> epochs_;  ///< (t_s, speed_mps), increasing t
};

}  // namespace odonav
