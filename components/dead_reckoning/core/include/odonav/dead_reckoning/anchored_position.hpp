#pragma once
// GNSS-anchored navigation position (docs/ALGORITHM.md, "Anchored navigation position"),
// middleware-free.
//
// The pure dead reckoning (DeadReckoner) starts at the first fix and never looks at GNSS again: its
// error grows with the distance driven (K and misalignment errors) and after a long drive it is
// metres off although GNSS was valid all along. The anchored position is the DR track plus an
// offset o (local ENU of the DR origin, m) that a small linear Kalman filter keeps on the fixes.
// Its state (8):
//
//   o = (o_e, o_n, o_u)  offset, anchored(t) = DR(t) + o                           [m]
//   s                    residual scale error of the DR increments (K error)        [-]
//   psi                  residual heading error of the DR increments (misalignment,
//                        INS heading), counter-clockwise seen from above           [rad]
//   b = (b_e, b_n, b_u)  the correlated part of the GNSS position error            [m]
//
//   process, per DR step with increment d = DR(t) - DR(t - dt):
//     o_e += s d_e - psi d_n,  o_n += s d_n + psi d_e,  o_u += s d_u  (the DR's own errors, so that
//       with s and psi known the DR increments are right even when K is off by 0.3 %)
//     o  random walk in distance, per axis q_o |dd| (what the two states do not model)
//     s  random walk in distance (K changes, surface), psi random walk in time (gyro drift)
//     b  first-order Gauss-Markov, correlation time fix_correlation_time_s, stationary sigma
//        sqrt(fix_correlated_fraction) x the fix sigma
//   measurement: z = fix(g) - DR(g - latency) = o(g) + b + white noise, the DR error when the fix
//     measured (AnchorFix::dr_enu_m: the DeadReckoner takes the GNSS latency in force into account);
//     o(g) = o(t) - (s, psi) acting on DR(t) - DR(g - latency), so a fix applied at a later step t
//     is exact (no approximation for the hold-off)
//   gate: a fix whose horizontal innovation exceeds gate_sigma x its predicted sigma is rejected
//     and counted (a multipath jump must not pull the position away)
//
// Why the bias state: GNSS errors are correlated over tens of seconds, so n fixes within that time
// are not n independent measurements; modelling the correlation keeps the covariance the size of
// the real error at any GNSS rate. Why s and psi: to average the fixes over several correlation
// times the DR increments must stay right over kilometres; the fixes observe both while the
// vehicle moves. By default they start at 0 +- 0 and only follow slow changes (free to learn, they
// chased the turn slip and K re-identifications on sim:terrain and cost accuracy); a DR on a
// nominal K gives them a prior.
//
// Through a GNSS outage the state is propagated by the DR increments alone: the position continues
// as DR from the last corrected state (corrected for the estimated scale and heading errors), and
// the covariance grows with the distance driven.
//
// Event time: a fix of epoch g is applied to the first DR step stamped at or after
// estimate_applies_from_s(g, hold_off_s) (the DR's --estimate-hold-off-s), whatever the order in
// which fixes and steps reached the program, so the output of step t never waits for a later GNSS
// and a replay at any speed gives the same numbers. Contract: every fix of epoch <= t - hold_off_s
// has been added before step(t).
#include <cmath>
#include <cstdint>
#include <deque>
#include <limits>
#include <optional>
#include <string>

#include <Eigen/Dense>

#include "odonav/consumer_rules.hpp"
#include "odonav/geodesy.hpp"
#include "odonav/results/output_files.hpp"
#include "odonav/state_json.hpp"

