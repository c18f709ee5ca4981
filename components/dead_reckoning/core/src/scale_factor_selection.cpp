#include "odonav/dead_reckoning/scale_factor_selection.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include <spdlog/spdlog.h>

#include "odonav/consumer_rules.hpp"

namespace odonav {

void ScaleFactorSelection::track_source(const std::string& source, double t_s, double now_s) {
  // Which identification instance is followed (the one the node's SourceArbiter hands on: the
  // highest-priority live instance): logged, and told in health for a while after a change (hot standby taking over,
  // the primary coming back).
  if (source == k_source_) return;
  if (k_source_.empty()) {
    spdlog::info("following K from '{}' (t={} s)", source, t_s);
  } else {
    ++counters_.k_source_changes;
    std::ostringstream note;
    note.precision(10);
    note << "K source changed from '" << k_source_ << "' to '" << source << "' at t=" << t_s << " s";
    spdlog::warn("{}", note.str());
    k_source_note_ = note.str();
    k_source_changed_at_s_ = now_s;
  }
  k_source_ = source;
}

std::optional<ScaleFactorUpdate> ScaleFactorSelection::on_identified(const IdentifiedScaleFactor& k, double now_s) {
  track_source(k.source, k.t_s, now_s);
  const bool valid = std::isfinite(k.k_m_per_pulse) && k.k_m_per_pulse > 0.0;
  if (!scale_factor_applicable(valid, k.converged, k.k_m_per_pulse, k.sigma_m_per_pulse, k.samples_accepted,
                               nominal_k_m_per_pulse_, !in_force_source_.empty() && k.source == in_force_source_))
    return std::nullopt;  // as odonav-offline
  if (commanded_ || (last_k_stamp_s_ && k.t_s <= *last_k_stamp_s_)) {
    ++counters_.k_ignored;
    return std::nullopt;
  }
  last_k_stamp_s_ = k.t_s;
  in_force_source_ = k.source;
  ++counters_.k_applied;
  return ScaleFactorUpdate{k.t_s, k.k_m_per_pulse, ScaleFactorSource::kIdentified};
}

ScaleFactorCommandResult ScaleFactorSelection::set_commanded_k(double k, double processed_s) {
  if (const auto problem = commanded_k_problem(k, nominal_k_m_per_pulse_)) return {false, "set_k: " + *problem, {}};
  // In force after everything already processed and after the last K given to the DR. Before
  // anything (processed_s = -inf, no K yet) the lowest finite time, so the stamp stays finite.
  double base = std::max(processed_s, last_k_stamp_s_.value_or(-std::numeric_limits<double>::infinity()));
  if (!std::isfinite(base)) base = -std::numeric_limits<double>::max();
  const double t_s = std::nextafter(base, std::numeric_limits<double>::infinity());
  last_k_stamp_s_ = t_s;
  commanded_ = true;
  in_force_source_.clear();  // after the release an identified K must again beat the nominal first
  std::ostringstream m;
  m.precision(10);
  m << "K = " << k << " m/pulse commanded (identified K ignored until release_k)";
  return {true, m.str(), ScaleFactorUpdate{t_s, k, ScaleFactorSource::kCommanded}};
}

ScaleFactorCommandResult ScaleFactorSelection::release_commanded_k() {
  commanded_ = false;
  return {true, "following the identified K again (from its next estimate)", std::nullopt};
}

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

DeadReckoningHealth dead_reckoning_health(const DeadReckoningHealthFacts& f) {
  using State = DeadReckoningHealthState;
  using Level = DeadReckoningHealthLevel;
  DeadReckoningHealth s;
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
  return s;
}

}  // namespace odonav
