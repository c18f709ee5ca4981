// SampleBuilder::save_state() / restore_state(): the builder's complete state for a component
// checkpoint (the identification's), every field listed once (checkpoint_state.hpp).
#include <cmath>
#include <string>
#include <vector>

#include "odonav/checkpoint_state.hpp"
#include "odonav/sample_builder.hpp"
#include "odonav/stream_state.hpp"

namespace odonav {

ODONAV_STATE_FIELDS(SampleBuilderCounters) {
  a("epochs", s.epochs)("accepted", s.accepted)("chain_starts", s.chain_starts)("invalid_fix", s.invalid_fix)(
      "low_fix_quality", s.low_fix_quality)("no_odometer", s.no_odometer)("no_attitude", s.no_attitude)(
      "negative_speed", s.negative_speed)("speed_jump", s.speed_jump)("gap", s.gap)("min_speed", s.min_speed)(
      "reversing", s.reversing)("yaw_rate", s.yaw_rate)("no_pulses", s.no_pulses)("innovation", s.innovation)(
      "cross_track", s.cross_track)("innovation_suspended", s.innovation_suspended)(
      "reversing_accepted", s.reversing_accepted)("odometer_jumps_rejected", s.odometer_jumps_rejected)(
      "odometer_rebases", s.odometer_rebases);
}

ODONAV_STATE_FIELDS(GnssLatencyEstimate) {
  a("applied_s", s.applied_s)("applied_sigma_s", s.applied_sigma_s)("estimate_s", s.estimate_s)("sigma_s", s.sigma_s)(
      "samples", s.samples)("blocks_left_out", s.blocks_left_out)("fixed", s.fixed)("reason", s.reason);
  a.check("applied_s", std::isfinite(s.applied_s), "is not finite");
  a.check("applied_sigma_s", std::isfinite(s.applied_sigma_s), "is not finite");
}

template <class Archive, class Self>
void SampleBuilder::state_fields(Archive& a, Self& b) {
  const std::size_t candidates = b.latency_candidates_s_.size();
  const char* per_candidate = "does not hold one value per latency candidate";
  a.via("odometer", b.odometer_)
      .via("attitude", b.attitude_)("pending_gnss", b.pending_gnss_)("last_gnss_t_s", b.last_gnss_t_s_)
      .via("misalignment_history", b.misalignment_)
      .via("k_estimates", b.k_estimates_)("watermark_s", b.watermark_s_)("chain_start", b.chain_start_)(
          "last_good_speed", b.last_good_speed_)("consecutive_innovation_rejections",
                                                 b.consecutive_innovation_rejections_)
      .via(
          "frame_origin", [&] { return b.frame_ ? std::optional<Geodetic>(b.frame_->origin()) : std::nullopt; },
          [&](const auto& origin) {
            if (origin) b.frame_.emplace(*origin);
          })("counters", b.counters_)("gnss_intervals_s", b.gnss_intervals_s_)(
          "last_period_row_t_s", b.last_period_row_t_s_)("gnss_period_s", b.gnss_period_s_)("latency", b.latency_)(
          "latency_closed_chi2", b.latency_closed_chi2_)("latency_closed_blocks", b.latency_closed_blocks_)(
          "latency_closed_samples", b.latency_closed_samples_)("latency_closed_fit_s", b.latency_closed_fit_)(
          "latency_block_start_s", b.latency_block_start_s_)("latency_block_samples", b.latency_block_samples_)(
          "latency_block_yy_m2", b.latency_block_yy_m2_)("latency_block_yphi", b.latency_block_yphi_)(
          "latency_block_phiphi", b.latency_block_phiphi_)("latency_samples", b.latency_samples_)(
          "latency_sums_applied_s", b.latency_sums_applied_s_)("latency_restarts", b.latency_restarts_)(
          "latency_pending", b.latency_pending_);
  a.check("watermark_s", !std::isnan(b.watermark_s_), "is not a number");
  a.check("consecutive_innovation_rejections", b.consecutive_innovation_rejections_ >= 0, "is negative");
  a.check("gnss_intervals_s", b.gnss_intervals_s_.size() <= static_cast<std::size_t>(b.params_.gnss_period_window),
          "is longer than the GNSS period window");
  a.check("latency_closed_chi2", b.latency_closed_chi2_.size() == candidates, per_candidate);
  a.check("latency_block_yphi", b.latency_block_yphi_.size() == candidates, per_candidate);
  a.check("latency_block_phiphi", b.latency_block_phiphi_.size() == candidates, per_candidate);
}

StateJson SampleBuilder::save_state() const { return save_fields(*this); }

void SampleBuilder::restore_state(const StateJson& state) {
  // Restored into a copy: this one changes only when everything was read.
  *this = restored_copy(SampleBuilder(params_), state, "sample_builder");
  // The closed fit's sigma is not saved: the same fit of the restored sums gives it (and the saved
  // estimate).
  fit_closed_blocks();
}

}  // namespace odonav
