#pragma once
// Odometer-to-INS installation misalignment calibration (docs/ALGORITHM.md §1), middleware-free.
//
// Per valid GNSS epoch: V_b = C_n^b V_n (body forward-left-up, m/s) with the INS attitude
// interpolated to the epoch. For motion along the odometer axis V_b = v (cos a_h cos a_p,
// sin a_h cos a_p, sin a_p) (docs/DATASET.md conventions), so two scalar least-squares regressions on the
// K-free regressor phi = V_forward give
//   theta_h = V_left / V_forward = tan a_h               ->  a_h = atan(theta_h)
//   theta_p = V_up   / V_forward = tan a_p / cos a_h      ->  a_p = atan(theta_p cos a_h)
// (exact inversions, not small-angle). The regressions are RLS with forgetting factor 1 and no
// prior, which is exactly the batch least squares theta = sum(y phi) / sum(phi^2): it is kept as those
// running sums (order-independent up to rounding, O(1) per epoch).
// One-sigma: sigma_theta = s / sqrt(sum phi^2), s = residual standard deviation of the regression
// (sqrt(RSS / (n - 1)), floored at residual_std_floor_mps), mapped to angles through the derivative of
// the inversion. What is published (and converged) differs in two ways, both for the first epochs
// and for residuals that are not independent; the outlier gate keeps the plain sigma:
//  - s^2 = (RSS + n0 sigma_v^2) / (n - 1 + n0): n0 = 3 pseudo-epochs of the assumed GNSS velocity
//    noise (gnss_velocity_sigma_mps), so that two or three residuals that happen to agree cannot
//    claim a fraction of the noise; after 100 epochs the pseudo-epochs weigh 3 %;
//  - times the serial-correlation factor of the regression's a-priori residuals
//    (ResidualCorrelationTracker, over about the last 50 used epochs).
//
// Event time: as the sample builder (sample_builder.hpp): add_gnss / add_ins in increasing time per
// stream, process_until(watermark_s) with the contract that every input stamped <= watermark_s has
// been added; one output per GNSS epoch (also for gated epochs, carrying the current values, so a
// downstream stream has a watermark), bit-identical whatever the interleaving of the add_* calls.
// freeze() / unfreeze() / reset() act on the epochs processed after the call.
#include <cmath>
#include <cstdint>
#include <deque>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Dense>

#include "odonav/braking_stop.hpp"
#include "odonav/event_time_aligner.hpp"
#include "odonav/published_estimates.hpp"
#include "odonav/residual_correlation.hpp"
#include "odonav/results/output_files.hpp"
#include "odonav/sensor_samples.hpp"
#include "odonav/state_json.hpp"
#include "odonav/frames.hpp"
#include "odonav/stream_buffers.hpp"

namespace odonav::calibration {

struct MisalignmentCalibratorParams {
  /// False when the recording has no INS: nothing can be calibrated (state stays waiting).
  bool use_ins = true;
  /// Minimum forward speed V_b,forward (m/s, > 0). Default 3: below it GNSS velocity noise dominates
  /// the ratio V_left / V_forward.
  double min_speed_mps = 3.0;
  /// Straight-line gate: |yaw rate| from the INS heading over [t - 2h, t] below this (rad/s). The
  /// window looks backwards so that the misalignment of epoch t leaves as soon as GNSS(t) and the
  /// INS at t are in: no output waits for INS after its epoch (that is, for the next GNSS epochs).
  /// Default 3 deg/s: side slip in turns and an uncompensated lever arm (omega x l) corrupt V_left.
  double max_yaw_rate_rad_s = 3.0 * kDegToRad;
  /// h above (s, > 0): the window is 2h long. Default 0.25 (a 0.5 s window).
  double yaw_rate_half_window_s = 0.25;
  /// GNSS antenna position in the INS body frame (forward-left-up, metres, from the INS reference
  /// point). When set, omega x l (omega from the INS attitude rates over [t - 2h, t]) is subtracted
  /// from the antenna velocity. When unset (default), the straight-line gate is what protects.
  std::optional<Eigen::Vector3d> lever_arm_body_m;
  /// Converged when both sigmas are below this (rad) with at least min_samples epochs used.
  /// Defaults 0.02 deg and 100 epochs.
  double converged_sigma_rad = 0.02 * kDegToRad;
  uint64_t min_samples = 100;
  /// Floor of the residual standard deviation (m/s, > 0), so a few lucky residuals cannot claim
  /// precision. Default 0.005.
  double residual_std_floor_mps = 0.005;
  /// Longest INS gap across which attitude is interpolated (s). Default 1.
  double max_bracket_s = 1.0;

