#include "odonav/dead_reckoning/scale_factor_selection.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include <spdlog/spdlog.h>

#include "odonav/consumer_rules.hpp"

namespace odonav::dead_reckoning {

void ScaleFactorSelection::track_source(const std::string& source, double t_s, double now_s) {
  // Which identification instance is followed (the one the node's SourceArbiter hands on: the
  // highest-priority live instance): logged, and told in health for a while after a change (hot standby taking over,
  // the primary coming back).
  if (source == state_.k_source) return;
  if (state_.k_source.empty()) {
    spdlog::info("following K from '{}' (t={} s)", source, t_s);
  } else {
    ++state_.counters.k_source_changes;
    std::ostringstream note;
    note.precision(10);
    note << "K source changed from '" << state_.k_source << "' to '" << source << "' at t=" << t_s << " s";
    spdlog::warn("{}", note.str());
    k_source_note_ = note.str();
    k_source_changed_at_s_ = now_s;
  }
  state_.k_source = source;
}

std::optional<ScaleFactorUpdate> ScaleFactorSelection::on_identified(const IdentifiedScaleFactor& k, double now_s) {
  track_source(k.source, k.t_s, now_s);
  const bool valid = std::isfinite(k.k_m_per_pulse) && k.k_m_per_pulse > 0.0;
  if (!scale_factor_applicable(valid, k.converged, k.k_m_per_pulse, k.sigma_m_per_pulse, k.samples_accepted,
                               nominal_k_m_per_pulse_,
                               !state_.in_force_source.empty() && k.source == state_.in_force_source,
                               nominal_k_rel_sigma_ * nominal_k_m_per_pulse_))
    return std::nullopt;  // as odonav-offline
  if (state_.commanded || (state_.last_k_stamp_s && k.t_s <= *state_.last_k_stamp_s)) {
    ++state_.counters.k_ignored;
    return std::nullopt;
  }
  state_.last_k_stamp_s = k.t_s;
  state_.in_force_source = k.source;
  ++state_.counters.k_applied;
  return ScaleFactorUpdate{k.t_s, k.k_m_per_pulse, ScaleFactorSource::kIdentified};
}

ScaleFactorCommandResult ScaleFactorSelection::set_commanded_k(double k, double processed_s) {
  if (const auto problem = commanded_k_problem(k, nominal_k_m_per_pulse_)) return {false, "set_k: " + *problem, {}};
  // In force after everything already processed and after the last K given to the DR. Before
  // anything (processed_s = -inf, no K yet) the lowest finite time, so the stamp stays finite.
  double base = std::max(processed_s, state_.last_k_stamp_s.value_or(-std::numeric_limits<double>::infinity()));
  if (!std::isfinite(base)) base = -std::numeric_limits<double>::max();
  const double t_s = std::nextafter(base, std::numeric_limits<double>::infinity());
  state_.last_k_stamp_s = t_s;
  state_.commanded = true;
  state_.in_force_source.clear();  // after the release an identified K must again beat the nominal first
  std::ostringstream m;
  m.precision(10);
  m << "K = " << k << " m/pulse commanded (identified K ignored until release_k)";
  return {true, m.str(), ScaleFactorUpdate{t_s, k, ScaleFactorSource::kCommanded}};
}

ScaleFactorCommandResult ScaleFactorSelection::release_commanded_k() {
  state_.commanded = false;
  return {true, "following the identified K again (from its next estimate)", std::nullopt};
}

}  // namespace odonav::dead_reckoning
