#include "odonav/identification/identification_core.hpp"

#include "odonav/consumer_rules.hpp"

#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace odonav {

IdentificationCore::IdentificationCore(const IdentificationParams& params)
    : params_(params),
      builder_(params.builder),
      main_(make_scale_factor_estimator(params.estimator_name, params.estimator)) {
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
  seed_k_m_per_pulse_.reset();
}

std::optional<std::string> IdentificationCore::commanded_k_problem(double k, double nominal_k) {
  return odonav::commanded_k_problem(k, nominal_k);  // the one set-K range (consumer_rules.hpp)
}

namespace {
bool takes_pseudo_samples(const ScaleFactorEstimator& e) { return e.name() != "coarse"; }
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

  IdentificationOutput out;
  out.t_s = t_s;
  out.epoch_status = EpochStatus::kAccepted;
  out.main = main_estimate();
  for (const auto& e : all_) out.all.push_back(e->estimate());
  out.samples_accepted = accepted_;
  out.samples_rejected = rejected_;
  out.frozen = frozen_;
  out.latency = builder_.latency();
  feed_gate(t_s, out.main);
  return out;
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
  if (!est.valid) return;
  // Strictly after the last one (the builder's history needs increasing stamps); a commanded K at
  // the time of the last processed epoch then applies from the next epoch on.
  if (last_gate_t_s_ && !(t_s > *last_gate_t_s_)) t_s = std::nextafter(*last_gate_t_s_, std::numeric_limits<double>::infinity());
  builder_.add_scale_factor_estimate(t_s, est.k_m_per_pulse, est.sigma_m_per_pulse);
  last_gate_t_s_ = t_s;
}

IdentificationOutput IdentificationCore::on_epoch(const SampleBuilderEpoch& epoch) {
  if (epoch.sample && !frozen_) {
    ++accepted_;
    main_->update(*epoch.sample);
    for (auto& e : all_) e->update(*epoch.sample);
    // Feed the gate from inside the callback, stamped with the sample time: it then applies from
    // the next epoch on whatever the chunking (sample_builder.hpp).
    feed_gate(epoch.t_s, main_estimate());
  } else if (epoch.status != EpochStatus::kAccepted && epoch.status != EpochStatus::kChainStart) {
    ++rejected_;
  }
  IdentificationOutput out;
  out.t_s = epoch.t_s;
  out.epoch_status = epoch.status;
  out.main = main_estimate();
  for (const auto& e : all_) out.all.push_back(e->estimate());
  out.samples_accepted = accepted_;
  out.samples_rejected = rejected_;
  out.frozen = frozen_;
  out.latency = epoch.latency;
  return out;
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

}  // namespace odonav
