#include "odonav/identification/identification_core.hpp"

#include "odonav/checkpoint_state.hpp"
#include "odonav/consumer_rules.hpp"

#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace odonav::identification {

IdentificationCore::IdentificationCore(const IdentificationParams& params)
    : params_(params),
      builder_(params.builder),
      main_(make_scale_factor_estimator(params.estimator_name, params.estimator)),
      turn_slip_(params.turn_slip),
      motion_(params.braking_stop) {
  if (params_.run_all_estimators) {
    for (const std::string& name : odonav::estimator_names())
      all_.push_back(make_scale_factor_estimator(name, params_.estimator));
  }
}

std::vector<std::string> IdentificationCore::estimator_names() const {
  std::vector<std::string> names;
  for (const auto& e : all_) names.push_back(e->name());
  return names;
}

void IdentificationCore::reset() {
  main_->reset();
  for (auto& e : all_) e->reset();
  turn_slip_ = TurnSlipEstimator(params_.turn_slip);
  seed_k_m_per_pulse_.reset();
  braking_snapshot_.reset();
}

std::optional<std::string> IdentificationCore::commanded_k_problem(double k, double nominal_k) {
  return odonav::commanded_k_problem(k, nominal_k);  // the one set-K range (consumer_rules.hpp)
}

namespace {
bool takes_pseudo_samples(const ScaleFactorEstimator& e) { return e.name() != "coarse"; }
// The coarse S/N divides distances between GNSS positions by pulses over whole straight runs: no
// velocity, so no timing error enters it, and it is the traditional baseline: braking stays in it.
bool withdraws_braking(const ScaleFactorEstimator& e) { return e.name() != "coarse"; }
}  // namespace

IdentificationOutput IdentificationCore::set_k(double k, double t_s) {
  if (!std::isfinite(k) || !(k > 0.0) || !std::isfinite(t_s)) {
    std::ostringstream m;
    m << "IdentificationCore::set_k: K = " << k << " m/pulse must be finite and > 0, t = " << t_s << " s finite";
    throw std::invalid_argument(m.str());
  }
  ScaleFactorSample seed;
  seed.t_s = t_s;
  seed.phi_pulses = 1.0;
  seed.y_m = k;  // K = y / phi exactly
  seed.dt_s = params_.estimator.sample_interval_s;
  seed.straight = true;
  auto reseed = [&](ScaleFactorEstimator& e) {
    e.reset();
    if (takes_pseudo_samples(e)) e.update(seed);
  };
  reseed(*main_);
  for (auto& e : all_) reseed(*e);
  seed_k_m_per_pulse_ = k;
  braking_snapshot_.reset();  // a commanded K is never withdrawn

  IdentificationOutput out;
  out.t_s = t_s;
  out.epoch_status = EpochStatus::kAccepted;
  out.main = main_estimate();
  for (const auto& e : all_) out.all.push_back(e->estimate());
  out.samples_accepted = accepted_;
  out.samples_rejected = rejected_;
  out.frozen = frozen_;
  out.latency = latency();
  feed_gate(t_s, out.main);
  return out;
}

GnssLatencyEstimate IdentificationCore::latency() const {
  GnssLatencyEstimate l = builder_.latency();
  widen_latency_sigma(l, main_->estimate().correlation_factor);
  return l;
}

ScaleFactorEstimate IdentificationCore::main_estimate() const {
  ScaleFactorEstimate e = main_->estimate();
  if (!e.valid && seed_k_m_per_pulse_) {
    e.valid = true;
    e.k_m_per_pulse = *seed_k_m_per_pulse_;
    e.sigma_m_per_pulse = 0.0;  // unknown: published as -1
    e.converged = false;
  }
  return e;
}

void IdentificationCore::feed_gate(double t_s, const ScaleFactorEstimate& est) {
  // The latency is fitted to the same samples: its significance tests count their correlation.
  builder_.set_latency_sigma_factor(est.correlation_factor);
  if (!est.valid) return;
  // Strictly after the last one (the builder's history needs increasing stamps); a commanded K at
  // the time of the last processed epoch then applies from the next epoch on.
  if (last_gate_t_s_ && !(t_s > *last_gate_t_s_))
    t_s = std::nextafter(*last_gate_t_s_, std::numeric_limits<double>::infinity());
  builder_.add_scale_factor_estimate(t_s, est.k_m_per_pulse, est.sigma_m_per_pulse);
  last_gate_t_s_ = t_s;
}

