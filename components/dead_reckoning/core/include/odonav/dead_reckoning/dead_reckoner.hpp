#pragma once
// SINS/odometer dead reckoning (docs/ALGORITHM.md §4), middleware-free.
//
// Per odometer interval [t_{j-1}, t_j] (units: s, m, pulses, rad):
//   dS_m = (K dN dir, 0, 0)                  odometer frame; dN = count increment, modulo 2^32
//   dS_b = C_m^b dS_m                         misalignment in force at t_j (exact rotation)
//   dS_n = C_b^n(attitude at (t_{j-1} + t_j) / 2) dS_b          (3-D mode)
//   dS_n = |dS| dir (sin psi_odo, cos psi_odo, 0),  psi_odo = heading - a_h   (2-D mode: pitch and
//          height ignored, so the whole odometer distance is laid on the horizontal; on a slope of
//          angle p the 2-D track is longer than the true horizontal track by 1/cos p, and the height
//          stays at the start height, while the 3-D mode follows the slope)
//   position = move_geodetic(position, dS_n)  (WGS-84; in ECEF near the poles: valid everywhere)
//   In the polar cap (|lat| >= kPolarCapLatRad) dS_n is laid out from north at the DR position
//   corrected by the DR's error at the latest GNSS epoch evaluated (the INS heading is relative to
//   north at the vehicle's true position; near a pole north turns by 1 rad per ρ metres across the
//   meridian, so a DR whose own position error chose north would turn its track by error / ρ and
//   carry that angle away from the pole: docs/ALGORITHM.md §4c).
// K in force at t_j: the latest add_scale_factor() stamped <= t_j, else params.nominal_k.
// Start: the first valid GNSS fix (fix not 0/6) at which the odometer count can be interpolated;
// the antenna position is moved to the INS reference point when a lever arm is configured (INS
// attitude at the fix; without INS the GNSS course with pitch = roll = 0 if moving, else unmoved).
// Without INS (params.use_ins = false, degraded mode): horizontal only, along the GNSS course
// atan2(ve, vn) interpolated to mid-interval while GNSS is valid and moving, held otherwise; the
// course is the direction of motion already, so |dS| is laid along it whatever the direction flag.
// A held course remembers the odometer direction it was measured with: when the vehicle changes
// direction below the course's minimum speed (stop, then reverse at a crawl), |dS| is laid against
// the held course, so a straight reversing manoeuvre is dead-reckoned exactly.
//
// Error against GNSS, per GNSS epoch g (valid fix, after the start): |DR(g - L) - GNSS(g)| horizontal,
// L the GNSS latency in force at estimate_applies_from_s(g, hold-off) (add_gnss_latency; 0 until
// one is added: the fix stamped g describes the position at g - L), DR(g - L) interpolated linearly (local ENU of the DR origin) between the outputs bracketing g, the
// antenna moved to the reference point by the lever arm (ENU) interpolated alike. It is
// evaluated at the first odometer sample t_j >= estimate_applies_from_s(g, hold-off) (the rule of
// consumer_rules.hpp: by then the fix of epoch g has arrived) and carried, with error_t_s = g, on
// the outputs until the next epoch is evaluated, at most the GNSS gap in force after g (the one the
// reference interpolation bridged: 0.5 s at 10 Hz, 2.5 s at 1 Hz) past its evaluation. So the error never holds
// a position back: an output waits for no GNSS later than its own time minus the hold-off.
//
// GNSS fixes for the anchored position (anchored_position.hpp): the same evaluation gives, for each
// valid epoch g, an AnchorFix (the reference point from the fix, the DR position and distance at g),
// carried by the output at which g is evaluated (the first output also the start fix). An epoch
// without the lever arm at g (attitude missing while a lever arm is configured) is left out of both
// and counted.
//
// Event time: as sample_builder.hpp, with the hold-off: the contract of process_until(w) is "every
// odometer and INS sample stamped <= w, and every GNSS fix, K and misalignment whose
// estimate_applies_from_s(stamp, hold-off) <= w, has been added" (K and misalignment are added by
// the caller stamped with their application time already). Before the start (and in the degraded
// mode, which steers by the GNSS course) the GNSS around t_j itself is needed: the output waits for
// it. One output per odometer sample after the start, emitted once its attitude and inputs are
// complete up to the watermark.
//
// Held estimates: an output at t_j used a held K (misalignment) when the latest GNSS epoch g the
// core knows with estimate_applies_from_s(g, hold-off) <= t_j has no estimate received yet
// (add_estimate_received; the estimators publish one per GNSS epoch) while an older epoch has: the estimator fell silent (stalled, restarting,
// dead) and the output went on with what was in force. Decided from the inputs added, in event time,
// so it never changes a number; counted, and reported as spans of consecutive outputs (HeldSpan).
// Never held: before any estimate of the kind was received (nothing to hold: nominal K, zero
// misalignment), a commanded K, and epochs the core does not know (GNSS itself silent).
#include <cmath>
#include <cstdint>
#include <deque>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Dense>

