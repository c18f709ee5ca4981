#pragma once
// The regression-sample builder of docs/ALGORITHM.md §2: turns the odometer, GNSS and INS streams into
// scale-factor samples y_k = K * phi_k + e_k, one per GNSS epoch, behind a set of counted gates.
//
// Event time: every stream is buffered by add_*() (each stream in increasing time, streams in any
// order relative to each other); process_until(watermark_s) then emits every GNSS epoch whose inputs
// are complete. An epoch stamped t needs the odometer and INS up to its sensor time t - latency in
// force and nothing later (every window ends there); the GNSS-latency search, which looks up to
// 0.25 s further, is fed deferred samples (see latency_search_min_s) and never holds an epoch back. The contract of process_until(w): every input stamped <= w (odometer, GNSS, INS,
// misalignment, scale-factor estimate) has already been added. Under that contract the output for
// given inputs is bit-identical whatever the interleaving of add_* and process_until calls.
//
// Per valid GNSS epoch t_k after the first (units: s, m, m/s, pulses):
//   phi_k = N(t_k) - N(t_{k-1})              N: accumulated count, interpolated linearly, wrap-safe
//   y_k   = 1/2 (v(t_{k-1}) + v(t_k)) (t_k - t_{k-1})   (mean speed over the interval, not the end speed)
//   v     = forward speed along the odometer axis: GNSS ENU velocity rotated with the INS attitude
//           interpolated to the epoch and the misalignment in force at t_k (latest stamped <= t_k),
//           exact rotation (forward_speed_along_odometer). Without INS (params.use_ins = false):
//           v = |v_ENU|, the 3-D ground speed, because the odometer measures the path along the
//           ground including its climb; the horizontal speed would bias K low by 1 - cos(slope)
//           (0.4 % on a 5 deg slope) while the 3-D norm only adds the second-order sigma_up^2 / (2 v).
//
// Chain rule (why outliers cannot leak): a sample always spans two CONSECUTIVE GNSS epochs. An epoch
// rejected for an interval property (gap, low speed at the other end, reversing odometer, yaw rate,
// zero pulses) still has a good velocity of its own, so the next sample starts at it. An epoch
// whose own velocity is bad (invalid fix, no attitude, no odometer count, negative forward speed,
// speed jump, innovation outlier) breaks the chain: no sample starts at it, so its velocity enters
// neither the sample that ends at it nor the one after it.
#include <cstdint>
#include <deque>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "odonav/sensor_samples.hpp"
#include "odonav/frames.hpp"
#include "odonav/geodesy.hpp"
#include "odonav/scale_factor_estimator.hpp"
#include "odonav/stream_buffers.hpp"
#include "odonav/turn_slip.hpp"

