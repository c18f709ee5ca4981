#include "odonav/identification/identification_core.hpp"

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
}

IdentificationOutput IdentificationCore::on_epoch(const SampleBuilderEpoch& epoch) {
  if (epoch.sample && !frozen_) {
    ++accepted_;
    main_->update(*epoch.sample);
    for (auto& e : all_) e->update(*epoch.sample);
    const ScaleFactorEstimate est = main_->estimate();
    // Feed the gate from inside the callback, stamped with the sample time: it then applies from
    // the next epoch on whatever the chunking (sample_builder.hpp).
    if (est.valid) builder_.add_scale_factor_estimate(epoch.t_s, est.k_m_per_pulse, est.sigma_m_per_pulse);
  } else if (epoch.status != EpochStatus::kAccepted && epoch.status != EpochStatus::kChainStart) {
    ++rejected_;
  }
  IdentificationOutput out;
  out.t_s = epoch.t_s;
  out.epoch_status = epoch.status;
  out.main = main_->estimate();
  for (const auto& e : all_) out.all.push_back(e->estimate());
  out.samples_accepted = accepted_;
  out.samples_rejected = rejected_;
  out.frozen = frozen_;
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
