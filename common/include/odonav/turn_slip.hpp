#pragma once
// Track slip in turns (docs/ALGORITHM.md §2, "Turn slip"). A skid-steered track slips whenever the
// vehicle turns: the odometer then counts more pulses per metre than on a straight, the more the
// sharper the turn. K is identified on intervals below the yaw-rate gate only (sample_builder.hpp,
// max_yaw_rate_rad_s), so whatever slip happens below that rate is inside K. Above it the model is
// first order in the yaw rate:
//
//   pulses per metre in a turn = (1 + s) x pulses per metre straight,
//   s = g * max(0, |yaw rate| - threshold)                      (dimensionless; g in s/rad)
//
// with the threshold = the yaw-rate gate. The identification estimates g from the intervals the
// yaw-rate gate keeps out of K (TurnSlipSample), by least squares against the K in force; the dead
// reckoning divides each distance increment by 1 + s at its own yaw rate (turn_slip_fraction).
//
// Regression: over an interval whose odometer steps i count n_i pulses at slip s_i, the GNSS
// distance is y = K sum n_i / (1 + s_i) ~ K (phi - g X), X = sum n_i max(0, |w_i| - threshold), so
// the residual against the K in force, r = y - K phi, is -K X g plus the sample's noise (velocity
// noise and pulse quantisation, regression_noise_variance_m2). Weighted least squares through zero;
// g is applied only once it is significant (|g| at least min_significance_sigmas of its sigma, from
// the residual scatter) over at least min_samples turns' samples: a vehicle that does not slip, or
// a drive without turns, keeps g = 0 and says why (TurnSlipEstimate::reason).
//
// Middleware-free, plain data; exact save/restore for the identification's checkpoint.
#include <cstdint>
#include <string>

#include "odonav/state_json.hpp"

namespace odonav {

/// One interval that the yaw-rate gate kept out of K (every other interval gate passed).
struct TurnSlipSample {
  double t_s = 0.0;         ///< end of the interval (GNSS epoch, event time, s)
  double dt_s = 0.0;        ///< interval length (s)
  double phi_pulses = 0.0;  ///< pulses counted over the interval
  double y_m = 0.0;         ///< distance from the GNSS velocity over the interval (m), as a K sample's
  /// X = sum over the interval's yaw-rate steps of the step's pulses times max(0, |yaw rate| -
  /// threshold) (pulses rad/s).
  double turn_pulses_radps = 0.0;
  double k_m_per_pulse = 0.0;  ///< the K estimate the residual is taken against (m/pulse)
  double sigma_y_m = 0.0;      ///< one-sigma of y - K phi from sensor noise alone (m)
};

struct TurnSlipParams {
  /// Samples needed before g may apply (>= 1). Default 30: about three turns at 10 Hz GNSS, and
  /// enough for the residual scatter to give g a meaningful sigma.
  uint64_t min_samples = 30;
  /// |g| / sigma_g needed before g applies (> 0). Default 3.
  double min_significance_sigmas = 3.0;
  /// A sample whose residual is further than this many noise sigmas plus max_slip_fraction of the
  /// distance from zero is a velocity outlier, not slip: dropped and counted. Defaults 5 and 0.1.
  double outlier_n_sigma = 5.0;
  double max_slip_fraction = 0.1;

  /// Throws std::invalid_argument naming the parameter.
  void validate() const;
};

/// The estimate after the samples so far.
struct TurnSlipEstimate {
  double g_s_per_rad = 0.0;       ///< least-squares slip gain (s/rad); 0 without samples
  double sigma_s_per_rad = -1.0;  ///< its one-sigma (s/rad); -1 = not enough samples for one
  uint64_t samples = 0;           ///< samples in the fit
  uint64_t outliers = 0;          ///< samples dropped as velocity outliers
  bool applies = false;           ///< significant: the dead reckoning applies g
  /// Why g does not apply, with the observed values ("" when it applies), e.g.
  /// "12 turn samples < 30" or "|g| = 0.004 s/rad < 3 sigma (sigma 0.006 s/rad)".
  std::string reason;
  /// The gain to apply: g when it applies, else 0 (s/rad).
  double applied_s_per_rad() const { return applies ? g_s_per_rad : 0.0; }
};

/// Slip fraction s at a yaw rate: g * max(0, |yaw_rate_radps| - threshold_radps), never below 0
/// nor above 0.5 (a guard against a wild rate; real slip is a few per cent). g in s/rad, rates in
/// rad/s; NaN inputs give 0.
double turn_slip_fraction(double g_s_per_rad, double threshold_radps, double yaw_rate_radps);

/// The gain dead reckoning applies from a published estimate (s/rad): g when it applies and is a
/// finite positive number, else 0. The DR node (from ScaleFactor) and odonav-offline both use it.
double turn_slip_gain_to_apply(bool applies, double g_s_per_rad);

class TurnSlipEstimator {
 public:
  /// Throws std::invalid_argument (TurnSlipParams::validate).
  explicit TurnSlipEstimator(const TurnSlipParams& params = {});

  /// One sample; ignored (not counted) when X, K or sigma_y are not positive and finite.
  void update(const TurnSlipSample& sample);
  TurnSlipEstimate estimate() const;

  /// The sums and counts (checkpoint_state.hpp, every double exact); restore_state throws
  /// CheckpointError naming the field and leaves the estimator unchanged then.
  StateJson save_state() const;
  void restore_state(const StateJson& state);

 private:
  friend struct odonav::StateAccess;  // save_fields() and restored_copy() reach state_fields
  template <class Archive, class Self>
  static void state_fields(Archive& a, Self& self);

  TurnSlipParams params_;
  // Weighted sums (weight 1 / sigma_y^2) of h^2, h r and r^2: h = -K X (m rad/s), r = y - K phi (m), so r = g h.
  double shh_ = 0.0;
  double shr_ = 0.0;
  double srr_ = 0.0;
  uint64_t samples_ = 0;
  uint64_t outliers_ = 0;
};

}  // namespace odonav
