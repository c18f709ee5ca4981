// The checkpoint state of the dead reckoning's cores (DeadReckoner, AnchoredPositionFilter):
// save_state() / restore_state(), every field listed once (checkpoint_state.hpp).
#include <cmath>
#include <string>
#include <vector>

#include "odonav/checkpoint_state.hpp"
#include "odonav/dead_reckoning/anchored_position.hpp"
#include "odonav/dead_reckoning/dead_reckoner.hpp"
#include "odonav/stream_state.hpp"

namespace odonav::dead_reckoning {

ODONAV_STATE_FIELDS(AnchorFix) {
  a("t_s", s.t_s)("fix_enu_m", s.fix_enu_m)("dr_enu_m", s.dr_enu_m)("dr_distance_m", s.dr_distance_m)("sigma_m",
                                                                                                      s.sigma_m);
}

ODONAV_STATE_FIELDS(HeldSpan) {
  a("first_t_s", s.first_t_s)("last_t_s", s.last_t_s)("outputs", s.outputs)("estimate_epoch_s", s.estimate_epoch_s)(
      "open", s.open);
}

ODONAV_STATE_FIELDS(DeadReckonerCounters) {
  a("odometer_samples", s.odometer_samples)("outputs", s.outputs)("before_start", s.before_start)(
      "unknown_direction", s.unknown_direction)("reversing", s.reversing)("heading_held", s.heading_held)(
      "distance_lost", s.distance_lost)("pulse_jumps_rejected", s.pulse_jumps_rejected)(
      "pulse_rebases", s.pulse_rebases)("anchor_fixes", s.anchor_fixes)(
      "anchor_fixes_no_attitude", s.anchor_fixes_no_attitude)("gnss_latency_stale", s.gnss_latency_stale)(
      "outputs_on_held_k", s.outputs_on_held_k)("outputs_on_held_misalignment", s.outputs_on_held_misalignment)(
      "turn_slip_stale", s.turn_slip_stale);
}

ODONAV_STATE_FIELDS(AnchoredPositionCounters) {
  a("steps", s.steps)("fixes_added", s.fixes_added)("fixes_applied", s.fixes_applied)(
      "fixes_rejected_gate", s.fixes_rejected_gate)("gate_restarts", s.gate_restarts)(
      "last_rejected_innovation_m", s.last_rejected_innovation_m)("last_rejected_gate_m", s.last_rejected_gate_m);
}

template <class Archive, class Self>
void DeadReckoner::state_fields(Archive& a, Self& d) {
  a.via("odometer", d.odometer_)("odometer_pending_t_s", d.pending_odometer_t_s_)
      .via("attitude", d.attitude_)("gnss", d.gnss_)("gnss_gap_s", d.gnss_gap_s_)(
          "gnss_intervals_s", d.gnss_intervals_s_)("gnss_last_gap_s", d.last_gnss_gap_s_)(
          "gnss_last_t_s", d.last_gnss_t_s_)("error_epochs", d.error_epochs_)("past_outputs", d.past_)(
          "last_error", d.last_error_)("start_t_s", d.start_t_s_)
      .via("k_history", d.k_history_)
      .via("misalignment_history", d.misalignment_)
      .via("gnss_latency_history", d.gnss_latency_)("gnss_latency_last", d.last_gnss_latency_)
      .via("turn_slip_history", d.turn_slip_)("turn_slip_last", d.last_turn_slip_)("watermark_s", d.watermark_s_)
      .via(
          "origin", [&] { return d.origin(); },
          [&](const auto& origin) {
            if (origin) d.frame_.emplace(*origin);
          })("position", d.position_)("last_t_s", d.last_t_s_)("last_count", d.last_count_)(
          "distance_m", d.distance_m_)("held_direction", d.held_direction_)("held_heading_rad", d.held_heading_rad_)(
          "last_attitude", d.last_attitude_)("start_fix", d.start_fix_)("counters", d.counters_)(
          "epochs_to_apply_s", d.epochs_to_apply_s_)("latest_applicable_epoch_s", d.latest_applicable_epoch_s_)(
          "held_k", d.held_[0])("held_misalignment", d.held_[1])("heading_position_offset_enu_m",
                                                                 d.heading_position_offset_enu_m_);
  a.check("gnss_gap_s", d.gnss_gap_s_.size() == d.gnss_.size(), "does not match 'gnss'");
  a.check("gnss_intervals_s", d.gnss_intervals_s_.size() <= static_cast<std::size_t>(d.params_.gnss_period_window),
          "is longer than the GNSS period window");
  a.check("gnss_last_gap_s", std::isfinite(d.last_gnss_gap_s_), "is not finite");
  a.check("watermark_s", !std::isnan(d.watermark_s_), "is not a number");
  a.check("held_direction", d.held_direction_ >= -1 && d.held_direction_ <= 1, "is not -1, 0 or 1");
  a.check("origin", d.frame_.has_value() == d.start_t_s_.has_value(),
          "and 'start_t_s' disagree on whether the dead reckoning started");
}

StateJson DeadReckoner::save_state() const { return save_fields(*this); }

void DeadReckoner::restore_state(const StateJson& state) {
  // Restored into a copy: this one changes only when everything was read.
  *this = restored_copy(DeadReckoner(params_), state, "dead_reckoner");
}

template <class Archive, class Self>
void AnchoredPositionFilter::state_fields(Archive& a, Self& f) {
  a("queued_fixes", f.queued_)("last_added_t_s", f.last_added_t_s_)("last_step_t_s", f.last_step_t_s_)(
      "last_enu_m", f.last_enu_m_)("initialised", f.initialised_)("x", f.x_)("p", f.p_)(
      "correlated_sigma_h_m", f.correlated_sigma_h_m_)("last_distance_m", f.last_distance_m_)(
      "last_fix_t_s", f.last_fix_t_s_)("last_fix_distance_m", f.last_fix_distance_m_)(
      "consecutive_gated", f.consecutive_gated_)("counters", f.counters_);
}

StateJson AnchoredPositionFilter::save_state() const { return save_fields(*this); }

void AnchoredPositionFilter::restore_state(const StateJson& state) {
  // Restored into a copy: this one changes only when everything was read.
  *this = restored_copy(AnchoredPositionFilter(params_), state, "anchored_position");
}

}  // namespace odonav::dead_reckoning