namespace odonav {

/// Rank of an NMEA GGA fix quality code for SampleBuilderParams::min_fix_rank:
/// 0 for 0 (invalid) and 6 (dead reckoning); 1 for 1 (single) and any other code; 2 for 2, 3, 9
/// (differential, PPS, SBAS); 3 for 5 (RTK float); 4 for 4 (RTK fixed).
int fix_quality_rank(int fix);

/// Gate settings. Defaults are those of docs/ALGORITHM.md §2 for a 10 Hz GNSS receiver.
struct SampleBuilderParams {
  /// Use the INS attitude to project the GNSS velocity (false: |v_ENU|, degraded mode without INS).
  bool use_ins = true;
  /// Minimum forward speed at BOTH ends of an interval (m/s, >= 0). Default 0.5: slow robots and
  /// manoeuvring vehicles crawl at 0.5-3 m/s. The real limit is min_pulses below; this one only keeps
  /// out the last metres before a stop, where GNSS velocity noise is of the order of the speed.
  double min_speed_mps = 0.5;
  /// Minimum pulses counted over a sample (pulses, >= 0). Default 16: the quantisation of phi (one
  /// pulse at each end, sqrt(1/6) pulse one-sigma) is then at most 2.5 % of the sample, whatever K
  /// and the GNSS rate (with K = 0.0125 m/pulse at 10 Hz that is 2 m/s; with an 800-pulse encoder on
  /// a 0.15 m wheel at 1 Hz it is 1 cm/s). 15.9, not 16: interpolated counts are often whole or
  /// half pulses, and a threshold on such a value would let the last bit of a time stamp (a DDS
  /// stamp has nanoseconds) decide.
  double min_pulses = 15.9;
  /// Minimum fix_quality_rank (1..4). Default 1: every valid fix (codes 0 and 6 are always rejected).
  int min_fix_rank = 1;
  /// Longest interval between consecutive GNSS epochs that makes a sample (s). A longer gap breaks
  /// the chain: no sample across an outage. 0 (default) = derived from the GNSS period P observed in
  /// the data (the median of the last intervals between GNSS rows, gnss_period_window rows):
  /// max(max_interval_floor_s, max_interval_periods * P), i.e. 0.5 s at 10 Hz and 2.5 s at 1 Hz
  /// (effective_max_interval_s). > 0: that value, whatever the data.
  double max_interval_s = 0.0;
  double max_interval_periods = 2.5;
  double max_interval_floor_s = 0.5;
  /// Intervals between GNSS rows the period P is the median of (>= 1). Default 15.
  int gnss_period_window = 15;
  /// Intervals driven backwards (every odometer sample describing the interval says direction -1)
  /// make samples too: the same K measures the distance backwards, as the dead reckoning lays it
  /// out. phi is the pulses counted and y the distance from the backwards speed (with INS the
  /// forward speed is negative at both ends: an epoch with a negative forward speed is accepted
  /// while the odometer reports reversing at it; without INS |v| is the speed anyway). An interval
  /// in which the direction changes is rejected (kReversing) whatever this says: the vehicle stops
  /// in it. false: every interval with a reversing sample is rejected and counted (kReversing).
  /// Default true (measured on slow_robot: docs/ALGORITHM.md §2).
  bool reversing_samples = true;
  /// Yaw-rate gate: reject intervals whose |heading change| / dt exceeds max_yaw_rate_rad_s (track
  /// skid in turns). Heading from the INS, or from the GNSS course without INS. Default on, 3 deg/s:
  /// a skid-steered track slips in any turn, by tenths of a percent already at 5-10 deg/s, which an
  /// estimator would take for a change of K (measured on the terrain scenario: 10 deg/s let -0.6 %
  /// excursions of K through; 3 deg/s removed them at the cost of ~8 % of the samples).
  bool yaw_rate_gate_enabled = true;
  double max_yaw_rate_rad_s = 3.0 * kDegToRad;
  /// With INS, the yaw rate of an interval longer than this (s, > 0) is the largest over steps of
  /// about this length (INS heading), not the mean: a 1 s interval may hold a turn whose mean rate
  /// passes the gate. Default 0.1 s (one step at 10 Hz: the mean, as before).
  double yaw_rate_step_s = 0.1;
  /// Intervals with |yaw rate| below this are marked straight (for the coarse S/N estimator). Default 1 deg/s.
  double straight_yaw_rate_rad_s = 1.0 * kDegToRad;
  /// Speed-jump gate (works before any K estimate): an epoch whose forward speed differs from the
  /// last good epoch's by more than max_acceleration_mps2 * dt + speed_jump_margin_mps is an outlier.
  /// The reference is used only if at most max(speed_jump_reference_max_age_s, the effective
  /// max interval) old, so a 1 Hz receiver keeps the gate. Defaults 6 m/s^2, 1 m/s, 1 s.
  double max_acceleration_mps2 = 6.0;
  double speed_jump_margin_mps = 1.0;
  double speed_jump_reference_max_age_s = 1.0;
  /// Cross-track gate (with INS; works before any estimate, at every GNSS rate): an epoch whose GNSS
  /// velocity, turned into the odometer frame, has a component across the odometer axis (left and
  /// up together) above cross_track_n_sigma * sigma_v + tan(cross_track_angle_rad) * |forward| is a
  /// velocity outlier and breaks the chain. The vehicle moves along its odometer axis, so only
  /// noise, side slip and a misalignment not applied yet put velocity across it; a receiver glitch
  /// of metres per second in a random direction mostly does. Why it matters at low rates: the
  /// speed-jump bound grows with the interval (7 m/s at 1 Hz) and the innovation gate lets 10 % of
  /// a sample through, so at 1 Hz such glitches entered K as single samples moving it by 1-2 %
  /// (terrain 1 Hz, seed 10: three of its six outliers). Defaults on, 5 sigma, 5 deg.
  bool cross_track_gate_enabled = true;
  double cross_track_n_sigma = 5.0;
  double cross_track_angle_rad = 5.0 * kDegToRad;
  /// Innovation gate, active once a K estimate stamped before t_k exists:
  ///   reject when |y - K^ phi| > innovation_bound_m(...) = n_sigma * sigma_gate +
  ///   k_change_fraction * |K^ phi|, with sigma_gate^2 = (sigma_v T)^2 / 2 + K^2 / 6 +
  ///   (sigma_K phi)^2 (regression_noise_variance_m2 plus the estimate's uncertainty); sigma_v from
  ///   the GNSS row's vel_std_mps or gnss_velocity_sigma_mps. The relative term lets a genuine K
  ///   change of up to that fraction through, so the estimator can still track it.
  bool innovation_gate_enabled = true;
  double innovation_n_sigma = 5.0;
  double gnss_velocity_sigma_mps = 0.1;
  double innovation_k_change_fraction = 0.10;
  /// After this many consecutive innovation rejections the estimate is presumed stale (a K change
  /// beyond k_change_fraction) and the innovation test is suspended until a sample passes it again;
  /// the speed-jump gate still applies. 0 (default) = derived from the observed GNSS period P:
  /// the epochs in innovation_suspend_after_s (5 s: 50 at 10 Hz, 5 at 1 Hz), at least 3.
  int innovation_max_consecutive_rejections = 0;
  double innovation_suspend_after_s = 5.0;
  /// Longest gap between two odometer / INS samples across which they are interpolated (s). Default 1.
  double max_bracket_s = 1.0;
  /// Odometer pulse-jump gate (stream_buffers.hpp): increments above max_speed_mps / k_m_per_pulse
  /// * dt + margin_pulses are rejected and counted (odometer_jumps_rejected). Set k_m_per_pulse to the
  /// configured nominal K (default 0.0125 m/pulse, 100 m/s: 8000 pulses/s).
  OdometerJumpGate odometer_jump_gate;
  /// GNSS antenna position in the INS body frame (forward-left-up, m) from the reference point.
  /// When set (and use_ins), the antenna's extra velocity C_b^n (omega_b x l) is removed from the
  /// GNSS velocity before projection; omega_b from the INS attitude over [t - h, t] (the window ends
  /// at the epoch, so the sample needs no INS after it; lag h / 2). With a mast of
  /// 2 m, pitching on rough ground and yaw in bends otherwise bias K by tenths of a percent.
  std::optional<Eigen::Vector3d> lever_arm_body_m;
  /// h above (s, > 0). Default 0.05 (the INS at 100 Hz gives the rate over 10 samples).
  double lever_arm_rate_half_window_s = 0.05;

