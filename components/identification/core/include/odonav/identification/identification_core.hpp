#pragma once
// Online identification of the odometer scale factor K (docs/ALGORITHM.md §2-3), middleware-free.
//
// Inputs (each stream in increasing event time): odometer, GNSS, INS attitude, misalignment.
// Per GNSS epoch the sample builder makes (or gates out) a regression sample y = K·phi; accepted
// samples feed the main estimator and, optionally, every other estimator side by side (all of them
// see exactly the same samples, gated with the main estimator's K). The main estimator's K, stamped
// with the sample time, is fed back to the builder's innovation gate from inside the epoch callback,
// so the result depends on time stamps only, however the inputs are chunked or interleaved. This is
// what makes the DDS node and odonav-offline give identical numbers.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "odonav/braking_stop.hpp"
#include "odonav/defaults.hpp"
#include "odonav/estimators.hpp"
#include "odonav/event_time_aligner.hpp"
#include "odonav/published_estimates.hpp"
#include "odonav/results/output_files.hpp"
#include "odonav/sample_builder.hpp"

namespace odonav::identification {

struct IdentificationParams {
  SampleBuilderParams builder;
  ScaleFactorEstimatorParams estimator;
  /// Main estimator (published, used by the gate and by dead reckoning); see estimator_names().
  std::string estimator_name = "vff_lm_rls";
  /// Also run every other estimator on the same samples (for comparison; offline tool).
  bool run_all_estimators = false;
  /// Hold-off d (s, >= 0) of the estimate-application rule (consumer_rules.hpp): the misalignment of
  /// epoch g is added (by the node and by odonav-offline) as in force from
  /// estimate_applies_from_s(g, d), so K of epoch g uses the misalignment of the epochs <= g - d and
  /// never waits for calibration's output of its own epoch.
  double estimate_hold_off_s = kDefaultEstimateHoldOff_s;
  /// Track slip in turns (turn_slip.hpp): estimated from the intervals the yaw-rate gate keeps out
  /// of K and published for dead reckoning. turn_slip_enabled false: no estimate, g = 0 published.
  bool turn_slip_enabled = true;
  TurnSlipParams turn_slip;
  /// Braking to a standstill (braking_stop.hpp): the estimators go back to their state from before
  /// the speed started to fall when the braking ends in a standstill, so the K a drive stops with is
  /// not the braking's. The GNSS latency search and the turn slip keep what they learnt.
  BrakingStopParams braking_stop;
};

/// What braking to a standstill withdrew (braking_stop.hpp), over the run.
struct BrakingStopCounters {
  uint64_t stops = 0;              ///< brakings that ended in a standstill and were withdrawn.
  uint64_t samples_withdrawn = 0;  ///< accepted samples of those brakings (still in samples_accepted).
};

/// One output per processed GNSS epoch (the estimate after that epoch).
struct IdentificationOutput {
  double t_s = 0.0;
  EpochStatus epoch_status = EpochStatus::kInvalidFix;
  /// The main estimator's estimate as published: sigma and converged are honest_estimate's (below);
  /// the estimator and the innovation gate keep its own.
  ScaleFactorEstimate main;
  /// Side-by-side estimates, in the order of IdentificationCore::estimator_names(); empty unless
  /// run_all_estimators.
  std::vector<ScaleFactorEstimate> all;
  uint64_t samples_accepted = 0;  ///< accepted regression samples so far.
  uint64_t samples_rejected = 0;  ///< gated-out epochs so far (not counting chain starts).
  bool frozen = false;            ///< identification frozen by command: K held.
  GnssLatencyEstimate latency;    ///< the GNSS latency in force after this epoch.
  /// main.k_m_per_pulse is the latency search's K of the drive's start (SampleBuilder::
  /// start_latency_k), not the estimator's: before the estimate converges and before any latency
  /// is decided, while the data show a latency clearly off the one in force.
  bool k_from_start_latency = false;
  /// Track slip in turns after this epoch (turn_slip.hpp) and the yaw rate (rad/s) above which it
  /// applies (the yaw-rate gate: below it any slip is inside K).
  TurnSlipEstimate turn_slip;
  double turn_slip_threshold_radps = 0.0;
  /// The epoch's motion phase (braking_stop.hpp) and the withdrawals so far.
  MotionPhase motion_phase = MotionPhase::kUnknown;
  BrakingStopCounters braking_stop;
  /// The GNSS latency in force is decided (SampleBuilder::latency_decided): before, main is never
  /// converged.
  bool latency_decided = false;
};

/// The GNSS latency's least-squares sigmas (s) widened by the K samples' residual correlation
/// factor (ScaleFactorEstimate::correlation_factor, >= 1): the latency is fitted to the same
/// samples as K, whose neighbours share a GNSS velocity, so its plain sigma counts too many
/// independent residuals, as K's does. Estimates are untouched; a fixed latency keeps sigma 0.
void widen_latency_sigma(GnssLatencyEstimate& latency, double correlation_factor);

/// What K's published sigma and converged say (docs/ALGORITHM.md "Honest sigma of K"): the
/// estimator's own sigma (the scatter of its residuals) says nothing of what all its samples share,
/// so the published one-sigma is
///   sigma = sqrt(max(f * sigma_own, sigma_lag)^2 + (dK/dlatency * u_latency)^2)
/// with f the serial-correlation factor of the residuals (own.correlation_factor), sigma_lag the
/// lag after a detected change (own.lag_sigma_m_per_pulse), dK/dlatency
/// (own.dk_dlatency_m_per_pulse_per_s) and u_latency the uncertainty (s) of the latency in force
/// (SampleBuilder::latency_in_force_uncertainty_s, its sigmas times f); converged = own.converged
/// and the latency decided and sigma / |K| < converged_rel_sigma. Unchanged when own has no value
/// or no sigma.
ScaleFactorEstimate honest_estimate(const ScaleFactorEstimate& own, double latency_uncertainty_s, bool latency_decided,
                                    double converged_rel_sigma);

/// What the ScaleFactor topic carries of an output for its consumers (the identification node
/// publishes it, odonav-offline hands it to dead reckoning): the main estimate (K 0 and sigma -1
/// while it has no value; sigma -1 when not finite and > 0), the latency in force and the turn slip.
/// source: the publishing instance's name.
PublishedScaleFactor published_scale_factor(const IdentificationOutput& output, const std::string& source);

/// The scale_factor.csv row of an output (odonav/results/output_files.hpp): the main estimate as
/// the topic carries it (K, its sigma and converged only while K has a value, as
/// published_scale_factor), with the k_<name> column of each estimator in `names` (every estimator
/// run side by side, odonav-offline) or, when `names` is empty, of the main one alone (the node).
/// What odonav-offline writes, and what the identification node publishes through the topic's field
/// table (odonav/dds/output_messages.hpp).
results::ScaleFactorRow output_row(const IdentificationOutput& output, const std::string& main_estimator,
                                   const std::vector<std::string>& names);

/// The identification's inputs (event_time_aligner.hpp ComponentInput): odometer and GNSS, the
/// misalignment estimates paced by the GNSS epochs and applied after the hold-off, and the INS with
/// use_ins.
std::vector<ComponentInput> identification_inputs(const IdentificationParams& params);

class IdentificationCore {
 public:
  /// Throws std::invalid_argument naming the parameter or the unknown estimator.
  explicit IdentificationCore(const IdentificationParams& params);