#include "odonav/defaults.hpp"
#include "odonav/dataset.hpp"
#include "odonav/dead_reckoning/anchored_position.hpp"
#include "odonav/frames.hpp"
#include "odonav/geodesy.hpp"
#include "odonav/results/output_files.hpp"
#include "odonav/stream_buffers.hpp"
#include "odonav/turn_slip.hpp"

namespace odonav::dead_reckoning {

/// Where the K in use comes from.
enum class ScaleFactorSource {
  kNominal,     ///< the configured nominal value (no other K received yet).
  kIdentified,  ///< identified online from GNSS.
  kCommanded,   ///< set by an operator command.
};
const char* to_string(ScaleFactorSource source);

enum class DeadReckoningMode { k3D, k2D };

struct DeadReckonerParams {
  /// K used before any add_scale_factor() (m/pulse, > 0).
  double nominal_k_m_per_pulse = kDefaultNominalK_m_per_pulse;
  /// One-sigma of the nominal K relative to it (>= 0; 0 = unknown): an identified K whose sigma is
  /// below it replaces the nominal (consumer_rules.hpp scale_factor_applicable).
  double nominal_k_rel_sigma = kDefaultNominalKRelSigma;
  DeadReckoningMode mode = DeadReckoningMode::k3D;
  /// False without INS: degraded mode (GNSS course, horizontal only).
  bool use_ins = true;
  /// GNSS antenna position in the body frame (forward-left-up, m) from the INS reference point;
  /// the DR tracks the reference point. Unset: the antenna is the reference point.
  std::optional<Eigen::Vector3d> lever_arm_body_m;
  /// Longest gap between odometer / INS samples across which they are interpolated (s). Default 1.
  double max_bracket_s = 1.0;
  /// Pulse-jump gate (stream_buffers.hpp, OdometerJumpGate): an odometer increment above
  /// max_speed_mps / nominal_k_m_per_pulse * dt + 2 pulses is a counter glitch, not distance: the
  /// sample is dropped and counted, so one bad count cannot move the position by kilometres.
  /// Fastest physically possible speed (m/s, > 0). Default 100 (8000 pulses/s at 0.0125 m/pulse).
  double max_speed_mps = 100.0;
  /// Longest gap between two GNSS epochs across which the reference (and, without INS, the GNSS
  /// course) is interpolated (s). 0 (default) = from the GNSS period P observed in the data, as the
  /// identification's interval gate: max(gnss_max_gap_floor_s, gnss_max_gap_periods * P), with P the
  /// median of the last gnss_period_window intervals between GNSS rows up to the earlier epoch of the
  /// pair (dead_reckoning_gnss_max_gap_s): 0.5 s at 10 Hz, 2.5 s at 1 Hz. A fixed 0.5 s left a 1 Hz
  /// vehicle without INS with no course at all (the slow robot's DR did not move: 86 %D).
  double gnss_max_gap_s = 0.0;
  /// Floor of the derived gap (s, > 0) and the gap before two GNSS rows were seen. Default 0.5.
  double gnss_max_gap_floor_s = 0.5;
  /// The derived gap in GNSS periods (> 0). Default 2.5: one missed fix is bridged, two are not.
  double gnss_max_gap_periods = 2.5;
  /// Intervals between GNSS rows the period is the median of (>= 1). Default 15.
  int gnss_period_window = 15;
  /// Degraded mode: the GNSS course is used only at horizontal speed >= this (m/s). 0 (default) =
  /// from the fixes' velocity accuracy (vel_std_mps, the larger of the two bracketing epochs):
  /// max(course_min_speed_floor_mps, course_min_speed_sigmas * vel_std), i.e. a course good to
  /// 1/20 rad (3 deg) or better; 1 m/s when the fixes carry no accuracy. An RTK receiver at
  /// 0.02 m/s gives 0.4 m/s (a robot reversing at 0.6 m/s keeps its course), the simulator's
  /// 0.05 m/s gives 1 m/s.
  double course_min_speed_mps = 0.0;
  double course_min_speed_floor_mps = 0.1;  ///< floor of the derived speed (m/s, > 0)
  double course_min_speed_sigmas = 20.0;    ///< the derived speed in velocity sigmas (> 0)
  /// %D is NaN while the distance travelled is below this (m). Default 1.
  double percent_min_distance_m = 1.0;
  /// Hold-off d (s, >= 0) of the estimate-application rule (consumer_rules.hpp). The node and
  /// odonav-offline add misalignment and K of epoch g as in force from g + d; the core itself
  /// evaluates the error against the GNSS fix of epoch g at the first odometer sample >= g + d.
  double estimate_hold_off_s = kDefaultEstimateHoldOff_s;
  /// Track slip in turns (turn_slip.hpp, add_turn_slip): the yaw rate of an odometer interval is
  /// the INS heading change over the window of this length (s, > 0) ending at its mid-interval, the
  /// step over which the identification measures the slip. Default 0.1 s.
  double turn_slip_yaw_rate_window_s = 0.1;
};

/// One output per odometer sample after the start.
struct DeadReckoningOutput {
  double t_s = 0.0;
  Geodetic position;                                ///< WGS-84 (rad, rad, m) of the reference point.
  Eigen::Vector3d enu_m = Eigen::Vector3d::Zero();  ///< local ENU (m) w.r.t. the DR origin.
  /// Rotation taking vectors of the DR origin's ENU frame (enu_m's axes) into the ENU frame at
  /// `position`: the two differ by the meridian convergence (near a pole by up to 180 deg).
  Eigen::Matrix3d origin_to_local = Eigen::Matrix3d::Identity();
  double heading_rad = 0.0;    ///< body heading (INS) or GNSS course (degraded) used, [0, 2 pi).
  double distance_m = 0.0;     ///< odometer distance travelled since the start, sum |dS| (m).
  double k_m_per_pulse = 0.0;  ///< K used for the interval ending here.
  ScaleFactorSource k_source = ScaleFactorSource::kNominal;
  /// Track slip s removed from the interval ending here: its distance is K pulses / (1 + s)
  /// (turn_slip.hpp; 0 on a straight, without INS or before any slip gain applies).
  double turn_slip_fraction = 0.0;
  bool degraded = false;        ///< no INS: heading from the GNSS course.
  bool heading_held = false;    ///< the heading was not measured for this interval (held).
  bool gnss_reference = false;  ///< a GNSS reference existed at t_s.
  double horizontal_error_m = std::numeric_limits<double>::quiet_NaN();      ///< |DR - GNSS| horizontal.
  double error_percent_distance = std::numeric_limits<double>::quiet_NaN();  ///< 100 error / distance.
  /// Valid GNSS epochs evaluated at this output, seen in the DR frame (for AnchoredPositionFilter).
  std::vector<AnchorFix> gnss_fixes;
  /// The GNSS epoch (s) the error refers to; NaN when no error is carried.
  double error_t_s = std::numeric_limits<double>::quiet_NaN();
  /// The K (misalignment) in force was held: the estimate of the latest GNSS epoch applicable here
  /// had not been received (see "Held estimates" above). Says nothing about the numbers above.
  bool k_held = false;
  bool misalignment_held = false;
};

/// Within this distance (m) of a pole the INS heading is a poor direction for dead reckoning:
/// "clockwise from true north" depends on where the vehicle is, and north at a position known to
/// within e metres across the meridian is turned by e / (distance to the pole) rad against north
/// at the true position, so inside 1000 m every metre of position error is more than 1 mrad
/// (0.057 deg) of heading, and at the pole itself north is only the meridian of the longitude
/// carried. The DR keeps integrating there (in ECEF, north taken where GNSS last put it:
/// docs/ALGORITHM.md §4c); health and the offline summary warn while it is inside.
constexpr double kPolarHeadingRadiusM = 1000.0;

/// Distance (m) of p to the nearer pole when it is within kPolarHeadingRadiusM, else nullopt.
std::optional<double> polar_heading_distance_m(const Geodetic& p);

/// The warning for a DR position distance_m (m) from the North (north) or South Pole: "within
/// 312 m of the North Pole: true north turns by 1/312 rad per metre across the meridian there, ...".
std::string polar_heading_text(double distance_m, bool north);

/// The dead_reckoning.csv row of an output (odonav/results/output_files.hpp): what odonav-offline
/// writes, and what the dead-reckoning node publishes through the topic's field table
/// (odonav/dds/output_messages.hpp).
results::DeadReckoningRow output_row(const DeadReckoningOutput& output);

/// The estimates whose arrival the dead reckoner tracks (add_estimate_received).
enum class HeldEstimate { kScaleFactor, kMisalignment };
const char* to_string(HeldEstimate estimate);

/// Consecutive outputs computed on a held estimate (event time, s).
struct HeldSpan {
  double first_t_s = 0.0;         ///< the first output on the held estimate
  double last_t_s = 0.0;          ///< the last one so far
  uint64_t outputs = 0;           ///< outputs in the span
  double estimate_epoch_s = 0.0;  ///< GNSS epoch of the latest estimate received (the one held)
  bool open = false;              ///< the last output so far was held: the span goes on
};

struct DeadReckonerCounters {
  uint64_t odometer_samples = 0;  ///< processed (including those before the start).
  uint64_t outputs = 0;
  uint64_t before_start = 0;                  ///< odometer samples before the DR start, not output.
  uint64_t unknown_direction = 0;             ///< intervals with direction 0, taken as forward.
  uint64_t reversing = 0;                     ///< intervals with direction -1.
  uint64_t heading_held = 0;                  ///< intervals without a measured heading (held).
  uint64_t distance_lost = 0;                 ///< intervals with no heading at all yet: not integrated.
  uint64_t pulse_jumps_rejected = 0;          ///< odometer samples dropped by the pulse-jump gate.
  uint64_t pulse_rebases = 0;                 ///< counter steps re-based on (one interval's pulses estimated).
  uint64_t anchor_fixes = 0;                  ///< valid GNSS epochs reported in gnss_fixes.
  uint64_t anchor_fixes_no_attitude = 0;      ///< valid epochs left out: no attitude for the lever arm.
  uint64_t gnss_latency_stale = 0;            ///< add_gnss_latency calls not later than the previous one.
  uint64_t outputs_on_held_k = 0;             ///< outputs whose K was held (DeadReckoningOutput::k_held)
  uint64_t outputs_on_held_misalignment = 0;  ///< outputs whose misalignment was held
  uint64_t turn_slip_stale = 0;               ///< add_turn_slip calls not later than the previous one.
};

/// The GNSS gap in force for an observed GNSS period (s; NaN: fewer than two rows seen):
/// params.gnss_max_gap_s when > 0, else max(gnss_max_gap_floor_s, gnss_max_gap_periods * period).
/// One function, so odonav-offline and odonav-dead-reckoning (which build their DeadReckonerParams
/// with dead_reckoner_params) bridge the same gaps.
double dead_reckoning_gnss_max_gap_s(const DeadReckonerParams& params, double gnss_period_s);

class DeadReckoner {
 public:
  /// Throws std::invalid_argument naming the parameter when params are out of range.
  explicit DeadReckoner(const DeadReckonerParams& params = {});