TurnSlipEstimate IdentificationCore::turn_slip_estimate() const {
  if (!params_.turn_slip_enabled) {
    TurnSlipEstimate off;
    off.reason = "turn slip estimation off (--turn-slip false)";
    return off;
  }
  if (!params_.builder.use_ins) {
    TurnSlipEstimate off;
    off.reason = "no INS: turns are not measured";
    return off;
  }
  return turn_slip_.estimate();
}

void IdentificationCore::track_braking_stop(const SampleBuilderEpoch& epoch, MotionPhase phase) {
  auto take = [&]() -> std::optional<BrakingSnapshot> {
    // Taken at the first braking epoch with a sample, so a snapshot always withdraws something.
    if (!epoch.sample) return std::nullopt;
    BrakingSnapshot snap;
    auto state_of = [](const ScaleFactorEstimator& e) {
      return withdraws_braking(e) ? std::make_shared<const StateJson>(e.save_state()) : nullptr;
    };
    snap.main = state_of(*main_);
    for (const auto& e : all_) snap.all.push_back(state_of(*e));
    return snap;
  };
  auto restore = [&](const BrakingSnapshot& snap) {
    if (withdraws_braking(*main_)) main_->restore_state(*snap.main);
    for (std::size_t i = 0; i < all_.size(); ++i)
      if (withdraws_braking(*all_[i])) all_[i]->restore_state(*snap.all[i]);
  };
  const uint64_t withdrawn =
      apply_braking_stop(braking_snapshot_, phase, params_.braking_stop.enabled && !frozen_, take, restore);
  if (withdrawn == 0) return;
  ++braking_stop_counters_.stops;
  braking_stop_counters_.samples_withdrawn += withdrawn;
  // The innovation gate tests against the K the drive stopped with from the next epoch on.
  feed_gate(epoch.t_s, main_estimate());
}

IdentificationOutput IdentificationCore::on_epoch(const SampleBuilderEpoch& epoch) {
  const MotionPhase phase = motion_.add(epoch.t_s, epoch.forward_speed_mps);
  track_braking_stop(epoch, phase);
  if (epoch.sample && !frozen_) {
    ++accepted_;
    if (braking_snapshot_) ++braking_snapshot_->used_since;
    main_->update(*epoch.sample);
    for (auto& e : all_) e->update(*epoch.sample);
    // Feed the gate from inside the callback, stamped with the sample time: it then applies from
    // the next epoch on whatever the chunking (sample_builder.hpp).
    feed_gate(epoch.t_s, main_estimate());
  } else if (epoch.status != EpochStatus::kAccepted && epoch.status != EpochStatus::kChainStart) {
    ++rejected_;
  }
  if (epoch.turn_sample && !frozen_ && params_.turn_slip_enabled) turn_slip_.update(*epoch.turn_sample);
  IdentificationOutput out;
  out.t_s = epoch.t_s;
  out.epoch_status = epoch.status;
  out.main = main_estimate();
  for (const auto& e : all_) out.all.push_back(e->estimate());
  out.samples_accepted = accepted_;
  out.samples_rejected = rejected_;
  out.frozen = frozen_;
  out.latency = epoch.latency;
  widen_latency_sigma(out.latency, out.main.correlation_factor);
  out.turn_slip = turn_slip_estimate();
  out.turn_slip_threshold_radps = turn_slip_threshold_radps();
  out.motion_phase = phase;
  out.braking_stop = braking_stop_counters_;
  out.latency_decided = builder_.latency_decided();
  // Only what is published changes: the estimators and the builder's innovation gate keep the
  // estimator's own K and sigma (feed_gate above), and a commanded or frozen K is never replaced.
  const ScaleFactorEstimate own = out.main;
  out.main = honest_estimate(own, builder_.latency_in_force_uncertainty_s(own.correlation_factor), out.latency_decided);
  if (out.main.valid && !out.main.converged && !frozen_ && !seed_k_m_per_pulse_) {
    if (const auto start = builder_.start_latency_k()) {
      // K at the block's own latency estimate: off by its sigma times K's sensitivity at most.
      out.main = honest_estimate(own, own.correlation_factor * start->latency_sigma_s, false);
      out.main.k_m_per_pulse = start->k_m_per_pulse;
      out.k_from_start_latency = true;
    }
  }
  return out;
}