namespace odonav::dead_reckoning {

struct DeadReckoningOutput;

struct AnchoredPositionParams {
  /// A fix of epoch g applies from odometer time estimate_applies_from_s(g, hold_off_s) on (s,
  /// >= 0): the DR's --estimate-hold-off-s, which the DR itself waits for before it reports the fix.
  double hold_off_s = kDefaultEstimateHoldOff_s;
  /// One-sigma of the offset's own random walk per axis, % of distance, reached at
  /// correlation_distance_m: what the scale and heading states do not model (slip in turns, a
  /// 2-D DR on slopes). q_o = (p/100)^2 L [m^2/m].
  double drift_percent_distance = 0.15;
  /// Distance over which that error grows before it decorrelates (m, > 0).
  double correlation_distance_m = 400.0;
  /// Prior one-sigma of the scale error of the DR increments at the first fix (%, >= 0). 0 by
  /// default: the identified K is taken as right and the state only follows slow residual errors
  /// (measured on sim:terrain, a prior of 0.3-1 % lets the state chase the turn slip and the K
  /// re-identifications and costs 0.05-0.5 m RMS; docs/DESIGN_DECISIONS.md). Give the K's uncertainty
  /// when the DR runs on a nominal K.
  double scale_sigma_percent = 0.0;
  /// Random walk of the scale error (% per sqrt(km), >= 0).
  double scale_random_walk_percent_per_sqrt_km = 0.02;
  /// Prior one-sigma of the heading error of the DR increments (deg, >= 0); 0 by default as the
  /// scale's: the calibrated misalignment is taken as right.
  double heading_sigma_deg = 0.0;
  /// Random walk of the heading error (deg per sqrt(s), >= 0): gyro drift, misalignment updates.
  double heading_random_walk_deg_per_sqrt_s = 0.0002;
  /// Correlation time of the GNSS position error (s, > 0): multipath and atmosphere make
  /// consecutive fixes err alike for tens of seconds. The correlated part is a Gauss-Markov state.
  double fix_correlation_time_s = 60.0;
  /// Share of a fix's variance that is correlated (in [0, 1)): the rest is white. A single-frequency
  /// receiver's is mostly correlated (the simulator's: 1.4 m of 1.5 m, 0.87).
  double fix_correlated_fraction = 0.87;
  /// Per-axis horizontal one-sigma of a fix without pos_std_m (m, > 0).
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
  double t_s = 0.0;                                           ///< GNSS epoch (s).
  Eigen::Vector3d fix_enu_m = Eigen::Vector3d::Zero();        ///< reference point from the fix (local ENU, m).
  Eigen::Vector3d dr_enu_m = Eigen::Vector3d::Zero();         ///< DR position at t_s (local ENU, m).
  double dr_distance_m = 0.0;                                 ///< DR distance driven at t_s (m).
  double sigma_m = std::numeric_limits<double>::quiet_NaN();  ///< horizontal one-sigma (m); NaN = unknown.
};

/// One DR step: the DR output at an odometer sample.
struct AnchorDrStep {
  double t_s = 0.0;
  Geodetic position;                                ///< DR position, WGS-84 (rad, rad, m).
  Eigen::Vector3d enu_m = Eigen::Vector3d::Zero();  ///< DR position, local ENU of the DR origin (m).
  double distance_m = 0.0;                          ///< DR distance driven since its start (m).
  /// Rotation taking vectors of the DR origin's ENU frame into the ENU frame at `position`
  /// (DeadReckoningOutput::origin_to_local); the identity when the two frames coincide.
  Eigen::Matrix3d origin_to_local = Eigen::Matrix3d::Identity();
};

enum class AnchorStatus {
  kNotStarted,     ///< no fix applied yet: the position is the pure DR, the covariance unknown.
  kAnchored,       ///< a fix applied within anchored_max_age_s.
  kDeadReckoning,  ///< bridging: DR from the last applied fix.
};
const char* to_string(AnchorStatus status);

struct AnchoredPosition {
  double t_s = 0.0;
  Geodetic position;                                ///< WGS-84 (rad, rad, m).
  Eigen::Vector3d enu_m = Eigen::Vector3d::Zero();  ///< local ENU of the DR origin (m).
  /// Position covariance (m^2) in the ENU frame at `position` (the filter's, in the origin's frame,
  /// turned with AnchorDrStep::origin_to_local); NaN while kNotStarted.
  Eigen::Matrix3d covariance_enu_m2 = Eigen::Matrix3d::Constant(std::numeric_limits<double>::quiet_NaN());
  AnchorStatus status = AnchorStatus::kNotStarted;
  double last_fix_t_s = std::numeric_limits<double>::quiet_NaN();          ///< epoch of the last applied fix.
  double distance_since_fix_m = std::numeric_limits<double>::quiet_NaN();  ///< DR distance since it (m).
  /// Estimated residual scale error of the DR increments (-) and heading error (rad, counter-clockwise
  /// from above); NaN while kNotStarted.
  double scale_error = std::numeric_limits<double>::quiet_NaN();
  double heading_error_rad = std::numeric_limits<double>::quiet_NaN();
  /// Horizontal one-sigma, sqrt(var_e + var_n) (m); NaN while kNotStarted.
  double horizontal_sigma_m() const { return std::sqrt(covariance_enu_m2(0, 0) + covariance_enu_m2(1, 1)); }
};

/// The navigation_position.csv row of a position (odonav/results/output_files.hpp): what
/// odonav-offline writes, and what the dead-reckoning node publishes through the topic's field table
/// (odonav/dds/output_messages.hpp).
results::NavigationPositionRow output_row(const AnchoredPosition& position);

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