  /// polar_heading_distance_m of the current DR position (nullopt before the start).
  std::optional<double> pole_distance_m() const;
  /// The current DR position (WGS-84); meaningful once started().
  const Geodetic& position() const { return position_; }

  /// Streams, each in strictly increasing time; throw StreamInputError on bad input.
  /// An odometer sample with an implausible pulse jump is dropped and counted (returns kJumpRejected).
  OdometerAddResult add_odometer(const OdometerSample& sample);
  void add_ins(const InsSample& sample);  ///< ignored when use_ins is false.
  void add_gnss(const GnssSample& sample);
  /// K (m/pulse, > 0) in force from t_s on, and where it comes from.
  void add_scale_factor(double t_s, double k_m_per_pulse, ScaleFactorSource source);
  /// Misalignment (rad) in force from t_s on (zero before the first).
  void add_misalignment(double t_s, const Misalignment& misalignment);
  /// GNSS latency (s, |latency| < 10) in force from t_s on (zero before the first): a fix stamped g
  /// describes the position at g - latency, so the error against GNSS and the anchor fix of epoch
  /// g compare it with the DR at g - latency, the latency being the one in force at
  /// estimate_applies_from_s(g, hold-off), when the epoch is evaluated. The node and odonav-offline
  /// add the latency every ScaleFactor carries at the ScaleFactor's application time. A value not
  /// later than the last one added is ignored and counted (gnss_latency_stale); an unchanged value
  /// is not stored again.
  void add_gnss_latency(double t_s, double latency_s);
  /// Track slip in turns in force from t_s on (none before the first): with INS, each interval's
  /// distance is K pulses / (1 + turn_slip_fraction(g, threshold, yaw rate)), the yaw rate over
  /// turn_slip_yaw_rate_window_s ending at the interval's middle. g (s/rad, finite, >= 0; 0 = none) and the threshold (rad/s,
  /// finite, >= 0) are the identification's (ScaleFactor). The node and odonav-offline add the
  /// applied gain of every ScaleFactor at its application time, as the latency. A value not later
  /// than the last one added is ignored and counted (turn_slip_stale); an unchanged one is not
  /// stored again. Throws StreamInputError on a value out of range.
  void add_turn_slip(double t_s, double g_s_per_rad, double threshold_radps);
  /// An estimate of GNSS epoch epoch_s (its stamp, s; not its application time) was received,
  /// applicable or not: the estimator is keeping up to there. Only for the held-estimate report.
  void add_estimate_received(HeldEstimate estimate, double epoch_s);