void widen_latency_sigma(GnssLatencyEstimate& latency, double correlation_factor) {
  if (!(correlation_factor > 1.0) || latency.fixed) return;
  if (latency.sigma_s > 0.0) latency.sigma_s *= correlation_factor;
  if (latency.applied_sigma_s > 0.0) latency.applied_sigma_s *= correlation_factor;
}

ScaleFactorEstimate honest_estimate(const ScaleFactorEstimate& own, double latency_uncertainty_s, bool latency_decided,
                                    double converged_rel_sigma) {
  ScaleFactorEstimate e = own;
  if (!e.valid || !std::isfinite(e.k_m_per_pulse) || !(e.sigma_m_per_pulse > 0.0)) return e;
  // The window's scatter widened by its residuals' serial correlation, or the lag after a change.
  const double scatter = std::max(e.sigma_m_per_pulse * e.correlation_factor, e.lag_sigma_m_per_pulse);
  const double latency_part = e.dk_dlatency_m_per_pulse_per_s * latency_uncertainty_s;
  e.sigma_m_per_pulse = std::hypot(scatter, latency_part);
  e.converged = own.converged && latency_decided && e.k_m_per_pulse != 0.0 &&
                e.sigma_m_per_pulse / std::abs(e.k_m_per_pulse) < converged_rel_sigma;
  return e;
}

ScaleFactorEstimate IdentificationCore::honest_estimate(const ScaleFactorEstimate& own, double latency_uncertainty_s,
                                                        bool latency_decided) const {
  return identification::honest_estimate(own, latency_uncertainty_s, latency_decided,
                                         params_.estimator.converged_rel_sigma);
}

std::vector<IdentificationOutput> IdentificationCore::process_until(double watermark_s) {
  std::vector<IdentificationOutput> outputs;
  builder_.process_until(watermark_s, [&](const SampleBuilderEpoch& e) { outputs.push_back(on_epoch(e)); });
  return outputs;
}

std::vector<IdentificationOutput> IdentificationCore::finish() {
  std::vector<IdentificationOutput> outputs;
  builder_.finish([&](const SampleBuilderEpoch& e) { outputs.push_back(on_epoch(e)); });
  return outputs;
}

ODONAV_STATE_FIELDS(BrakingStopCounters) { a("stops", s.stops)("samples_withdrawn", s.samples_withdrawn); }

template <class Archive, class Self>
void IdentificationCore::state_fields(Archive& a, Self& c) {
  // An estimator's state, restored by the estimator (which checks its name and parameters).
  auto estimator = [&](const char* key, auto& e) {
    a.via(
        key, [&] { return e->save_state(); },
        [&](const auto& state) { restore_or_refuse("estimator " + e->name() + ":", *e, state); });
  };
  a("accepted", c.accepted_)("rejected", c.rejected_)("frozen", c.frozen_)(
      "commanded_k_m_per_pulse", c.seed_k_m_per_pulse_)("last_gate_t_s", c.last_gate_t_s_)
      .via("sample_builder", c.builder_);
  estimator("main_estimator", c.main_);
  a.via("turn_slip", c.turn_slip_)
      .via(
          "side_by_side",
          [&] {
            std::vector<StateJson> states;
            for (const auto& e : c.all_) states.push_back(e->save_state());
            return states;
          },
          [&](const auto& states) {
            if (states.size() != c.all_.size())
              throw CheckpointError("field 'side_by_side' holds " + std::to_string(states.size()) +
                                    " estimators, this core runs " + std::to_string(c.all_.size()));
            for (std::size_t i = 0; i < states.size(); ++i)
              restore_or_refuse("estimator " + c.all_[i]->name() + ":", *c.all_[i], states[i]);
          })("braking_stop", c.braking_stop_counters_)
      .via(
          "motion_epochs", [&] { return c.motion_.state(); }, [&](const auto& v) { c.motion_.restore(v); })(
          "braking_snapshot", c.braking_snapshot_);
  if (c.braking_snapshot_)
    a.check("braking_snapshot", c.braking_snapshot_->all.size() == c.all_.size(),
            "does not hold one state per side-by-side estimator");
}

StateJson IdentificationCore::save_state() const { return save_fields(*this); }

void IdentificationCore::restore_state(const StateJson& state) {
  // Restored into a copy: this one changes only when everything was read.
  *this = restored_copy(IdentificationCore(params_), state, "identification");
  builder_.set_latency_sigma_factor(main_->estimate().correlation_factor);
}