  /// Outlier gate. Each epoch enters both regressions with weight phi^2 = V_forward^2, so a single
  /// wrong GNSS velocity (a receiver glitch of 30 m/s, a row of 1e6 m/s) would own the estimate and
  /// still look converged. The same three tests as the sample builder's gates (sample_builder.hpp),
  /// applied to the body-frame velocity V_b of the epoch:
  ///  1. physical limit: V_b not finite, or its horizontal GNSS speed above max_speed_mps;
  ///  2. speed jump (works before any estimate): |V_forward - V_forward of the last used epoch| above
  ///     max_acceleration_mps2 * dt + speed_jump_margin_mps, the reference used only if at most
  ///     speed_jump_reference_max_age_s old;
  ///  3. innovation, once innovation_min_samples epochs were used: for the left and the up
  ///     regression, |y - theta phi| > innovation_n_sigma * sqrt(s^2 + (sigma_theta phi)^2)
  ///     + tan(innovation_angle_margin_rad) * phi, with s = max(residual std, GNSS velocity sigma)
  ///     (the row's vel_std_mps, else gnss_velocity_sigma_mps) and sigma_theta the regression's
  ///     one-sigma. The angle margin lets side slip in gentle curves through. After
  ///     innovation_max_consecutive_rejections rejections in a row the estimate is presumed wrong
  ///     (an early outlier got in) and the innovation test is suspended until an epoch passes it.
  /// Defaults: 100 m/s (as the odometer pulse-jump gate), 6 m/s^2, 1 m/s, 1 s, 5 epochs, 5 sigma,
  /// 0.1 m/s, 1 deg, 50 epochs. 5 epochs, as a provisional estimate (consumer_rules.hpp), and not
  /// more: the gate's own sigma_theta term keeps it wide while the estimate is young, and at 1 Hz
  /// GNSS 20 epochs were the first half minute, open to any sideways error (terrain seed 8 at 1 Hz:
  /// one at about 25 s kept the heading 0.03 deg off and unconverged for the whole drive).
  bool outlier_gate_enabled = true;
  double max_speed_mps = 100.0;
  double max_acceleration_mps2 = 6.0;
  double speed_jump_margin_mps = 1.0;
  double speed_jump_reference_max_age_s = 1.0;
  uint64_t innovation_min_samples = 5;
  double innovation_n_sigma = 5.0;
  double gnss_velocity_sigma_mps = 0.1;
  double innovation_angle_margin_rad = 1.0 * kDegToRad;
  int innovation_max_consecutive_rejections = 50;

