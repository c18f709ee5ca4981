#include "odonav/dead_reckoning/dead_reckoning_health.hpp"

#include <cstdio>

#include "odonav/consumer_rules.hpp"

namespace odonav::dead_reckoning {

std::string held_span_text(HeldEstimate estimate, const HeldSpan& span) {
  const char* producer = estimate == HeldEstimate::kScaleFactor ? "identification" : "calibration";
  char buf[192];
  if (span.open)
    std::snprintf(buf, sizeof buf, "outputs since t=%.1f s use the %s of t=%.1f s held: %s silent", span.first_t_s,
                  to_string(estimate), span.estimate_epoch_s, producer);
  else
    std::snprintf(buf, sizeof buf, "outputs t=%.1f-%.1f s used the %s of t=%.1f s held: %s silent", span.first_t_s,
                  span.last_t_s, to_string(estimate), span.estimate_epoch_s, producer);
  return buf;
}

ComponentHealth dead_reckoning_health(const DeadReckoningHealthFacts& f) {
  using State = ComponentHealth::State;
  using Level = ComponentHealth::Level;
  ComponentHealth s;
  auto add = [&s](const std::string& r) { s.reason = s.reason.empty() ? r : s.reason + "; " + r; };
  if (!f.started) {
    s.state = State::kStarting;
    add("waiting for a valid GNSS fix to start from");
  }
  // K: the reason DR navigates with what it uses.
  if (f.k_commanded) {
    add("using commanded K");
  } else if (f.scale_factor_absent) {
    s.state = s.state == State::kStarting ? s.state : State::kDegraded;
    s.level = Level::kWarn;
    // Absent after being heard: the DR keeps the last identified K (it is not reset).
    add(f.k_applied > 0 ? "no identification: keeping the last identified K" : "using nominal K: no identification");
  } else if (!f.scale_factor_heard) {
    add("waiting for identification");
  } else if (f.k_applied == 0) {
    add("K not converged yet: using nominal K");
  }
  if (!f.k_source_note.empty() && f.now_s < f.k_source_changed_at_s + kDeadReckoningNoticeDuration_s)
    add(f.k_source_note);
  // Odometer pulse jumps (a counter glitch): WARN for a while after the last one, with the total.
  if (f.pulse_jumps_rejected > 0 && f.now_s < f.pulse_jumps_changed_at_s + kDeadReckoningNoticeDuration_s) {
    s.level = Level::kWarn;
    add("rejected " + std::to_string(f.pulse_jumps_rejected) + " odometer samples: pulse jump (counter glitch)");
  }
  // Outputs computed on a held estimate (event time, decided by the core): while it goes on, and a
  // while after, so a monitor polling at 1 Hz sees which outputs they were.
  auto held = [&](HeldEstimate e, const std::optional<HeldSpan>& span, double changed_at_s) {
    if (!span || !(span->open || f.now_s < changed_at_s + kDeadReckoningNoticeDuration_s)) return;
    s.level = Level::kWarn;
    add(held_span_text(e, *span));
  };
  held(HeldEstimate::kScaleFactor, f.held_k_span, f.held_k_changed_at_s);
  held(HeldEstimate::kMisalignment, f.held_misalignment_span, f.held_misalignment_changed_at_s);
  // Absent after some were applied: the DR keeps applying the last one (it is not reset).
  if (f.misalignment_absent && f.misalignments_applied > 0 && f.held_misalignment_t_s)
    add(held_misalignment_text(*f.held_misalignment_t_s, f.misalignment_silent_s));
  else if (f.misalignment_absent)
    add("using zero misalignment: no calibration");
  else if (f.misalignment_heard && f.misalignments_applied == 0)
    add("misalignment not converged yet: using zero");
  // The results contradict independent evidence (consistency_monitor.hpp): a wrong input, named.
  if (!f.inconsistency.empty()) {
    s.level = Level::kWarn;
    add("inconsistent: " + f.inconsistency);
  }
  if (f.pole_distance_m) {
    s.level = Level::kWarn;
    add(polar_heading_text(*f.pole_distance_m, f.pole_north));
  }
  // After a restart: what the restore did, the catch-up of the downtime, failed checkpoint writes.
  bool warn = s.level == Level::kWarn;
  apply_restart_notes(f, f.now_s, s.reason, warn);
  if (warn) s.level = Level::kWarn;
  return s;
}

}  // namespace odonav::dead_reckoning