  /// GNSS latency (s): the receiver stamps a fix latency seconds after the instant it describes
  /// (processing delay, or a clock offset between receiver and odometer/INS time). The odometer
  /// count and the INS attitude of an epoch stamped t are taken at t - latency. A set value is
  /// used as it is (--gnss-latency-s); unset (default) it is estimated online (GnssLatencyEstimate,
  /// docs/ALGORITHM.md "GNSS latency").
  std::optional<double> gnss_latency_fixed_s;
  /// Online estimation: candidate latencies from latency_search_min_s to latency_search_max_s in
  /// steps of latency_search_step_s (defaults -0.2, 0.5, 0.01 s). For every candidate the squared
  /// residuals of the accepted samples against that candidate's own least-squares K are summed
  /// (one K per candidate and block of latency_block_s, so neither the K estimate nor a change of
  /// the true K enters them); the estimate is the vertex of a parabola fitted around the smallest
  /// sum, its sigma from the curvature.
  /// The sums are deferred: an accepted sample at t_k enters them before the first later epoch whose
  /// sensor time reaches t_k - latency_search_min_s + pulse_rate_half_window_s (its look-ahead), and
  /// a latency decided then applies from that epoch on (deterministic: it depends on stamps only).
  bool latency_estimation_enabled = true;
  double latency_search_min_s = -0.2;
  double latency_search_max_s = 0.5;
  double latency_search_step_s = 0.01;
  /// Pulse rate at a time: the count difference over [t - h, t + h] / 2h, h = this (s, in (0, 1]).
  /// Default 0.05 s. Used by the latency estimate (deferred, so it may look past the epoch) and the
  /// trapezoid correction, which reads the rates at t - h (windows [t - 2h, t]) over the interval
  /// shifted back by h, so it needs no odometer after the epoch.
  double pulse_rate_half_window_s = 0.05;
  /// Samples spanning at least this long (s, > 0; default 0.3: GNSS below about 3 Hz) get the
  /// trapezoid correction: y += K^ (phi' - T/2 (rate(t0 - h) + rate(t1 - h))), phi' the pulses over
  /// [t0 - h, t1 - h]: the distance the trapezoid of the two speeds misses, as the odometer's
  /// pulse-rate profile shows it (docs/ALGORITHM.md §2), read h earlier so that no window passes t1.
  /// At 10 Hz the curvature error is far below the GNSS noise and the rate's quantisation would
  /// only add noise.
  double trapezoid_correction_min_interval_s = 0.3;
  /// Half width of the least-squares parabola fitted around the smallest sum (s, > 0; at least 5
  /// candidates). Default 0.1 s.
  double latency_fit_half_width_s = 0.1;
  /// The estimate is applied (replaces the value in force, initially 0) once it comes from at least
  /// latency_min_sample_time_s (default 20 s) of samples, i.e. that time divided by the observed GNSS
  /// period (200 samples at 10 Hz, 20 at 1 Hz) but never fewer than latency_min_samples (default
  /// 20), lies inside the search range and either its sigma is at most latency_apply_sigma_s
  /// (default 0.002 s) and it differs from the value in force by more than that sigma, or it is more
  /// than 5 sigma from the value in force (below). A fixed count of 200 kept a 1 Hz receiver's
  /// latency out for 275-387 s of terrain (K RMS 0.176 % at 100 ms against 0.077 % without latency).
  double latency_apply_sigma_s = 0.002;
  double latency_min_sample_time_s = 20.0;
  int latency_min_samples = 20;
  /// An estimate more than 5 sigma away from the value in force is applied at once, however large
  /// its sigma; when the applied value moves by more than latency_restart_s (default 0.02 s) from the
  /// one the sums were collected at, the sums start again (they were gated at the old value).
  double latency_restart_s = 0.02;
  /// ... but only when that sigma is at most latency_apply_coarse_sigma_s (default 0.012 s). 7 ms was
  /// chosen when the 1 Hz sums were biased (a wrong 60 ms passed at 10 ms on 3 of 10 seeds); since
  /// the search compares the speeds' trapezoid without the curvature correction, 12 ms applies no
  /// latency on any of the 10 seeds of terrain at 1 Hz and of the slow robot, whose truth is 0.
  double latency_apply_coarse_sigma_s = 0.012;
  /// An estimate whose sigma is at most this fraction (in (0, 1), default 0.5) of the sigma the value
  /// in force had when it was applied, and which differs from it by more than its own sigma, is
  /// applied too: the latency is refined as the information grows where sigma never reaches
  /// latency_apply_sigma_s (1 Hz: the coarse value applied at sigma 10-12 ms is replaced once sigma
  /// is 5-6 ms; terrain, 10 seeds at 50/100/200 ms: the largest final error 36 -> 14 ms).
  double latency_refine_sigma_fraction = 0.5;
  /// Samples enter the latency sums only once the innovation gate is armed: the K estimate's
  /// one-sigma is at most this fraction of K (default 0.005). The sums do not use that K otherwise.
  double latency_max_k_rel_sigma = 0.005;
  /// Length of the blocks the per-candidate K is fitted over (s, > 0; default 30 s by sample
  /// stamp): long enough that a block holds several speed changes (the latency is read from the
  /// part of the pulse-rate profile a scale cannot explain), short enough that the true K (steps,
  /// wear, load) hardly moves within one. Against the running K estimate instead, the estimate lag
  /// after a change of K times the speed profile biased the latency by +1 to +2.5 ms.
  double latency_block_s = 30.0;
  /// One-sigma (s, >= 0) of the GNSS latency before the data say anything about it (estimated
  /// online, no estimate yet; default 0.1 s: receivers stamp tens to a few hundred ms late, and
  /// one that is known to be later should be given --gnss-latency-s). Enters K's published sigma
  /// only (latency_in_force_uncertainty_s), never a gate or an estimate.
  double latency_prior_sigma_s = 0.1;
};

/// The max interval in force for an observed GNSS period (s; NaN: not yet observed):
/// params.max_interval_s when > 0, else max(max_interval_floor_s, max_interval_periods * period).
double effective_max_interval_s(const SampleBuilderParams& params, double gnss_period_s);

/// The GNSS latency the builder works with (all in s).
struct GnssLatencyEstimate {
  /// Latency applied to the epochs (fixed, or the last estimate that met the apply rule, else 0).
  double applied_s = 0.0;
  /// The one-sigma of the estimate when it was applied: 0 when fixed, -1 while none was applied.
  double applied_sigma_s = -1.0;
  /// The online estimate and its one-sigma; sigma -1 while there is none (too few samples, no
  /// minimum inside the search range). With a fixed latency: the fixed value, sigma 0.
  double estimate_s = 0.0;
  double sigma_s = -1.0;
  /// Samples in the estimate.
  uint64_t samples = 0;
  /// Blocks of samples left out of the estimate because one K could not describe them (their own
  /// latency lay more than 5 of their sigmas from the others'; docs/ALGORITHM.md "GNSS latency").
  uint64_t blocks_left_out = 0;
  bool fixed = false;
  /// Why there is no usable estimate (empty when there is): names the rule and the observed value.
  std::string reason;
};

/// What happened to one GNSS epoch (the first gate that rejected it, or accepted).
enum class EpochStatus {
  kAccepted,       ///< a sample ending at this epoch was produced.
  kChainStart,     ///< good epoch with no good previous epoch: a sample may start here.
  kInvalidFix,     ///< fix 0 or 6.
  kLowFixQuality,  ///< fix rank below min_fix_rank.
  kNoOdometer,     ///< no odometer count can be interpolated at the epoch.
  kNoAttitude,     ///< use_ins and no INS attitude can be interpolated at the epoch.
  kNegativeSpeed,  ///< forward speed < 0 (reversing seen by GNSS / INS) while the odometer reports
                   ///< forward, or reversing_samples is off.
  kSpeedJump,      ///< forward speed jumped beyond the acceleration bound.
  kGap,            ///< interval to the previous good epoch longer than max_interval_s.
  kMinSpeed,       ///< speed below min_speed_mps at one end of the interval.
  kReversing,      ///< the odometer's direction changes within the interval, or (reversing_samples
                   ///< off) a sample of it reports -1.
  kYawRate,        ///< |yaw rate| over the interval above max_yaw_rate_rad_s.
  kNoPulses,       ///< no pulse counted over the interval (phi <= 0).
  kInnovation,     ///< innovation test against the K estimate failed.
  kCrossTrack,     ///< GNSS velocity across the odometer axis beyond the cross-track bound (outlier).
};

/// The last EpochStatus: sample_builder.cpp holds one table entry (status, counter, text) per status
/// up to it, checked at compile time, so a new status must come with its counter and its name.
inline constexpr EpochStatus kLastEpochStatus = EpochStatus::kCrossTrack;

/// Stable lower-case name of a status ("accepted", "speed_jump", ...), for logs and counters.
const char* to_string(EpochStatus status);

/// The right-hand side of the innovation test (SampleBuilderParams, innovation gate) [m]:
///   n_sigma * sqrt(regression_noise_variance_m2(sigma_v, T, K) + (sigma_K phi)^2)
///     + k_change_fraction * |K phi|.
/// sigma_v_mps: GNSS velocity one-sigma [m/s]; k_m_per_pulse, sigma_k_m_per_pulse: the estimate
/// gated against [m/pulse]; phi_pulses: pulses of the sample; interval_s: T [s]. A sample whose
/// |y - K phi| exceeds it is an innovation outlier (docs/ALGORITHM.md, "Scale-factor regression").
double innovation_bound_m(const SampleBuilderParams& params, double sigma_v_mps, double k_m_per_pulse,
                          double sigma_k_m_per_pulse, double phi_pulses, double interval_s);

/// Half window h [s] of the pulse rates of the trapezoid correction (SampleBuilderParams,
/// trapezoid_correction_min_interval_s) for a sample of interval_s [s] with the estimate
/// k_m_per_pulse and the GNSS velocity one-sigma sigma_v_mps: the shortest h, from
/// pulse_rate_half_window_s up to a quarter of the interval, whose pulse quantisation in the rate,
/// |K| sqrt(2/12) / (2h) m/s, is at most a quarter of sigma_v (docs/ALGORITHM.md §2).
double trapezoid_rate_half_window_s(const SampleBuilderParams& params, double k_m_per_pulse, double sigma_v_mps,
                                    double interval_s);

/// Counts per gate (each GNSS epoch is counted once, under the first gate that rejected it).
struct SampleBuilderCounters {
  uint64_t epochs = 0;
  uint64_t accepted = 0;
  uint64_t chain_starts = 0;
  uint64_t invalid_fix = 0;
  uint64_t low_fix_quality = 0;
  uint64_t no_odometer = 0;
  uint64_t no_attitude = 0;
  uint64_t negative_speed = 0;
  uint64_t speed_jump = 0;
  uint64_t gap = 0;
  uint64_t min_speed = 0;
  uint64_t reversing = 0;
  uint64_t yaw_rate = 0;
  uint64_t no_pulses = 0;
  uint64_t innovation = 0;
  uint64_t cross_track = 0;
  /// Samples accepted while the innovation test was suspended (not a rejection: also in accepted).
  uint64_t innovation_suspended = 0;
  /// Samples of intervals driven backwards (reversing_samples; also in accepted).
  uint64_t reversing_accepted = 0;
  /// Odometer samples (not GNSS epochs) rejected by the pulse-jump gate, and counter steps re-based
  /// on (stream_buffers.hpp, OdometerBuffer).
  uint64_t odometer_jumps_rejected = 0;
  uint64_t odometer_rebases = 0;
  /// The counter for one status.
  uint64_t count(EpochStatus status) const;
};

/// One processed GNSS epoch.
struct SampleBuilderEpoch {
  double t_s = 0.0;
  EpochStatus status = EpochStatus::kInvalidFix;
  /// Forward speed at the epoch (m/s); NaN when it could not be computed.
  double forward_speed_mps = 0.0;
  /// The sample ending at this epoch, present iff status == kAccepted.
  std::optional<ScaleFactorSample> sample;
  /// The GNSS latency after this epoch.
  GnssLatencyEstimate latency;
  /// With status kYawRate: the interval as a turn-slip sample (turn_slip.hpp), when it passed every
  /// other interval gate, INS is used and a K estimate exists to compare with.
  std::optional<TurnSlipSample> turn_sample;
};

class SampleBuilder {
 public:
  /// Throws std::invalid_argument naming the parameter when params are out of range.
  explicit SampleBuilder(const SampleBuilderParams& params = {});