  /// Emits, in time order, the output of every odometer sample stamped <= watermark_s whose inputs
  /// are final. Contract: every input stamped <= watermark_s has been added.
  std::vector<DeadReckoningOutput> process_until(double watermark_s);
  /// End of data: processes everything left.
  std::vector<DeadReckoningOutput> finish();

  /// The complete state (checkpoint_state.hpp, every double exact): the integration (origin,
  /// position, count, distance, held heading), the buffered inputs not yet processed or still needed
  /// (odometer, attitude, GNSS, K, misalignment, latency), the epochs whose error is not evaluated
  /// yet and the outputs it needs, the last error, the held-estimate tracking and the counters. A
  /// DeadReckoner restored from it and fed the inputs that follow those already added gives the
  /// same outputs, bit for bit, as this one.
  StateJson save_state() const;
  /// Restores save_state()'s state into this dead reckoner, which must have been made with the same
  /// parameters (a checkpoint's configuration hash says so). Throws CheckpointError naming the field
  /// when it is not a state of this version; the dead reckoner is unchanged then.
  void restore_state(const StateJson& state);

  bool started() const { return frame_.has_value(); }
  /// The DR origin (reference point at the start), once started.
  std::optional<Geodetic> origin() const;
  const DeadReckonerCounters& counters() const { return counters_; }
  /// The last span of outputs on a held estimate of that kind, if any.
  const std::optional<HeldSpan>& last_held_span(HeldEstimate estimate) const {
    return held_[static_cast<int>(estimate)].span;
  }

