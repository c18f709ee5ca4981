#include "odonav/dead_reckoning/dead_reckoning_component.hpp"

#include <cmath>
#include <utility>

#include "odonav/consumer_rules.hpp"

namespace odonav::dead_reckoning {

DeadReckoningComponent::DeadReckoningComponent(const DeadReckonerParams& params, const AnchoredPositionParams& anchored,
                                               bool navigation, const ConsistencyParams& consistency)
    : hold_off_s_(params.estimate_hold_off_s),
      navigation_(navigation),
      core_(params),
      anchor_(anchored),
      consumer_(params.nominal_k_m_per_pulse, params.nominal_k_rel_sigma),
      monitor_(consistency) {}

void DeadReckoningComponent::on_misalignment(const PublishedMisalignment& m) {
  core_.add_estimate_received(HeldEstimate::kMisalignment, m.t_s);  // applicable or not
  if (!misalignment_applicable(m.converged, m.samples_used, m.heading_rad, m.pitch_rad, m.heading_std_rad,
                               m.pitch_std_rad))
    return;
  monitor_.set_misalignment(m.heading_std_rad, m.converged);
  const Misalignment misalignment{m.heading_rad, m.pitch_rad};
  const double from_s = estimate_applies_from_s(m.t_s, hold_off_s_);
  core_.add_misalignment(from_s, misalignment);  // StreamInputError on non-finite angles
  consumer_.applied_misalignment.add(from_s, misalignment);
  ++consumer_.misalignments_applied;
  consumer_.held_misalignment_t_s = m.t_s;
}

void DeadReckoningComponent::on_scale_factor(const PublishedScaleFactor& k, double now_s) {
  core_.add_estimate_received(HeldEstimate::kScaleFactor, k.t_s);  // applicable or not
  const double from_s = estimate_applies_from_s(k.t_s, hold_off_s_);
  // The error against GNSS and the anchor fixes compare each fix with the DR at its stamp minus the
  // latency in force.
  if (std::isfinite(k.gnss_latency_s) && std::abs(k.gnss_latency_s) < 10.0)
    core_.add_gnss_latency(from_s, k.gnss_latency_s);
  // A gain not applied (or not a positive number) is 0; a threshold that is not a rate carries no slip.
  if (std::isfinite(k.turn_slip_threshold_radps) && k.turn_slip_threshold_radps >= 0.0)
    core_.add_turn_slip(from_s, turn_slip_gain_to_apply(k.turn_slip_applies, k.turn_slip_s_per_rad),
                        k.turn_slip_threshold_radps);
  monitor_.set_scale_factor(k.k_m_per_pulse, k.sigma_m_per_pulse, k.converged);
  const IdentifiedScaleFactor identified{from_s,   k.k_m_per_pulse,     k.converged,
                                         k.source, k.sigma_m_per_pulse, k.samples_accepted};
  if (const auto update = consumer_.k_selection.on_identified(identified, now_s))
    core_.add_scale_factor(update->t_s, update->k_m_per_pulse, update->source);
}

ScaleFactorCommandResult DeadReckoningComponent::set_commanded_k(double k_m_per_pulse, double processed_s) {
  ScaleFactorCommandResult r = consumer_.k_selection.set_commanded_k(k_m_per_pulse, processed_s);
  if (r.update) core_.add_scale_factor(r.update->t_s, r.update->k_m_per_pulse, r.update->source);
  return r;
}

DeadReckoningStep DeadReckoningComponent::publish(DeadReckoningOutput o) {
  DeadReckoningStep step;
  step.misalignment = consumer_.applied_misalignment.at_or_before(o.t_s).value_or(Misalignment{});
  if (navigation_) step.navigation = anchor_.step(o);
  consumer_.applied_misalignment.drop_before(o.t_s);
  monitor_.on_output(o);
  step.consistent = monitor_.consistent();
  step.output = std::move(o);
  return step;
}

std::vector<ComponentInput> dead_reckoning_inputs(const DeadReckonerParams& p) {
  std::vector<ComponentInput> in{{"odometer", true, "", 0.0},
                                 {"gnss", true, "", p.estimate_hold_off_s},
                                 {"misalignment", false, "gnss", p.estimate_hold_off_s},
                                 {"scale_factor", false, "gnss", p.estimate_hold_off_s}};
  if (p.use_ins) in.push_back({"ins", true, "", 0.0});
  return in;
}

}  // namespace odonav::dead_reckoning