  /// Stream inputs, each in strictly increasing time; throw StreamInputError on bad input.
  /// An odometer sample with an implausible pulse jump is dropped and counted (returns kJumpRejected).
  OdometerAddResult add_odometer(const OdometerSample& sample);
  void add_gnss(const GnssSample& sample);
  /// Ignored (not buffered) when params.use_ins is false.
  void add_ins(const InsSample& sample);
  /// Misalignment in force from t_s on (radians; zero before the first one).
  void add_misalignment(double t_s, const Misalignment& misalignment);
  /// A scale-factor estimate (m/pulse, one-sigma m/pulse) made from samples up to t_s. The epoch at
  /// t_k gates with the latest estimate stamped strictly before t_k. To feed back the estimator's
  /// output deterministically, stamp it with the sample's t_s and add it from the epoch callback of
  /// process_until (it then applies from the next epoch on, however the calls are chunked).
  void add_scale_factor_estimate(double t_s, double k_m_per_pulse, double sigma_m_per_pulse);

  using EpochCallback = std::function<void(const SampleBuilderEpoch&)>;
  /// Processes, in time order, every buffered GNSS epoch stamped <= watermark_s whose inputs are
  /// complete (see stream_buffers.hpp); calls on_epoch (if given) for each before moving to the
  /// next, and returns them. A watermark lower than a previous one changes nothing.
  std::vector<SampleBuilderEpoch> process_until(double watermark_s, const EpochCallback& on_epoch = {});
  /// End of data: processes everything left (as process_until(+infinity)).
  std::vector<SampleBuilderEpoch> finish(const EpochCallback& on_epoch = {});