  /// Braking to a standstill (braking_stop.hpp), classified by V_b,forward at each epoch: when a
  /// braking ends in a standstill, the regressions go back to their sums from before the speed
  /// started to fall. A braking vehicle pitches on its suspension (nose down), so V_up of its
  /// epochs measures the dive, not the odometer axis; and a drive that ends on them leaves them
  /// with the most recent say in a short calibration. A braking that ends moving keeps its epochs.
  BrakingStopParams braking_stop;
};

enum class CalibrationState {
  kWaiting,      ///< no epoch used yet (or no INS at all).
  kCalibrating,  ///< estimating, not converged.
  kConverged,    ///< both sigmas below the threshold with enough samples.
  kFrozen,       ///< values held by freeze(); epochs are not used.
};
const char* to_string(CalibrationState state);

/// What happened to one GNSS epoch.
enum class CalibrationEpochStatus {
  kUsed,        ///< entered both regressions.
  kNoIns,       ///< use_ins is false: calibration impossible.
  kInvalidFix,  ///< GNSS fix 0, 6, 7 or 8 (not a measured fix).
  kNoAttitude,  ///< no INS attitude can be interpolated at the epoch.
  kReversing,   ///< V_b,forward < 0.
  kLowSpeed,    ///< V_b,forward below min_speed_mps.
  kTurning,     ///< |yaw rate| above max_yaw_rate_rad_s.
  kFrozen,      ///< frozen: epoch not used.
  kOutlier,     ///< GNSS velocity failed the outlier gate (physical limit, speed jump or innovation).
};
const char* to_string(CalibrationEpochStatus status);

struct MisalignmentCounters {
  uint64_t epochs = 0;
  uint64_t used = 0;
  uint64_t no_ins = 0;
  uint64_t invalid_fix = 0;
  uint64_t no_attitude = 0;
  uint64_t reversing = 0;
  uint64_t low_speed = 0;
  uint64_t turning = 0;
  uint64_t frozen = 0;
  uint64_t outlier = 0;
  /// Epochs used while the innovation test was suspended (also counted in used).
  uint64_t innovation_suspended = 0;
  /// Brakings that ended in a standstill, and the used epochs they withdrew (still in used).
  uint64_t braking_stops = 0;
  uint64_t braking_withdrawn = 0;
};

/// One output per GNSS epoch.
struct MisalignmentOutput {
  double t_s = 0.0;
  CalibrationState state = CalibrationState::kWaiting;
  CalibrationEpochStatus epoch_status = CalibrationEpochStatus::kUsed;
  Misalignment misalignment;  ///< current estimate (rad); zero until an epoch is used.
  double sigma_heading_rad = std::numeric_limits<double>::infinity();  ///< one-sigma of a_h.
  double sigma_pitch_rad = std::numeric_limits<double>::infinity();    ///< one-sigma of a_p.
  uint64_t samples_used = 0;
  bool converged = false;
  /// Why the state is what it is, in words (e.g. "no INS: the misalignment needs the INS attitude").
  std::string reason;
};

/// What the Misalignment topic carries of an output (the calibration node publishes it, odonav-offline
/// hands it to the consumers): the angles, the one-sigmas (-1 when not finite), converged and the
/// epochs used.
PublishedMisalignment published_misalignment(const MisalignmentOutput& output);

/// The misalignment.csv row of an output (odonav/results/output_files.hpp): what odonav-offline
/// writes, and what the calibration node publishes through the topic's field table
/// (odonav/dds/output_messages.hpp), so the file of either transport holds the same values.
results::MisalignmentRow output_row(const MisalignmentOutput& output);

/// The calibration's inputs (event_time_aligner.hpp ComponentInput): GNSS, and the INS with use_ins.
std::vector<ComponentInput> calibration_inputs(const MisalignmentCalibratorParams& params);

class MisalignmentCalibrator {
 public:
  /// Throws std::invalid_argument naming the parameter when params are out of range.
  explicit MisalignmentCalibrator(const MisalignmentCalibratorParams& params = {});

  /// Streams, each in strictly increasing time; throw StreamInputError on bad input.
  void add_gnss(const GnssSample& sample);
  void add_ins(const InsSample& sample);  ///< ignored when use_ins is false.

  /// Processes every buffered GNSS epoch stamped <= watermark_s whose attitude is final.
  std::vector<MisalignmentOutput> process_until(double watermark_s);
  /// End of data: processes everything left.
  std::vector<MisalignmentOutput> finish();

  /// Holds the current values; later epochs are not used until unfreeze().
  void freeze();
  void unfreeze();
  /// Forgets all samples (state waiting); counters are kept.
  void reset();

  /// The current estimate, as the last output would carry it (t_s is that of the last epoch).
  MisalignmentOutput current() const;
  const MisalignmentCounters& counters() const { return counters_; }

  /// The state a restarted calibration needs to continue exactly (calibration_checkpoint.hpp;
  /// checkpoint_state.hpp, every double exact): both regressions' sums and residual correlations,
  /// the used-epoch count, the gates' state (speed-jump reference, consecutive innovation
  /// rejections), frozen, the last epoch's time, the counters, the motion phase and the braking
  /// snapshot. Not the buffered samples: after a restore the INS from restore_margin_s() before the
  /// last epoch and the GNSS after it are fed again.
  StateJson save_state() const;
  /// Restores save_state()'s state into this calibrator, which must have been made with the same
  /// parameters (the checkpoint's configuration hash says so) and fed nothing yet. Throws
  /// std::runtime_error (CheckpointError) naming the field when it is not a state of this version;
  /// the calibrator is unchanged then.
  void restore_state(const StateJson& state);
  /// How long before a restored epoch (s) the INS must be fed again for the next epochs' attitude
  /// and yaw-rate windows: the window (2h) plus the longest bracket interpolated across.
  double restore_margin_s() const { return 2.0 * params_.yaw_rate_half_window_s + params_.max_bracket_s; }