  /// The complete state (checkpoint_state.hpp, every double exact): queued fixes, the filter's
  /// state and covariance, the last step, the gate and the counters (DeadReckoner::save_state's
  /// rule).
  StateJson save_state() const;
  /// Restores save_state()'s state into a filter made with the same parameters. Throws
  /// CheckpointError naming the field; the filter is unchanged then.
  void restore_state(const StateJson& state);

  const AnchoredPositionCounters& counters() const { return counters_; }
  /// Odometer time from which a fix of epoch epoch_s applies: estimate_applies_from_s(epoch_s,
  /// hold_off_s).
  double applies_from_s(double epoch_s) const;
  const AnchoredPositionParams& params() const { return params_; }

 private:
  static constexpr int kN = 8;  ///< o_e, o_n, o_u, s, psi, b_e, b_n, b_u
  using Vector = Eigen::Matrix<double, kN, 1>;
  using Matrix = Eigen::Matrix<double, kN, kN>;
  void apply(const AnchorFix& fix, const AnchorDrStep& now);
  void start(const Eigen::Vector3d& z, double sigma_h_m);
  void propagate(const Eigen::Vector3d& d_m, double dd_m, double dt_s);
  // The filter's checkpoint fields, listed once for save_state() and restore_state().
  friend struct odonav::StateAccess;  // save_fields() and restored_copy() reach state_fields
  template <class Archive, class Self>
  static void state_fields(Archive& a, Self& self);

  AnchoredPositionParams params_;
  double q_offset_m2_per_m_ = 0.0, q_scale_per_m_ = 0.0, q_heading_rad2_per_s_ = 0.0;
  std::deque<AnchorFix> queued_;
  std::optional<double> last_added_t_s_;
  std::optional<double> last_step_t_s_;
  Eigen::Vector3d last_enu_m_ = Eigen::Vector3d::Zero();
  bool initialised_ = false;
  Vector x_ = Vector::Zero();
  Matrix p_ = Matrix::Zero();
  double correlated_sigma_h_m_ = 0.0;  ///< stationary sigma of b per horizontal axis, from the last fix
  double last_distance_m_ = 0.0;
  double last_fix_t_s_ = std::numeric_limits<double>::quiet_NaN();
  double last_fix_distance_m_ = 0.0;
  int consecutive_gated_ = 0;
  AnchoredPositionCounters counters_;
};

}  // namespace odonav::dead_reckoning