  void add_odometer(const OdometerSample& sample) { builder_.add_odometer(sample); }
  void add_gnss(const GnssSample& sample) { builder_.add_gnss(sample); }
  void add_ins(const InsSample& sample) { builder_.add_ins(sample); }
  /// Misalignment (rad) in force from t_s on.
  void add_misalignment(double t_s, const Misalignment& misalignment) { builder_.add_misalignment(t_s, misalignment); }
  /// A published misalignment, applied by the consumer rule (consumer_rules.hpp,
  /// misalignment_applicable) in force from estimate_applies_from_s(its epoch, params'
  /// estimate_hold_off_s): K of epoch g never waits for the calibration of epoch g. Returns whether it
  /// was applied. Throws StreamInputError when an applicable estimate's angles are not finite.
  bool apply_misalignment(const PublishedMisalignment& misalignment);

  /// Processes every GNSS epoch whose inputs are complete up to watermark_s (see sample_builder.hpp).
  std::vector<IdentificationOutput> process_until(double watermark_s);
  /// End of data.
  std::vector<IdentificationOutput> finish();

  /// Commands (applied from the next processed epoch on).
  void freeze() { frozen_ = true; }
  void unfreeze() { frozen_ = false; }
  /// Forgets every estimate and starts identifying again.
  void reset();

  /// Why a commanded K [m/pulse] is refused, or nothing when it is acceptable: it must be finite,
  /// > 0 and within [0.1, 10] x nominal_k_m_per_pulse (nominal: finite, > 0). A K outside that
  /// range is a typing error (a unit slip), not an odometer: the identification would take many
  /// windows to recover from it.
  static std::optional<std::string> commanded_k_problem(double k_m_per_pulse, double nominal_k_m_per_pulse);
  /// Re-seeds the identification at a commanded K [m/pulse] (finite, > 0; else
  /// std::invalid_argument naming the value), event time t_s [s] (the last processed epoch, finite):
  /// every estimator forgets its window and sums (start covariance, as after reset()) and is given
  /// one seed pseudo-sample phi = 1 pulse, y = K m at t_s. That is the weakest prior there is: K is
  /// exactly the commanded value until the first real sample, the first real samples outweigh it
  /// within one (phi is tens of pulses per GNSS interval) and it leaves the window like any sample.
  /// The coarse estimator takes no pseudo-samples: it reports the commanded K until its first
  /// counted run. The innovation gate uses the commanded K from the next epoch on. Counters
  /// (accepted, rejected) are kept; frozen stays as it was, so a frozen identification holds the
  /// commanded K. Returns the output to publish at once (stamp t_s, the commanded K).
  IdentificationOutput set_k(double k_m_per_pulse, double t_s);
  /// The K given by the last set_k(), until reset() (nothing before any).
  std::optional<double> commanded_k_m_per_pulse() const { return seed_k_m_per_pulse_; }

