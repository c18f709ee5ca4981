#pragma once
// Online identification of the odometer scale factor K (ALGORITHM.md §2-3), middleware-free.
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
#include <string>
#include <vector>

#include "odonav/estimators.hpp"
#include "odonav/sample_builder.hpp"

namespace odonav {

struct IdentificationParams {
  SampleBuilderParams builder;
  ScaleFactorEstimatorParams estimator;
  /// Main estimator (published, used by the gate and by dead reckoning); see estimator_names().
  std::string estimator_name = "vff_lm_rls";
  /// Also run every other estimator on the same samples (for comparison; offline tool).
  bool run_all_estimators = false;
};

/// One output per processed GNSS epoch (the estimate after that epoch).
struct IdentificationOutput {
  double t_s = 0.0;
  EpochStatus epoch_status = EpochStatus::kInvalidFix;
  ScaleFactorEstimate main;                ///< the main estimator's estimate.
  /// Side-by-side estimates, in the order of IdentificationCore::estimator_names(); empty unless
  /// run_all_estimators.
  std::vector<ScaleFactorEstimate> all;
  uint64_t samples_accepted = 0;           ///< accepted regression samples so far.
  uint64_t samples_rejected = 0;           ///< gated-out epochs so far (not counting chain starts).
  bool frozen = false;                     ///< identification frozen by command: K held.
};

class IdentificationCore {
 public:
  /// Throws std::invalid_argument naming the parameter or the unknown estimator.
  explicit IdentificationCore(const IdentificationParams& params);

  void add_odometer(const OdometerSample& sample) { builder_.add_odometer(sample); }
  void add_gnss(const GnssSample& sample) { builder_.add_gnss(sample); }
  void add_ins(const InsSample& sample) { builder_.add_ins(sample); }
  /// Misalignment (rad) in force from t_s on.
  void add_misalignment(double t_s, const Misalignment& misalignment) { builder_.add_misalignment(t_s, misalignment); }

  /// Processes every GNSS epoch whose inputs are complete up to watermark_s (see sample_builder.hpp).
  std::vector<IdentificationOutput> process_until(double watermark_s);
  /// End of data.
  std::vector<IdentificationOutput> finish();

  /// Commands (applied from the next processed epoch on).
  void freeze() { frozen_ = true; }
  void unfreeze() { frozen_ = false; }
  /// Forgets every estimate and starts identifying again.
  void reset();

  const std::string& main_estimator_name() const { return params_.estimator_name; }
  /// Names of the side-by-side estimators (empty unless run_all_estimators).
  std::vector<std::string> estimator_names() const;
  const SampleBuilderCounters& builder_counters() const { return builder_.counters(); }
  /// The main estimator (e.g. for save_state/restore_state).
  ScaleFactorEstimator& main_estimator() { return *main_; }
  const ScaleFactorEstimator& main_estimator() const { return *main_; }

 private:
  IdentificationOutput on_epoch(const SampleBuilderEpoch& epoch);

  IdentificationParams params_;
  SampleBuilder builder_;
  std::unique_ptr<ScaleFactorEstimator> main_;
  std::vector<std::unique_ptr<ScaleFactorEstimator>> all_;
  uint64_t accepted_ = 0;
  uint64_t rejected_ = 0;
  bool frozen_ = false;
};

}  // namespace odonav
