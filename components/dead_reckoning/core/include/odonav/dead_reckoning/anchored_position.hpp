#pragma once
// GNSS-anchored navigation position (docs/ALGORITHM.md, "Anchored navigation position"),
// middleware-free.
//
// The pure dead reckoning (DeadReckoner) starts at the first fix and never looks at GNSS again: its
// error grows with the distance driven (K and misalignment errors) and after a long drive it is
// metres off although GNSS was valid all along. The anchored position is the DR track plus an
// offset x (local ENU of the DR origin, m) that a small Kalman filter keeps on the GNSS fixes:
//
//   anchored(t) = DR(t) + x
//   process:     x is a random walk in distance: per axis, var += q dd with
//                q = (drift_percent_distance / 100)^2 * correlation_distance_m  [m^2/m],
//                dd = odometer distance of the step (so standing still adds nothing)
//   measurement: z = fix(g) - DR(g), the DR error seen at the fix epoch g (reference point, after the
//                lever arm), noise per horizontal axis c sigma_fix^2 (GNSS pos_std_m), vertical
//                c (vertical_sigma_factor * sigma_fix)^2, c = max(1, fix_correlation_time_s / time
//                since the previous fix): GNSS errors are correlated over tens of seconds
//   gate:        a fix whose horizontal innovation exceeds gate_sigma x its predicted sigma is
//                rejected and counted (a multipath jump must not pull the position away)
//
// Because z is the DR error at the fix's own epoch, applying it a little later is exact up to the
// DR error growth over that delay (millimetres over 0.2 s). Through a GNSS outage x stays at the
// last corrected value: the position continues as DR from the last good fix, and the covariance
// grows with the distance driven.
//
// Event time: a fix of epoch g is applied to the first DR step stamped at or after g + hold_off_s,
// whatever the order in which fixes and steps reached the program, so the output of step t never
// waits for a later GNSS and a replay at any speed gives the same numbers. Contract: every fix of
// epoch <= t - hold_off_s has been added before step(t).
#include <cmath>
#include <cstdint>
#include <deque>
#include <limits>
#include <optional>

#include <Eigen/Dense>

#include "odonav/geodesy.hpp"