 private:
  struct KInForce {
    double k_m_per_pulse;
    ScaleFactorSource source;
    template <class Archive, class Self>  // checkpoint fields (checkpoint_state.hpp)
    static void state_fields(Archive& a, Self& s) {
      a("k_m_per_pulse", s.k_m_per_pulse)("source", s.source);
      a.check("k_m_per_pulse", std::isfinite(s.k_m_per_pulse), "is not finite");
      a.check("source",
              s.source == ScaleFactorSource::kNominal || s.source == ScaleFactorSource::kIdentified ||
                  s.source == ScaleFactorSource::kCommanded,
              "is not 0, 1 or 2");
    }
  };
  enum class Readiness { kReady, kWait };
  Readiness try_start(double t_j);
  std::optional<Eigen::Vector3d> gnss_reference_enu(double t_s, const std::optional<Attitude>& att) const;
  std::optional<Eigen::Vector3d> gnss_velocity_at(double t_s) const;
  bool gnss_final_at(double t_s) const;
  bool gnss_complete_at(double t_s) const;
  void evaluate_errors(DeadReckoningOutput& o);
  struct Past {  ///< a recent output, for the error at GNSS epochs between outputs.
    double t_s;
    Eigen::Vector3d enu_m;
    double distance_m;
    /// The lever arm in ENU at t_s: zero without a lever arm, unset when it is configured but
    /// the attitude (INS, or the GNSS course without INS) is not known at t_s.
    std::optional<Eigen::Vector3d> lever_arm_enu_m;
    template <class Archive, class Self>
    static void state_fields(Archive& a, Self& s) {
      a("t_s", s.t_s)("enu_m", s.enu_m)("distance_m", s.distance_m)("lever_arm_enu_m", s.lever_arm_enu_m);
    }
  };
  struct EpochError {
    double epoch_s;
    double applies_s;
    double horizontal_error_m;
    double error_percent_distance;
    double carry_s;  ///< carried on the outputs up to this long after applies_s (the GNSS gap).
    template <class Archive, class Self>
    static void state_fields(Archive& a, Self& s) {
      a("epoch_s", s.epoch_s)("applies_s", s.applies_s)("horizontal_error_m", s.horizontal_error_m)(
          "error_percent_distance", s.error_percent_distance)("carry_s", s.carry_s);
    }
  };
  Eigen::Vector3d lever_arm_enu(const Attitude& att) const;
  DeadReckoningOutput step(const OdometerBuffer::Entry& sample);
  std::optional<Attitude> lever_arm_attitude_at(double t_s) const;
  /// The slip fraction of the odometer interval ending at t_s with mid-interval mid_s (add_turn_slip):
  /// the gain in force at t_s, the yaw rate over the window ending at mid_s; 0 without INS.
  double turn_slip_fraction_at(double t_s, double mid_s) const;