  const SampleBuilderCounters& counters() const { return counters_; }
  const SampleBuilderParams& params() const { return params_; }
  /// The local ENU frame of gnss_position_enu_m (origin: the first valid GNSS fix), once known.
  const std::optional<LocalEnuFrame>& position_frame() const { return frame_; }
  /// GNSS epochs buffered and not yet processed.
  std::size_t pending_epochs() const { return pending_gnss_.size(); }
  /// The GNSS period observed so far (s; NaN before two GNSS rows) and the gates derived from it.
  double gnss_period_s() const { return gnss_period_s_; }
  double max_interval_in_force_s() const { return effective_max_interval_s(params_, gnss_period_s_); }
  int innovation_rejections_before_suspension() const;
  /// The GNSS latency in force and its online estimate.
  const GnssLatencyEstimate& latency() const { return latency_; }
  /// The K the latency search fits at its own latency estimate over the drive's first block of
  /// samples, while that estimate clearly differs from the latency in force (docs/ALGORITHM.md
  /// "GNSS latency", "The start of a drive"). Before any latency is decided, the samples of an
  /// accelerating start are off by the unknown latency times their speed change, and the running
  /// K estimate with them (-9 % to -2 % over the first 30 s of sim:terrain at 200 ms), while the
  /// K of the best latency candidate is not. Given only while all of these hold:
  ///   - the latency is estimated online and none was decided yet (none applied, the sums never
  ///     restarted), and the search's first block is still open;
  ///   - at any GNSS rate: the search compares the trapezoid of two speeds with the trapezoid of
  ///     two pulse rates, like with like, so its K has no bias of its own at 1-2 Hz either;
  ///   - the block's own latency estimate beats the value in force (beats_nominal: more than
  ///     kProvisionalMinSigmas of its sigmas away).
  struct StartLatencyK {
    double k_m_per_pulse = 0.0;    ///< K at the block's latency estimate (m/pulse).
    double latency_s = 0.0;        ///< the block's latency estimate (s) ...
    double latency_sigma_s = 0.0;  ///< ... and its one-sigma (s).
  };
  std::optional<StartLatencyK> start_latency_k() const;
  /// How far (one-sigma, s) the true latency may lie from the one in force, as the latency search
  /// knows it now (docs/ALGORITHM.md "Honest sigma of K"): 0 with a fixed latency or estimation
  /// off; else hypot(estimate - applied, sigma) of the online estimate when it has one, else the
  /// sigma the value in force was applied with, else hypot(...) of the open block's own fit (as
  /// start_latency_k, from 10 samples on), else latency_prior_sigma_s; each least-squares sigma
  /// times sigma_factor (>= 1: the residuals' serial correlation, widen_latency_sigma). What K's
  /// published sigma adds as |dK/dlatency| times it.
  double latency_in_force_uncertainty_s(double sigma_factor) const;
  /// The serial-correlation factor (>= 1) of the samples' residuals, K's
  /// (ScaleFactorEstimate::correlation_factor): the latency search judges whether an estimate
  /// differs significantly from the value in force (the apply rules, latency_decided,
  /// start_latency_k) against factor * sigma; its thresholds on sigma stay on the plain one. 1 until
  /// set; not part of the saved state (the caller sets it again after a restore).
  void set_latency_sigma_factor(double factor) { latency_sigma_factor_ = factor >= 1.0 ? factor : 1.0; }
  /// Whether the latency in force is decided (docs/ALGORITHM.md "Honest sigma of K"): fixed or
  /// estimation off, or an estimate was applied, or the online estimate confirms the value in
  /// force (its sigma at most latency_apply_coarse_sigma_s and the value in force within 3 of its
  /// sigmas: beats_nominal false). K is not published as converged before (IdentificationCore).
  bool latency_decided() const;