bool IdentificationCore::apply_misalignment(const PublishedMisalignment& m) {
  if (!misalignment_applicable(m.converged, m.samples_used, m.heading_rad, m.pitch_rad, m.heading_std_rad,
                               m.pitch_std_rad))
    return false;
  if (!std::isfinite(m.heading_rad) || !std::isfinite(m.pitch_rad))
    throw StreamInputError("misalignment: angles are not finite");
  add_misalignment(estimate_applies_from_s(m.t_s, params_.estimate_hold_off_s),
                   Misalignment{m.heading_rad, m.pitch_rad});
  return true;
}

PublishedScaleFactor published_scale_factor(const IdentificationOutput& out, const std::string& source) {
  PublishedScaleFactor p;
  p.t_s = out.t_s;
  const ScaleFactorEstimate& e = out.main;
  const bool has_value = e.valid && std::isfinite(e.k_m_per_pulse);
  p.k_m_per_pulse = has_value ? e.k_m_per_pulse : 0.0;
  p.sigma_m_per_pulse =
      has_value && std::isfinite(e.sigma_m_per_pulse) && e.sigma_m_per_pulse > 0.0 ? e.sigma_m_per_pulse : -1.0;
  p.converged = has_value && e.converged;
  p.samples_accepted = out.samples_accepted;
  p.source = source;
  p.gnss_latency_s = out.latency.applied_s;
  p.turn_slip_applies = out.turn_slip.applies;
  p.turn_slip_s_per_rad = out.turn_slip.g_s_per_rad;
  p.turn_slip_threshold_radps = out.turn_slip_threshold_radps;
  return p;
}

results::ScaleFactorRow output_row(const IdentificationOutput& k, const std::string& main_estimator,
                                   const std::vector<std::string>& names) {
  results::ScaleFactorRow r;
  r.t_s = k.t_s;
  auto value_of = [](const ScaleFactorEstimate& e) {
    return e.valid ? std::optional<double>(e.k_m_per_pulse) : std::nullopt;
  };
  for (std::size_t i = 0; i < names.size() && i < k.all.size(); ++i) {
    r.k_by_estimator.emplace_back(names[i], value_of(k.all[i]));
    if (names[i] == "vff_lm_rls" && k.all[i].valid) r.lambda_vff_lm_rls = k.all[i].forgetting_factor;
  }
  if (names.empty()) {  // one estimator only (the DDS node): its own column
    r.k_by_estimator.emplace_back(main_estimator, value_of(k.main));
    if (main_estimator == "vff_lm_rls" && k.main.valid) r.lambda_vff_lm_rls = k.main.forgetting_factor;
  }
  r.estimator = main_estimator;
  const PublishedScaleFactor p = published_scale_factor(k, "");
  if (k.main.valid && std::isfinite(k.main.k_m_per_pulse)) r.k_m_per_pulse = k.main.k_m_per_pulse;
  if (p.sigma_m_per_pulse >= 0.0) r.sigma_m_per_pulse = p.sigma_m_per_pulse;
  r.forgetting_factor = k.main.forgetting_factor;
  r.window_fill = k.main.window_fill;
  r.converged = p.converged;
  r.samples_accepted = k.samples_accepted;
  r.samples_rejected = k.samples_rejected;
  r.epoch_status = to_string(k.epoch_status);
  r.gnss_latency_s = k.latency.applied_s;
  // The sigma of the value in force, not of the online estimate: the two differ until the
  // estimate is applied, and before the first application the value in force (0) is not the
  // estimate at all.
  if (k.latency.applied_sigma_s >= 0.0) r.gnss_latency_sigma_s = k.latency.applied_sigma_s;
  r.turn_slip_s_per_rad = k.turn_slip.g_s_per_rad;
  if (k.turn_slip.sigma_s_per_rad >= 0.0) r.turn_slip_sigma_s_per_rad = k.turn_slip.sigma_s_per_rad;
  r.turn_slip_applies = k.turn_slip.applies;
  return r;
}

std::vector<ComponentInput> identification_inputs(const IdentificationParams& p) {
  std::vector<ComponentInput> in{
      {"odometer", true, "", 0.0}, {"gnss", true, "", 0.0}, {"misalignment", false, "gnss", p.estimate_hold_off_s}};
  if (p.builder.use_ins) in.push_back({"ins", true, "", 0.0});
  return in;
}

}  // namespace odonav::identification