  DeadReckonerParams params_;
  OdometerBuffer odometer_;
  AttitudeBuffer attitude_;
  std::deque<double> pending_odometer_t_s_;
  std::deque<GnssSample> gnss_;
  /// The gap in force after each row of gnss_ (same index): the period observed up to that row.
  std::deque<double> gnss_gap_s_;
  std::deque<double> gnss_intervals_s_;  ///< the last gnss_period_window intervals between rows
  double last_gnss_gap_s_ = 0.0;         ///< the gap in force after the last row added
  void pop_gnss_front();
  std::optional<double> last_gnss_t_s_;
  /// GNSS epochs whose error is not evaluated yet, with the GNSS gap in force after each.
  std::deque<std::pair<GnssSample, double>> error_epochs_;
  std::deque<Past> past_;  ///< outputs (and the start) the next errors may need.
  std::optional<EpochError> last_error_;
  std::optional<double> start_t_s_;  ///< epoch of the start fix.
  StepHistory<KInForce> k_history_{"scale_factor"};
  StepHistory<Misalignment> misalignment_{"misalignment"};
  struct TurnSlipInForce {
    double g_s_per_rad;
    double threshold_radps;
    template <class Archive, class Self>
    static void state_fields(Archive& a, Self& s) {
      a("g_s_per_rad", s.g_s_per_rad)("threshold_radps", s.threshold_radps);
    }
  };
  StepHistory<TurnSlipInForce> turn_slip_{"turn_slip"};
  std::optional<std::pair<double, TurnSlipInForce>> last_turn_slip_;  ///< (t_s, value) last added
  StepHistory<double> gnss_latency_{"gnss_latency"};
  std::optional<std::pair<double, double>> last_gnss_latency_;  ///< (t_s, latency s) last added
  double watermark_s_ = -std::numeric_limits<double>::infinity();