namespace odonav {

struct DeadReckoningOutput;

/// Delay between a GNSS epoch and the first odometer sample its fix is applied to (s): covers the
/// normal arrival delay of a fix after its epoch so that the position never waits for it.
inline constexpr double kDefaultAnchorHoldOff_s = 0.2;
/// A fix applies from epoch + hold-off - this (s) when the hold-off is > 0 (see applies_from_s).
inline constexpr double kAnchorApplicationGuard_s = 1e-6;

struct AnchoredPositionParams {
  /// A fix of epoch g applies from odometer time g + hold_off_s on (s, >= 0; 1 us earlier when > 0,
  /// see AnchoredPositionFilter::applies_from_s).
  double hold_off_s = kDefaultAnchorHoldOff_s;
  /// One-sigma DR error growth per axis, % of distance: an identified K to ~0.1 % and a calibrated
  /// heading misalignment to ~0.05 deg (0.09 % cross-track) give about 0.13 %D; 0.2 leaves margin for
  /// the INS heading error. With correlation_distance_m it sets the process noise q.
  double drift_percent_distance = 0.2;
  /// Distance over which that error grows before it decorrelates (m, > 0): K changes (track wear,
  /// surface) are re-identified within a few hundred metres. q = (p/100)^2 L makes the one-sigma of
  /// a random walk reach p %D at L.
  double correlation_distance_m = 400.0;
  /// Correlation time of the GNSS position error (s, >= 0): multipath and atmosphere make
  /// consecutive fixes err alike for tens of seconds, so n fixes within it are not n independent
  /// measurements. Each fix's variance is multiplied by max(1, this / time since the previous fix),
  /// which gives the same information per second at any GNSS rate and keeps the covariance from
  /// shrinking as if the errors were white. 0 = white fixes.
  double fix_correlation_time_s = 60.0;
  /// Horizontal one-sigma of a fix without pos_std_m (m, > 0).
  double default_fix_sigma_m = 2.0;
  /// Smallest fix sigma used (m, > 0): an RTK receiver claiming 1 mm must not freeze the filter.
  double min_fix_sigma_m = 0.02;
  /// Vertical fix sigma = this x horizontal (> 0): GNSS height is 1.5-2 x worse than horizontal.
  double vertical_sigma_factor = 1.5;
  /// Innovation gate on the horizontal innovation, in predicted sigmas (> 0).
  double gate_sigma = 6.0;
  /// After this many consecutive gated fixes (>= 1) the filter restarts on the next fix: the DR,
  /// not the GNSS, has left the gate (a precise receiver, a DR drifting faster than modelled), and
  /// a gate that never reopens would leave the position unanchored for good. Counted.
  int gate_restart_after = 5;
  /// Status ANCHORED while the last applied fix's epoch is at most this old (s, > 0); after it,
  /// DEAD_RECKONING. 2.5 s covers a 1 Hz receiver with one epoch missing.
  double anchored_max_age_s = 2.5;
};

/// A GNSS fix seen in the DR's frame: what DeadReckoner reports for each valid epoch it passes.
struct AnchorFix {
  double t_s = 0.0;                                      ///< GNSS epoch (s).
  Eigen::Vector3d fix_enu_m = Eigen::Vector3d::Zero();   ///< reference point from the fix (local ENU, m).
  Eigen::Vector3d dr_enu_m = Eigen::Vector3d::Zero();    ///< DR position at t_s (local ENU, m).
  double dr_distance_m = 0.0;                            ///< DR distance driven at t_s (m).
  double sigma_m = std::numeric_limits<double>::quiet_NaN();  ///< horizontal one-sigma (m); NaN = unknown.
};

/// One DR step: the DR output at an odometer sample.
struct AnchorDrStep {
  double t_s = 0.0;
  Geodetic position;                                 ///< DR position, WGS-84 (rad, rad, m).
  Eigen::Vector3d enu_m = Eigen::Vector3d::Zero();   ///< DR position, local ENU of the DR origin (m).
  double distance_m = 0.0;                           ///< DR distance driven since its start (m).
};

enum class AnchorStatus {
  kNotStarted,     ///< no fix applied yet: the position is the pure DR, the covariance unknown.
  kAnchored,       ///< a fix applied within anchored_max_age_s.
  kDeadReckoning,  ///< bridging: DR from the last applied fix.
};
const char* to_string(AnchorStatus status);

struct AnchoredPosition {
  double t_s = 0.0;
  Geodetic position;                                 ///< WGS-84 (rad, rad, m).
  Eigen::Vector3d enu_m = Eigen::Vector3d::Zero();   ///< local ENU of the DR origin (m).
  /// Position covariance in ENU (m^2), diagonal; NaN while kNotStarted.
  Eigen::Matrix3d covariance_enu_m2 = Eigen::Matrix3d::Constant(std::numeric_limits<double>::quiet_NaN());
  AnchorStatus status = AnchorStatus::kNotStarted;
  double last_fix_t_s = std::numeric_limits<double>::quiet_NaN();  ///< epoch of the last applied fix.
  double distance_since_fix_m = std::numeric_limits<double>::quiet_NaN();  ///< DR distance since it (m).
  /// Horizontal one-sigma, sqrt(var_e + var_n) (m); NaN while kNotStarted.
  double horizontal_sigma_m() const { return std::sqrt(covariance_enu_m2(0, 0) + covariance_enu_m2(1, 1)); }
};

struct AnchoredPositionCounters {
  uint64_t steps = 0;
  uint64_t fixes_added = 0;
  uint64_t fixes_applied = 0;
  uint64_t fixes_rejected_gate = 0;  ///< innovation above gate_sigma.
  uint64_t gate_restarts = 0;        ///< restarts on a fix after gate_restart_after gated ones.
  double last_rejected_innovation_m = std::numeric_limits<double>::quiet_NaN();
  double last_rejected_gate_m = std::numeric_limits<double>::quiet_NaN();
};

class AnchoredPositionFilter {
 public:
  /// Throws std::invalid_argument naming the parameter when params are out of range.
  explicit AnchoredPositionFilter(const AnchoredPositionParams& params = {});

  /// Queues a fix (epochs strictly increasing, values finite: else StreamInputError).
  void add_fix(const AnchorFix& fix);
  /// The position at a DR step (steps strictly increasing in time): applies every queued fix whose
  /// epoch + hold_off_s <= step.t_s, in epoch order, then reports.
  AnchoredPosition step(const AnchorDrStep& step);
  /// The same for a DeadReckoner output, whose gnss_fixes are added first.
  AnchoredPosition step(const DeadReckoningOutput& dr);

  const AnchoredPositionCounters& counters() const { return counters_; }
  /// Odometer time from which a fix of epoch epoch_s applies: epoch + hold_off_s - 1 us (hold-off
  /// > 0), else the epoch itself.
  double applies_from_s(double epoch_s) const;
  const AnchoredPositionParams& params() const { return params_; }

 private:
  void apply(const AnchorFix& fix);

  AnchoredPositionParams params_;
  double q_m2_per_m_ = 0.0;
  std::deque<AnchorFix> queued_;
  std::optional<double> last_added_t_s_;
  std::optional<double> last_step_t_s_;
  bool initialised_ = false;
  Eigen::Vector3d offset_m_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d variance_m2_ = Eigen::Vector3d::Zero();
  double last_distance_m_ = 0.0;
  double last_fix_t_s_ = std::numeric_limits<double>::quiet_NaN();
  double last_fix_distance_m_ = 0.0;
  std::optional<double> previous_fix_t_s_;
  int consecutive_gated_ = 0;  ///< epoch of the previous fix taken (applied or gated)
  AnchoredPositionCounters counters_;
};

}  // namespace odonav
