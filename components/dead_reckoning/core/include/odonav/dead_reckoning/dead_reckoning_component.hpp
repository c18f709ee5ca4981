#pragma once
// odonav-dead-reckoning's processing without middleware: the dead reckoner (dead_reckoner.hpp), the
// GNSS-anchored navigation position (anchored_position.hpp) and every rule about the estimates it
// consumes (consumer_rules.hpp: the hold-off, which misalignment and K apply, the GNSS latency and
// the turn slip each ScaleFactor carries; scale_factor_selection.hpp: which K is in force). The DDS
// node converts messages and calls this class; odonav-offline calls it with the producers' outputs
// converted by the same functions their nodes publish from, so both decide alike.
//
// Event time throughout (s, the data's stamps); now_s arguments are a wall clock used only for the
// health notes. Not thread-safe: its owner calls it one task at a time.
#include <cstdint>
#include <optional>
#include <vector>

#include "odonav/dead_reckoning/anchored_position.hpp"
#include "odonav/dead_reckoning/consistency_monitor.hpp"
#include "odonav/dead_reckoning/dead_reckoner.hpp"
#include "odonav/dead_reckoning/dead_reckoning_checkpoint.hpp"
#include "odonav/dead_reckoning/scale_factor_selection.hpp"
#include "odonav/event_time_aligner.hpp"
#include "odonav/published_estimates.hpp"

namespace odonav::dead_reckoning {

/// One output of dead reckoning as it is published: the DR output, the anchored position at the
/// same time, and the misalignment (rad) that was in force for it.
struct DeadReckoningStep {
  DeadReckoningOutput output;
  AnchoredPosition navigation;
  Misalignment misalignment;
  /// ConsistencyMonitor::consistent() after this output: false while the results contradict
  /// independent evidence (monitor().reason() says how).
  bool consistent = true;
};

/// Dead reckoning's inputs (event_time_aligner.hpp ComponentInput): the odometer, GNSS as the
/// reference applied after the hold-off, the misalignment and scale-factor estimates paced by the
/// GNSS epochs with the same hold-off, and the INS with use_ins.
std::vector<ComponentInput> dead_reckoning_inputs(const DeadReckonerParams& params);

class DeadReckoningComponent {
 public:
  /// Throws std::invalid_argument naming the parameter when params are out of range. navigation:
  /// false when nobody reads the anchored position (publish() then leaves it at its default and
  /// spends nothing on it).
  DeadReckoningComponent(const DeadReckonerParams& params, const AnchoredPositionParams& anchored,
                         bool navigation = true, const ConsistencyParams& consistency = {});

  /// Sensor samples, each stream in increasing time (DeadReckoner::add_*; StreamInputError on bad input).
  OdometerAddResult add_odometer(const OdometerSample& sample) { return core_.add_odometer(sample); }
  void add_ins(const InsSample& sample) { core_.add_ins(sample); }
  void add_gnss(const GnssSample& sample) {
    core_.add_gnss(sample);
    monitor_.add_gnss(sample);
  }

  /// A misalignment of the calibration: received (the held-estimate report), and in force from
  /// estimate_applies_from_s(epoch, hold-off) when misalignment_applicable. Throws StreamInputError
  /// when an applicable estimate's angles are not finite (nothing is applied then).
  void on_misalignment(const PublishedMisalignment& misalignment);
  /// A scale factor of an identification instance: received; the GNSS latency (finite, |.| < 10 s)
  /// and the turn slip it carries (threshold finite and >= 0) in force from its application time;
  /// its K given to the dead reckoner when ScaleFactorSelection takes it. now_s: wall clock (s).
  void on_scale_factor(const PublishedScaleFactor& scale_factor, double now_s);
  /// Operator commands (ScaleFactorSelection); an accepted set_k is given to the dead reckoner.
  /// processed_s: the event time processed so far (s).
  ScaleFactorCommandResult set_commanded_k(double k_m_per_pulse, double processed_s);
  ScaleFactorCommandResult release_commanded_k() { return consumer_.k_selection.release_commanded_k(); }

  /// The outputs of every odometer sample whose inputs are complete up to watermark_s (the contract of
  /// DeadReckoner::process_until: every input applying at or before watermark_s has been given).
  std::vector<DeadReckoningOutput> process_until(double watermark_s) { return core_.process_until(watermark_s); }
  std::vector<DeadReckoningOutput> finish() { return core_.finish(); }
  /// The published form of an output: its anchored position (the filter steps through it) and the
  /// misalignment in force. Call once per output to publish, in time order.
  DeadReckoningStep publish(DeadReckoningOutput output);

  const DeadReckoner& core() const { return core_; }
  const AnchoredPositionFilter& anchor() const { return anchor_; }
  const DeadReckoningConsumerState& consumer() const { return consumer_; }
  const ScaleFactorSelection& k_selection() const { return consumer_.k_selection; }
  /// The checks of the results against independent evidence (not part of the checkpoint: after a
  /// restart they gather their evidence anew).
  const ConsistencyMonitor& monitor() const { return monitor_; }
  /// The state a checkpoint saves and restores.
  DeadReckoningStateRefs state() { return {core_, anchor_, consumer_}; }

 private:
  double hold_off_s_;
  bool navigation_;
  DeadReckoner core_;
  AnchoredPositionFilter anchor_;
  DeadReckoningConsumerState consumer_;
  ConsistencyMonitor monitor_;
};

}  // namespace odonav::dead_reckoning
