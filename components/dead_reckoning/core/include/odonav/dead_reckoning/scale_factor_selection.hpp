#pragma once
// Which K dead reckoning navigates with: the policy of
// odonav-dead-reckoning, without middleware, so its node only converts messages and calls this
// (docs/ALGORITHM.md §4 for the DR itself, docs/DDS.md for the topics).
//
// K sources, in order of precedence:
//   commanded  set_commanded_k() (COMMAND_SET_K) latches an operator's K; identified K is ignored
//              until release_commanded_k() (COMMAND_RELEASE_K), after which the next applicable
//              identified K is used again;
//   identified a ScaleFactor that consumer_rules.hpp says is applicable (valid, and converged or
//              provisionally better than the nominal K: 3 sigma away from it, or its sigma below
//              the nominal's; or of the same source as the identified K in force: a later
//              estimate of the same instance replaces it),
//              stamped after every K already given to the DR (event time, s);
//   nominal    DeadReckonerParams::nominal_k_m_per_pulse until one of the above arrives.
// Every K handed out is stamped strictly after the previous one, so DeadReckoner::add_scale_factor
// never sees time go back.
//
// Wall-clock times (now_s, s) are the node's steady clock; event times (t_s, s) are the stamps.
#include <cstdint>
#include <limits>
#include <optional>
#include <string>

#include "odonav/dead_reckoning/dead_reckoner.hpp"

namespace odonav::dead_reckoning {

/// A K to give DeadReckoner::add_scale_factor: in force from t_s (event time, s) on.
struct ScaleFactorUpdate {
  double t_s = 0.0;
  double k_m_per_pulse = 0.0;
  ScaleFactorSource source = ScaleFactorSource::kNominal;
};

/// One ScaleFactor as received, in core units.
struct IdentifiedScaleFactor {
  double t_s = 0.0;            ///< event time of the estimate (its stamp, s)
  double k_m_per_pulse = 0.0;  ///< 0 or not finite: no value yet (the message has no "valid" flag)
  bool converged = false;
  std::string source;               ///< publishing identification instance (ScaleFactor.source)
  double sigma_m_per_pulse = -1.0;  ///< one-sigma of K (m/pulse); -1 = unknown
  uint64_t samples_accepted = 0;    ///< samples the identification accepted so far
};

/// Answer to a command: accepted or rejected, with the text the Health acknowledgement carries.
struct ScaleFactorCommandResult {
  bool accepted = false;
  std::string detail;
  std::optional<ScaleFactorUpdate> update;  ///< the K to give the DR now (set_commanded_k accepted)
};

struct ScaleFactorSelectionCounters {
  uint64_t k_applied = 0;         ///< identified K given to the DR
  uint64_t k_ignored = 0;         ///< applicable identified K not used: commanded K latched, or not newer
  uint64_t k_source_changes = 0;  ///< changes of ScaleFactor.source after the first one
};

class ScaleFactorSelection {
 public:
  /// nominal_k_m_per_pulse: the DR's nominal K (m/pulse), the reference of the commanded-K range
  /// (consumer_rules.hpp commanded_k_problem; an invalid nominal makes every set_k rejected).
  /// nominal_k_rel_sigma: the nominal K's one-sigma relative to it (kDefaultNominalKRelSigma; 0 = unknown),
  /// against which an identified K's sigma is weighed (scale_factor_applicable).
  explicit ScaleFactorSelection(double nominal_k_m_per_pulse, double nominal_k_rel_sigma = kDefaultNominalKRelSigma)
      : nominal_k_m_per_pulse_(nominal_k_m_per_pulse), nominal_k_rel_sigma_(nominal_k_rel_sigma) {}

  /// A received ScaleFactor (now_s: wall clock, s). Tracks its source (logged; a change is counted
  /// and noted for kDeadReckoningNoticeDuration_s). Returns the K to give the DR when it is
  /// applicable, no K is commanded and it is stamped after the last K given; else nothing (an
  /// applicable one is counted as ignored).
  std::optional<ScaleFactorUpdate> on_identified(const IdentifiedScaleFactor& k, double now_s);

  /// COMMAND_SET_K with value k_m_per_pulse, processed_s = the event time processed so far (s; -inf
  /// before anything). Rejected, with "set_k: <commanded_k_problem>", outside [0.1, 10] x nominal K.
  /// Accepted: K latched, in force at nextafter(max(processed_s, last K stamp)), so after everything
  /// already processed and after the last K given (strictly increasing stamps).
  ScaleFactorCommandResult set_commanded_k(double k_m_per_pulse, double processed_s);
  /// COMMAND_RELEASE_K: identified K followed again from its next applicable estimate (always accepted).
  ScaleFactorCommandResult release_commanded_k();

  bool commanded() const { return state_.commanded; }
  /// Stamp of the last K given to the DR (event time, s), if any.
  std::optional<double> last_k_stamp_s() const { return state_.last_k_stamp_s; }
  /// ScaleFactor.source followed ("" before the first ScaleFactor).
  const std::string& k_source() const { return state_.k_source; }
  /// ScaleFactor.source of the identified K in force ("" while the nominal or a commanded K is):
  /// its later estimates replace it without having to beat the nominal K again.
  const std::string& in_force_source() const { return state_.in_force_source; }
  /// "K source changed from 'a' to 'b' at t=T s" of the last change ("" none), and when it happened
  /// (wall clock, s; -inf none).
  const std::string& k_source_note() const { return k_source_note_; }
  double k_source_changed_at_s() const { return k_source_changed_at_s_; }
  const ScaleFactorSelectionCounters& counters() const { return state_.counters; }

  /// What a checkpoint keeps (the source-change note is about the wall clock: not kept).
  struct State {
    bool commanded = false;
    std::optional<double> last_k_stamp_s;
    std::string k_source;
    std::string in_force_source;
    ScaleFactorSelectionCounters counters;
  };
  State state() const { return state_; }
  void restore_state(const State& s) { state_ = s; }

 private:
  void track_source(const std::string& source, double t_s, double now_s);

  double nominal_k_m_per_pulse_;
  double nominal_k_rel_sigma_;
  State state_;  ///< the selection's memory: what a checkpoint keeps
  std::string k_source_note_;
  double k_source_changed_at_s_ = -std::numeric_limits<double>::infinity();
};

/// When a count last changed (wall clock, s): the pulse-jump WARN window starts at each new total.
class CountChangeTime {
 public:
  /// The count as of now_s (wall clock, s).
  void observe(uint64_t count, double now_s) {
    if (count == count_) return;
    count_ = count;
    changed_at_s_ = now_s;
  }
  double changed_at_s() const { return changed_at_s_; }

 private:
  uint64_t count_ = 0;
  double changed_at_s_ = -std::numeric_limits<double>::infinity();
};

}  // namespace odonav::dead_reckoning