  /// Everything the builder holds besides its parameters (checkpoint_state.hpp, every double
  /// exact): the buffered inputs not processed yet, the sample chain, the gates' references, the
  /// observed GNSS period, the latency estimate with its sums, the counters. A builder made with the
  /// same parameters and given restore_state(save_state()) continues exactly as this one would (a
  /// component checkpoint; the inputs it had taken in must then not be added again).
  StateJson save_state() const;
  /// Throws CheckpointError (checkpoint_state.hpp) naming the field when the state is not one of a
  /// builder with these parameters; the builder is unchanged then.
  void restore_state(const StateJson& state);

 private:
  struct GoodEpoch {
    double t_s;
    Eigen::Vector3d vel_enu_mps;
    Attitude attitude;
    double count_pulses;
    template <class Archive, class Self>  // checkpoint fields (checkpoint_state.hpp)
    static void state_fields(Archive& a, Self& s) {
      a("t_s", s.t_s)("vel_enu_mps", s.vel_enu_mps)("attitude", s.attitude)("count_pulses", s.count_pulses);
    }
  };
  struct KEstimate {
    double k_m_per_pulse;
    double sigma_m_per_pulse;
    template <class Archive, class Self>
    static void state_fields(Archive& a, Self& s) {
      a("k_m_per_pulse", s.k_m_per_pulse)("sigma_m_per_pulse", s.sigma_m_per_pulse);
    }
  };
  // The builder's checkpoint fields, listed once for save_state() and restore_state().
  friend struct odonav::StateAccess;  // save_fields() and restored_copy() reach state_fields
  template <class Archive, class Self>
  static void state_fields(Archive& a, Self& self);
  /// What an epoch that passed its own checks gives: the chain-start record and what the
  /// interval checks need.
  struct EpochInputs {
    GoodEpoch epoch{};
    Misalignment misalignment;
    /// Forward speed (m/s); NaN until it is computed.
    double forward_speed_mps = std::numeric_limits<double>::quiet_NaN();
  };
  /// Outcome of the innovation test of one sample.
  enum class InnovationVerdict {
    kPassed,     ///< inside the bound, or not tested (gate off, no estimate yet).
    kOutlier,    ///< outside the bound: the epoch is rejected (kInnovation).
    kSuspended,  ///< outside, but after too many consecutive rejections the test is suspended.
  };
  /// One GNSS epoch through every gate, in order: own velocity, interval, innovation; then the chain.
  SampleBuilderEpoch process_epoch(const GnssSample& gnss);
  /// Step 1, the epoch's own velocity (fix, odometer count, attitude, forward speed, speed jump):
  /// the chain-breaking status that rejects it, or nullopt with `inputs` filled (forward_speed_mps
  /// as far as it was computed, also on a rejection).
  std::optional<EpochStatus> check_epoch_velocity(const GnssSample& gnss, EpochInputs& inputs);
  /// Step 2, the interval from the chain start to this epoch (gap, speeds, reversing, yaw rate,
  /// pulses): kAccepted with `sample` filled, or the gate that rejected the interval.
  /// speed_trapezoid_m: y before the trapezoid correction (the trapezoid of the two speeds, m), which
  /// the latency search compares with the trapezoid of two pulse rates.
  /// turn: when the yaw-rate gate rejects an interval that passed every other interval gate (INS
  /// and a K estimate present), filled with its turn-slip sample (turn_slip.hpp); may be null.
  EpochStatus check_interval(const GnssSample& gnss, const EpochInputs& inputs, ScaleFactorSample& sample,
                             double& speed_trapezoid_m, TurnSlipSample* turn) const;
  /// X of a turn-slip sample over [start_sensor_t, end_sensor_t] (pulses rad/s; turn_slip.hpp);
  /// nullopt when an INS attitude or odometer count inside it is missing.
  std::optional<double> turn_pulses_radps(double start_sensor_t, double end_sensor_t, const GoodEpoch& start) const;
  /// Step 3, the innovation test of an accepted sample against the latest K estimate stamped before
  /// it, with the consecutive-rejection rule (SampleBuilderParams).
  InnovationVerdict innovation_gate(const GnssSample& gnss, const ScaleFactorSample& sample);
  double forward_speed(const Eigen::Vector3d& vel_enu_mps, const Attitude& att, const Misalignment& mis) const;
  bool compensates_lever_arm() const;
  /// GNSS velocity moved from the antenna to the INS reference point (ENU, m/s).
  Eigen::Vector3d reference_point_velocity(const GnssSample& g, const Attitude& att) const;
  void count(EpochStatus status);
  /// Pulse rate (pulses/s) at sensor time t_s (pulse_rate_half_window_s); nullopt without counts.
  std::optional<double> pulse_rate_at(double t_s) const;
  /// The same over [t - h, t + h] for the given half window h [s].
  std::optional<double> pulse_rate_at(double t_s, double half_window_s) const;
  /// Samples the latency estimate needs before it may be applied (latency_min_sample_time_s over the
  /// observed GNSS period, at least latency_min_samples).
  uint64_t latency_min_samples_in_force() const;
  /// Updates the observed GNSS period with a new row at t_s.
  void observe_gnss_period(double t_s);
  /// Sensor time of a GNSS epoch stamped t_s: t_s - applied latency.
  double sensor_time(double t_s) const { return t_s - latency_.applied_s; }
  /// The largest latency any query may use (applied value and candidates), for pruning.
  double earliest_sensor_offset_s() const;
  /// An accepted sample waiting for the odometer its latency candidates look at (the smallest
  /// candidate, -0.2 s by default, needs the pulse rate 0.25 s after the epoch).
  struct PendingLatencySample {
    double t0_s;
    double t1_s;
    double y_m;
    double applied_s;      ///< latency in force when the sample was made.
    double needs_until_s;  ///< sensor time up to which the odometer must be final to add it.
    template <class Archive, class Self>
    static void state_fields(Archive& a, Self& s) {
      a("t0_s", s.t0_s)("t1_s", s.t1_s)("y_m", s.y_m)("applied_s", s.applied_s)("needs_until_s", s.needs_until_s);
    }
  };
  /// Queues an accepted sample between the epochs stamped t0_s and t1_s for the latency sums.
  void defer_latency_sample(double t0_s, double t1_s, double y_m);
  /// Adds a deferred sample to the sums (update_latency), unless the sums restarted away from the
  /// latency it was made at.
  void fold_latency_sample(const PendingLatencySample& sample);
  /// Adds an accepted sample between the epochs stamped t0_s and t1_s to the latency candidates and
  /// updates latency_ (estimation only; the applied value changes for the following epochs).
  void update_latency(double t0_s, double t1_s, double y_m);
  /// The parabola fit of the per-candidate sums of normalised squared residuals (samples of them,
  /// fitted_k K values fitted to them): fills estimate_s, sigma_s, samples, reason of out and
  /// returns whether there is an estimate.
  bool fit_latency(const std::vector<double>& sums, uint64_t samples, uint64_t fitted_k, GnssLatencyEstimate& out,
                   uint64_t min_samples) const;
  /// The open block's residual sum per candidate (against the candidate's own K over the block),
  /// scaled by the block's residual variance: (samples - 1) / its smallest sum. False when the
  /// block has too few samples or no residual.
  bool weighted_block_residuals(std::vector<double>& out) const;
  /// Whether the open block (its weighted_block_residuals) agrees with the reference latency: the
  /// closed blocks' estimate or, before any block closed after a restart, the value applied. Its own
  /// parabola's vertex within 5 hypot(own sigma, reference sigma) of it (true without a reference;
  /// false when the block gives no vertex of its own).
  bool block_consistent(const std::vector<double>& block) const;
  /// Fits the closed blocks' sums: latency_closed_fit_ and latency_closed_sigma_s_ (none when the
  /// fit fails). After every closed block and after a restore (the sigma is not saved).
  void fit_closed_blocks();
  /// Clears the latency sums (closed blocks and the open one).
  void restart_latency_sums();

