// What every estimator's save_state() / restore_state() shares (estimator_internal.hpp): the
// estimator's name and parameters around its own fields.
#include <stdexcept>

#include "estimator_internal.hpp"

namespace odonav {

ODONAV_STATE_FIELDS(ScaleFactorEstimatorParams) {
  a("k_prior_m_per_pulse", s.k_prior_m_per_pulse)("prior_weight_pulses2", s.prior_weight_pulses2)(
      "sigma_y_floor_m", s.sigma_y_floor_m)("sigma_y_ewma_alpha", s.sigma_y_ewma_alpha)(
      "converged_rel_sigma", s.converged_rel_sigma)("min_samples", s.min_samples)(
      "forgetting_factor", s.forgetting_factor)("window_length", s.window_length)("resum_interval", s.resum_interval)(
      "lambda_min", s.lambda_min)("vff_c_m2", s.vff_c_m2)("vff_kappa", s.vff_kappa)(
      "vff_change_threshold", s.vff_change_threshold)("vff_change_drift", s.vff_change_drift)(
      "sigma_v_mps", s.sigma_v_mps)("sample_interval_s", s.sample_interval_s)(
      "coarse_min_length_m", s.coarse_min_length_m)("coarse_position_sigma_m", s.coarse_position_sigma_m)(
      "kf_rel_process_noise_per_sqrt_s", s.kf_rel_process_noise_per_sqrt_s)(
      "kf_change_threshold", s.kf_change_threshold)("kf_change_drift", s.kf_change_drift)("kf_change_rel_sigma",
                                                                                          s.kf_change_rel_sigma);
}

}  // namespace odonav

namespace odonav::estimators_internal {

StateJson save_estimator_state(const std::string& name, const ScaleFactorEstimatorParams& params,
                               const std::function<void(StateOut&)>& fields) {
  StateOut out;
  out("estimator", name)("params", params);
  fields(out);
  return out.take();
}

void restore_estimator_state(const StateJson& state, const std::string& name, const ScaleFactorEstimatorParams& params,
                             const std::function<void(StateIn&)>& fields) {
  try {
    StateIn in(state, "");
    std::string saved_by;
    in("estimator", saved_by);
    if (saved_by != name) throw CheckpointError("the state was saved by estimator '" + saved_by + "'");
    const StateJson ours = to_state(params);
    const StateJson& saved = state.at("params");
    if (!saved.is_object()) throw CheckpointError("field 'params' is not an object");
    for (const auto& [key, value] : ours.items()) {
      const auto it = saved.find(key);
      if (it == saved.end()) throw CheckpointError("field 'params." + key + "' is missing");
      // Equal values on purpose: a different parameter would not continue identically.
      if (*it != value)
        throw CheckpointError("saved with " + key + " = " + it->dump() + " but this estimator has " + value.dump());
    }
    fields(in);
  } catch (const std::exception& e) {
    throw CheckpointError("estimator state for '" + name + "': " + e.what());
  }
}

}  // namespace odonav::estimators_internal
