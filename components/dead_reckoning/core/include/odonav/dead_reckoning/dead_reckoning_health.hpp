#pragma once
// The dead-reckoning node's health decision, a pure function over the facts the node supplies
// (components/dead_reckoning/README.md, Health), as identification_health and calibration_health
// are for their components. Wall-clock times (now_s, *_at_s, s) are the node's steady clock; event
// times (t_s, s) are the stamps.
#include <cstdint>
#include <limits>
#include <optional>
#include <string>

#include "odonav/component_health.hpp"
#include "odonav/dead_reckoning/dead_reckoner.hpp"
#include "odonav/restart_policy.hpp"

namespace odonav::dead_reckoning {

/// How long (wall clock, s) health tells about an event (K source change, pulse jump): long enough
/// for a monitor polling at 1 Hz, or an operator, to see it.
inline constexpr double kDeadReckoningNoticeDuration_s = 30.0;

/// What the dead-reckoning node knows when it publishes Health (past its required inputs' checks).
struct DeadReckoningHealthFacts : RestartHealthNotes {
  double now_s = 0.0;                ///< wall clock (s)
  bool started = false;              ///< DeadReckoner::started(): a start fix was found
  bool k_commanded = false;          ///< ScaleFactorSelection::commanded()
  bool scale_factor_absent = false;  ///< the scale-factor input is declared absent
  bool scale_factor_heard = false;   ///< a ScaleFactor was received
  uint64_t k_applied = 0;            ///< identified K given to the DR
  std::string k_source_note;         ///< last K source change note ("" none)
  double k_source_changed_at_s = -std::numeric_limits<double>::infinity();  ///< wall clock (s)
  uint64_t pulse_jumps_rejected = 0;  ///< DeadReckonerCounters::pulse_jumps_rejected
  double pulse_jumps_changed_at_s = -std::numeric_limits<double>::infinity();  ///< wall clock (s)
  bool misalignment_absent = false;             ///< the misalignment input is declared absent
  bool misalignment_heard = false;              ///< a Misalignment was received
  uint64_t misalignments_applied = 0;           ///< misalignments given to the DR
  std::optional<double> held_misalignment_t_s;  ///< stamp of the last one given (event time, s)
  double misalignment_silent_s = 0.0;           ///< wall time since the calibration was last heard (s)
  /// DeadReckoner::last_held_span: the last outputs on a held K / misalignment, and when (wall
  /// clock, s) a held output was last made (the notice lasts kDeadReckoningNoticeDuration_s after).
  std::optional<HeldSpan> held_k_span;
  double held_k_changed_at_s = -std::numeric_limits<double>::infinity();
  std::optional<HeldSpan> held_misalignment_span;
  double held_misalignment_changed_at_s = -std::numeric_limits<double>::infinity();
  /// ConsistencyMonitor::reason(): the findings in force ("" none).
  std::string inconsistency;
  /// DeadReckoner::pole_distance_m() (m) and the pole's hemisphere: the DR is within
  /// kPolarHeadingRadiusM of a pole, where its heading is ill-defined (WARN while inside).
  std::optional<double> pole_distance_m;
  bool pole_north = true;
};

/// "outputs t=52.5-54.6 s used the K of t=52.4 s held: identification silent" (span closed), or
/// "outputs since t=52.5 s use the K of t=52.4 s held: identification silent" (open); the
/// misalignment's names the calibration.
std::string held_span_text(HeldEstimate estimate, const HeldSpan& span);

/// The dead-reckoning node's own health (components/dead_reckoning/README.md, Health): starting
/// until the start fix; the K in use (commanded, or why nominal / last identified); the K source
/// change note and the pulse-jump WARN, each for kDeadReckoningNoticeDuration_s after the event;
/// why the misalignment is zero; the last span of outputs on a held K / misalignment (WARN) while
/// it goes on and for kDeadReckoningNoticeDuration_s after. Pure: the same facts give the same answer.
ComponentHealth dead_reckoning_health(const DeadReckoningHealthFacts& facts);

}  // namespace odonav::dead_reckoning