  SampleBuilderParams params_;
  OdometerBuffer odometer_;
  AttitudeBuffer attitude_;
  std::deque<GnssSample> pending_gnss_;
  std::optional<double> last_gnss_t_s_;
  StepHistory<Misalignment> misalignment_{"misalignment"};
  StepHistory<KEstimate> k_estimates_{"scale_factor_estimate"};
  double watermark_s_ = -std::numeric_limits<double>::infinity();
  std::optional<GoodEpoch> chain_start_;
  std::optional<std::pair<double, double>> last_good_speed_;  ///< (t_s, forward speed m/s)
  int consecutive_innovation_rejections_ = 0;
  std::optional<LocalEnuFrame> frame_;
  SampleBuilderCounters counters_;
  std::deque<double> gnss_intervals_s_;
  std::optional<double> last_period_row_t_s_;
  double gnss_period_s_ = std::numeric_limits<double>::quiet_NaN();
  GnssLatencyEstimate latency_;
  std::vector<double> latency_candidates_s_;
  /// Per candidate: the closed blocks' weighted_block_residuals, summed (dimensionless), and the
  /// blocks and samples in them.
  std::vector<double> latency_closed_chi2_;
  uint64_t latency_closed_blocks_ = 0;
  uint64_t latency_closed_samples_ = 0;
  std::optional<double> latency_closed_fit_;  ///< the closed blocks' latency estimate (s), if any.
  double latency_closed_sigma_s_ = -1.0;      ///< its sigma (s); fit_closed_blocks, not saved.
  /// The open block (from latency_block_start_s_, the end stamp of its first sample): sum y^2 and,
  /// per candidate, sum y phi and sum phi^2 (m^2, m pulses, pulses^2).
  double latency_block_start_s_ = 0.0;
  uint64_t latency_block_samples_ = 0;
  double latency_block_yy_m2_ = 0.0;
  std::vector<double> latency_block_yphi_;
  std::vector<double> latency_block_phiphi_;
  std::vector<double> latency_chi2_;                  ///< closed blocks plus the open one, per candidate.
  std::deque<PendingLatencySample> latency_pending_;  ///< accepted, not yet in the sums (in order).
  uint64_t latency_samples_ = 0;                      ///< samples in latency_chi2_.
  double latency_sums_applied_s_ = 0.0;               ///< the applied latency the sums were collected at.
  uint64_t latency_restarts_ = 0;
  double latency_sigma_factor_ = 1.0;  // set_latency_sigma_factor; not saved
};

}  // namespace odonav