 private:
  struct Regression {
    double sum_phi2 = 0.0, sum_phi_y = 0.0, sum_y2 = 0.0;
    double theta() const { return sum_phi2 > 0.0 ? sum_phi_y / sum_phi2 : 0.0; }
    double residual_sum_squares() const;
    template <class Archive, class Self>  // checkpoint fields (checkpoint_state.hpp)
    static void state_fields(Archive& a, Self& s) {
      a("sum_phi2", s.sum_phi2)("sum_phi_y", s.sum_phi_y)("sum_y2", s.sum_y2);
      a.check("sum_phi2", s.sum_phi2 >= 0.0 && std::isfinite(s.sum_phi2), "is negative or not finite");
      a.check("sum_phi_y", std::isfinite(s.sum_phi_y), "is not finite");
      a.check("sum_y2", s.sum_y2 >= 0.0 && std::isfinite(s.sum_y2), "is negative or not finite");
    }
  };
  // The calibrator's checkpoint fields, listed once for save_state() and restore_state().
  friend struct odonav::StateAccess;  // save_fields() and restored_copy() reach state_fields
  template <class Archive, class Self>
  static void state_fields(Archive& a, Self& self);
  MisalignmentOutput process_epoch(const GnssSample& gnss);
  /// Tests 2 and 3 of the outlier gate (the physical limit is tested first, in process_epoch): true when the epoch's body velocity v_b (m/s)
  /// must not enter the regressions. Updates the consecutive-rejection count.
  bool is_outlier(const GnssSample& gnss, const Eigen::Vector3d& v_b);
  /// One-sigma of theta (dimensionless) and the residual scale s (m/s) of a regression.
  struct RegressionSpread {
    double residual_std_mps;
    double sigma_theta;
  };
  RegressionSpread spread(const Regression& r) const;
  /// The published one-sigma of theta (dimensionless): see the top of this file.
  double published_sigma_theta(const Regression& r, const ResidualCorrelationTracker& correlation) const;
  static constexpr double kPriorResidualEpochs = 3.0;
  /// The braking-to-a-standstill rule for an epoch with forward speed speed_mps (NaN: none),
  /// before the epoch's own gates (braking_stop.hpp).
  void track_braking_stop(double t_s, double speed_mps);

  MisalignmentCalibratorParams params_;
  AttitudeBuffer attitude_;
  std::deque<GnssSample> pending_gnss_;
  std::optional<double> last_gnss_t_s_;
  double watermark_s_ = -std::numeric_limits<double>::infinity();
  Regression heading_, pitch_;
  // The a-priori residuals' serial correlation of each regression (m/s), weight 1/50 per epoch. A
  // braking rollback keeps them: they describe the noise, not the estimate.
  static constexpr double kResidualCorrelationAlpha = 0.02;
  ResidualCorrelationTracker heading_correlation_{kResidualCorrelationAlpha};
  ResidualCorrelationTracker pitch_correlation_{kResidualCorrelationAlpha};
  uint64_t samples_used_ = 0;
  /// Last used epoch (the speed-jump reference): time (s) and forward speed (m/s).
  std::optional<std::pair<double, double>> last_used_forward_;
  int consecutive_innovation_rejections_ = 0;
  bool innovation_suspended_now_ = false;
  bool frozen_ = false;
  double last_t_s_ = 0.0;
  MisalignmentCounters counters_;
  MotionPhaseTracker motion_;
  /// The regressions when the current braking began, and the epochs used since; none while driving.
  struct BrakingSnapshot {
    Regression heading, pitch;
    uint64_t samples_used = 0;
    std::optional<std::pair<double, double>> last_used_forward;
    int consecutive_innovation_rejections = 0;
    uint64_t used_since = 0;
    template <class Archive, class Self>
    static void state_fields(Archive& a, Self& s) {
      a("heading", s.heading)("pitch", s.pitch)("samples_used", s.samples_used)(
          "last_used_forward", s.last_used_forward)("consecutive_innovation_rejections",
                                                    s.consecutive_innovation_rejections)("used_since", s.used_since);
      a.check("consecutive_innovation_rejections", s.consecutive_innovation_rejections >= 0, "is negative");
    }
  };
  std::optional<BrakingSnapshot> braking_snapshot_;
};

// body_rate_rad_s() lives in frames.hpp (the sample builder uses it too).

}  // namespace odonav::calibration