  const std::string& main_estimator_name() const { return params_.estimator_name; }
  /// Names of the side-by-side estimators (empty unless run_all_estimators).
  std::vector<std::string> estimator_names() const;
  const SampleBuilderCounters& builder_counters() const { return builder_.counters(); }
  const BrakingStopCounters& braking_stop_counters() const { return braking_stop_counters_; }
  /// The track slip in turns so far (turn_slip.hpp; "off" or "no INS" as its reason when not estimated)
  /// and the yaw rate (rad/s) beyond which it applies (the yaw-rate gate).
  TurnSlipEstimate turn_slip_estimate() const;
  double turn_slip_threshold_radps() const { return params_.builder.max_yaw_rate_rad_s; }
  /// The GNSS latency in force and its online estimate (sample_builder.hpp), with the sigmas
  /// widened as published (widen_latency_sigma).
  GnssLatencyEstimate latency() const;
  /// The main estimator.
  ScaleFactorEstimator& main_estimator() { return *main_; }
  const ScaleFactorEstimator& main_estimator() const { return *main_; }

  /// The complete state (checkpoint_state.hpp, every double exact): the sample builder (inputs
  /// taken in and not processed yet, the sample chain, the gates' references, the GNSS latency and
  /// its sums), every estimator, the counters, frozen, the commanded K and the gate's last stamp. A
  /// core made with the same parameters and given restore_state(save_state()) produces exactly the
  /// outputs this one would, provided the inputs it had taken in are not added again (a component
  /// checkpoint).
  StateJson save_state() const;
  /// Throws CheckpointError (checkpoint_state.hpp) naming the field when the state is not one of a
  /// core with these parameters; the core is unchanged then.
  void restore_state(const StateJson& state);

 private:
  IdentificationOutput on_epoch(const SampleBuilderEpoch& epoch);
  /// The main estimate, or the commanded K while an estimator without pseudo-samples (coarse) has
  /// no value of its own since set_k().
  ScaleFactorEstimate main_estimate() const;
  void feed_gate(double t_s, const ScaleFactorEstimate& estimate);
  /// identification::honest_estimate with the params' converged_rel_sigma.
  ScaleFactorEstimate honest_estimate(const ScaleFactorEstimate& own, double latency_uncertainty_s,
                                      bool latency_decided) const;
  /// The braking-to-a-standstill rule for one epoch (braking_stop.hpp), before its sample is fed.
  void track_braking_stop(const SampleBuilderEpoch& epoch, MotionPhase phase);

  IdentificationParams params_;
  SampleBuilder builder_;
  std::unique_ptr<ScaleFactorEstimator> main_;
  std::vector<std::unique_ptr<ScaleFactorEstimator>> all_;
  TurnSlipEstimator turn_slip_;
  uint64_t accepted_ = 0;
  uint64_t rejected_ = 0;
  bool frozen_ = false;
  std::optional<double> seed_k_m_per_pulse_;  ///< commanded K of the last set_k() (m/pulse)
  std::optional<double> last_gate_t_s_;       ///< stamp of the last estimate given to the gate (s)
  MotionPhaseTracker motion_;
  /// The estimators' states (main, then side by side) when the current braking began, and the
  /// samples accepted since; none while driving.
  /// The estimators' states are shared, immutable, between copies of the core; null for an
  /// estimator that does not withdraw brakings.
  struct BrakingSnapshot {
    std::shared_ptr<const StateJson> main;
    std::vector<std::shared_ptr<const StateJson>> all;
    uint64_t used_since = 0;
    template <class Archive, class Self>  // checkpoint fields (checkpoint_state.hpp)
    static void state_fields(Archive& a, Self& s) {
      a("main", s.main)("all", s.all)("samples", s.used_since);
    }
  };
  std::optional<BrakingSnapshot> braking_snapshot_;
  BrakingStopCounters braking_stop_counters_;

  // The core's checkpoint fields, listed once for save_state() and restore_state().
  friend struct odonav::StateAccess;  // save_fields() and restored_copy() reach state_fields
  template <class Archive, class Self>
  static void state_fields(Archive& a, Self& self);
};

}  // namespace odonav::identification