  std::optional<LocalEnuFrame> frame_;
  Geodetic position_;
  double last_t_s_ = 0.0;
  double last_count_ = 0.0;
  double distance_m_ = 0.0;
  std::optional<double> held_heading_rad_;
  int held_direction_ = 0;  ///< odometer direction the held course was measured with (0: not known)
  /// Degraded mode: the course's minimum speed in force at t_s (course_min_speed_mps).
  double course_min_speed_at(double t_s) const;
  std::optional<Attitude> last_attitude_;
  // The DR's error at the latest GNSS epoch evaluated (fix minus DR, ENU of the origin, m): in the
  // polar cap the INS heading is taken from north at the DR position plus this (where the INS, and
  // the truth, are to GNSS accuracy), not at the DR position alone (see step()).
  std::optional<Eigen::Vector3d> heading_position_offset_enu_m_;
  std::optional<AnchorFix> start_fix_;  ///< reported with the first output
  DeadReckonerCounters counters_;
  /// GNSS epochs not yet applicable at the last output (for the held-estimate decision).
  std::deque<double> epochs_to_apply_s_;
  std::optional<double> latest_applicable_epoch_s_;  ///< latest GNSS epoch applicable at the last output
  struct HeldTracker {
    std::deque<double> received_s;            ///< epochs received (sorted) not yet applicable
    std::optional<double> last_applicable_s;  ///< latest received epoch applicable at the last output
    std::optional<HeldSpan> span;
    void receive(double epoch_s);
    /// Whether an output at t_s, with epoch_s the latest GNSS epoch applicable, is on a held
    /// estimate (exempt: never); updates the span.
    bool decide(double t_s, const std::optional<double>& epoch_s, bool exempt);
    template <class Archive, class Self>
    static void state_fields(Archive& a, Self& s) {
      a("received_s", s.received_s)("last_applicable_s", s.last_applicable_s)("span", s.span);
    }
  };
  HeldTracker held_[2];

  // The dead reckoner's checkpoint fields, listed once for save_state() and restore_state().
  friend struct odonav::StateAccess;  // save_fields() and restored_copy() reach state_fields
  template <class Archive, class Self>
  static void state_fields(Archive& a, Self& self);
};

}  // namespace odonav::dead_reckoning
