#pragma once
// The regression-sample builder of docs/ALGORITHM.md §2: turns the odometer, GNSS and INS streams into
// scale-factor samples y_k = K * phi_k + e_k, one per GNSS epoch, behind a set of counted gates.
//
// Event time: every stream is buffered by add_*() (each stream in increasing time, streams in any
// order relative to each other); process_until(watermark_s) then emits every GNSS epoch whose inputs
// are complete. The contract of process_until(w): every input stamped <= w (odometer, GNSS, INS,
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

namespace odonav {

/// Rank of an NMEA GGA fix quality code for SampleBuilderParams::min_fix_rank:
/// 0 for 0 (invalid) and 6 (dead reckoning); 1 for 1 (single) and any other code; 2 for 2, 3, 9
/// (differential, PPS, SBAS); 3 for 5 (RTK float); 4 for 4 (RTK fixed).
int fix_quality_rank(int fix);

/// Gate settings. Defaults are those of docs/ALGORITHM.md §2 for a 10 Hz GNSS receiver.
struct SampleBuilderParams {
  /// Use the INS attitude to project the GNSS velocity (false: |v_ENU|, degraded mode without INS).
  bool use_ins = true;
  /// Minimum forward speed at BOTH ends of an interval (m/s, >= 0). Default 2.
  double min_speed_mps = 2.0;
  /// Minimum fix_quality_rank (1..4). Default 1: every valid fix (codes 0 and 6 are always rejected).
  int min_fix_rank = 1;
  /// Longest interval between consecutive GNSS epochs that makes a sample (s, > 0). A longer gap
  /// breaks the chain: no sample across an outage. Default 0.5.
  double max_interval_s = 0.5;
  /// Yaw-rate gate: reject intervals whose |heading change| / dt exceeds max_yaw_rate_rad_s (track
  /// skid in turns). Heading from the INS, or from the GNSS course without INS. Default on, 3 deg/s:
  /// a skid-steered track slips in any turn, by tenths of a percent already at 5-10 deg/s, which an
  /// estimator would take for a change of K (measured on the terrain scenario: 10 deg/s let -0.6 %
  /// excursions of K through; 3 deg/s removed them at the cost of ~8 % of the samples).
  bool yaw_rate_gate_enabled = true;
  double max_yaw_rate_rad_s = 3.0 * kDegToRad;
  /// Intervals with |yaw rate| below this are marked straight (for the coarse S/N estimator). Default 1 deg/s.
  double straight_yaw_rate_rad_s = 1.0 * kDegToRad;
  /// Speed-jump gate (works before any K estimate): an epoch whose forward speed differs from the
  /// last good epoch's by more than max_acceleration_mps2 * dt + speed_jump_margin_mps is an outlier.
  /// The reference is used only if at most speed_jump_reference_max_age_s old. Defaults 6 m/s^2, 1 m/s, 1 s.
  double max_acceleration_mps2 = 6.0;
  double speed_jump_margin_mps = 1.0;
  double speed_jump_reference_max_age_s = 1.0;
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
  /// the speed-jump gate still applies. Default 50 (5 s at 10 Hz).
  int innovation_max_consecutive_rejections = 50;
  /// Longest gap between two odometer / INS samples across which they are interpolated (s). Default 1.
  double max_bracket_s = 1.0;
  /// Odometer pulse-jump gate (stream_buffers.hpp): increments above max_speed_mps / k_m_per_pulse
  /// * dt + margin_pulses are rejected and counted (odometer_jumps_rejected). Set k_m_per_pulse to the
  /// configured nominal K (default 0.0125 m/pulse, 100 m/s: 8000 pulses/s).
  OdometerJumpGate odometer_jump_gate;
  /// GNSS antenna position in the INS body frame (forward-left-up, m) from the reference point.
  /// When set (and use_ins), the antenna's extra velocity C_b^n (omega_b x l) is removed from the
  /// GNSS velocity before projection; omega_b from the INS attitude over [t - h, t + h]. With a mast of
  /// 2 m, pitching on rough ground and yaw in bends otherwise bias K by tenths of a percent.
  std::optional<Eigen::Vector3d> lever_arm_body_m;
  /// h above (s, > 0). Default 0.05 (the INS at 100 Hz gives the rate over 10 samples).
  double lever_arm_rate_half_window_s = 0.05;
};

/// What happened to one GNSS epoch (the first gate that rejected it, or accepted).
enum class EpochStatus {
  kAccepted,       ///< a sample ending at this epoch was produced.
  kChainStart,     ///< good epoch with no good previous epoch: a sample may start here.
  kInvalidFix,     ///< fix 0 or 6.
  kLowFixQuality,  ///< fix rank below min_fix_rank.
  kNoOdometer,     ///< no odometer count can be interpolated at the epoch.
  kNoAttitude,     ///< use_ins and no INS attitude can be interpolated at the epoch.
  kNegativeSpeed,  ///< forward speed < 0 (reversing seen by GNSS / INS).
  kSpeedJump,      ///< forward speed jumped beyond the acceleration bound.
  kGap,            ///< interval to the previous good epoch longer than max_interval_s.
  kMinSpeed,       ///< speed below min_speed_mps at one end of the interval.
  kReversing,      ///< an odometer sample of the interval reports direction -1.
  kYawRate,        ///< |yaw rate| over the interval above max_yaw_rate_rad_s.
  kNoPulses,       ///< no pulse counted over the interval (phi <= 0).
  kInnovation,     ///< innovation test against the K estimate failed.
};

/// The last EpochStatus: sample_builder.cpp holds one table entry (status, counter, text) per status
/// up to it, checked at compile time, so a new status must come with its counter and its name.
inline constexpr EpochStatus kLastEpochStatus = EpochStatus::kInnovation;

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
  /// Samples accepted while the innovation test was suspended (not a rejection: also in accepted).
  uint64_t innovation_suspended = 0;
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

 private:
  struct GoodEpoch {
    double t_s;
    Eigen::Vector3d vel_enu_mps;
    Attitude attitude;
    double count_pulses;
  };
  struct KEstimate {
    double k_m_per_pulse;
    double sigma_m_per_pulse;
  };
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
  EpochStatus check_interval(const GnssSample& gnss, const EpochInputs& inputs, ScaleFactorSample& sample) const;
  /// Step 3, the innovation test of an accepted sample against the latest K estimate stamped before
  /// it, with the consecutive-rejection rule (SampleBuilderParams).
  InnovationVerdict innovation_gate(const GnssSample& gnss, const ScaleFactorSample& sample);
  double forward_speed(const Eigen::Vector3d& vel_enu_mps, const Attitude& att, const Misalignment& mis) const;
  bool compensates_lever_arm() const;
  /// GNSS velocity moved from the antenna to the INS reference point (ENU, m/s).
  Eigen::Vector3d reference_point_velocity(const GnssSample& g, const Attitude& att) const;
  void count(EpochStatus status);

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
};

}  // namespace odonav
