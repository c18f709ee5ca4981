#include "odonav/identification/identification_options.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

#include "odonav/hold_off_option.hpp"

namespace odonav::identification {

void add_identification_options(Options& o) {
  add_estimate_hold_off_option(o);
  const IdentificationParams d;
  std::vector<std::string> names = estimator_names();
  o.add_choice("estimator", d.estimator_name, names, "scale-factor estimator published and used by dead reckoning");
  o.add_int("window", static_cast<int64_t>(d.estimator.window_length),
            "window length L of lm_rls / vff_lm_rls, in accepted samples (L x GNSS period ~ memory)", 2, 1000000);
  o.add_double("lambda-min", d.estimator.lambda_min,
               "lower bound of the variable forgetting factor per 0.1 s of GNSS interval (lambda_min^n for n x 0.1 s)",
               0.5, 1.0);
  o.add_double("vff-kappa", d.estimator.vff_kappa, "VFF: C = kappa * sigma_y^2 when --vff-c is 0", 1e-3, 1e6);
  o.add_double("vff-c", d.estimator.vff_c_m2, "VFF: residual variance scale C (m^2); 0 = automatic", 0.0, 1e6);
  o.add_double("vff-change-threshold", d.estimator.vff_change_threshold,
               "VFF: CUSUM threshold (sigmas) of the change detector that cuts the window back after a change of "
               "K; 0 = off",
               0.0, 1e6);
  o.add_double("ff-lambda", d.estimator.forgetting_factor, "constant forgetting factor of ff_rls", 0.5, 1.0);
  o.add_double("converged-rel-sigma", d.estimator.converged_rel_sigma,
               "K is 'converged' when sigma_K / K is below this", 1e-6, 1.0);
  o.add_double("id-min-speed", d.builder.min_speed_mps, "gate: minimum speed at both ends of a sample (m/s)", 0.0,
               100.0);
  o.add_double("id-max-yaw-rate-deg-s", rad_to_deg(d.builder.max_yaw_rate_rad_s),
               "gate: maximum |yaw rate| over a sample (deg/s)", 0.1, 1000.0);
  o.add_double("innovation-n-sigma", d.builder.innovation_n_sigma, "gate: GNSS velocity outlier threshold (sigmas)",
               1.0, 1000.0);
  o.add_double("gnss-velocity-sigma", d.builder.gnss_velocity_sigma_mps,
               "one-sigma GNSS velocity noise assumed by the outlier gate (m/s)", 1e-4, 10.0);
  o.add_double("max-interval-s", d.builder.max_interval_s,
               "gate: longest GNSS interval a sample may span (s); 0 = from the observed GNSS period P: "
               "max(0.5 s, 2.5 P)",
               0.0, 100.0);
  o.add_double("min-pulses", d.builder.min_pulses, "gate: minimum pulses counted over a sample (quantisation)", 0.0,
               1e9);
  o.add_bool("turn-slip", d.turn_slip_enabled,
             "estimate the track slip in turns (pulses per metre growing with the yaw rate beyond the yaw-rate gate) "
             "and publish it for dead reckoning");
  o.add_bool("reversing-samples", d.builder.reversing_samples,
             "intervals driven backwards (odometer direction -1 throughout) make samples of K too");
  o.add_bool("id-braking-stop", d.braking_stop.enabled,
             "a braking that ends in a standstill leaves K as it was before the braking (its samples are withdrawn)");
  o.add_double("id-braking-stop-decel-mps2", d.braking_stop.braking_mps2,
               "with --id-braking-stop: braking is the GNSS speed falling faster than this over 1 s (m/s^2)", 0.01,
               100.0);
  o.add_string("gnss-latency-s", "auto",
               "GNSS latency (s) the fixes are stamped late by (receiver delay or clock offset): 'auto' "
               "estimates it online, 'off' assumes 0, a number fixes it (negative: stamps that lead the "
               "measurement)");
  // The identification's gates carry "id-" as the calibration's carry "cal-": one name, one meaning
  // in every program (odonav-offline takes both).
  o.add_renamed("min-speed", "id-min-speed");
  o.add_renamed("max-yaw-rate-deg-s", "id-max-yaw-rate-deg-s");
  o.add_renamed("braking-stop", "id-braking-stop");
  o.add_renamed("braking-stop-decel-mps2", "id-braking-stop-decel-mps2");
}

std::optional<double> parse_gnss_latency_option(const std::string& text, bool& estimate) {
  estimate = false;
  if (text == "auto") {
    estimate = true;
    return std::nullopt;
  }
  if (text == "off") return std::nullopt;
  std::size_t used = 0;
  double v = 0.0;
  try {
    v = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != text.size() || text.empty() || !std::isfinite(v) || std::abs(v) >= 10.0)
    throw ConfigError("--gnss-latency-s: '" + text + "' is not 'auto', 'off' or a latency in seconds within +-10");
  return v;
}

IdentificationParams identification_params_from(const Options& o) {
  IdentificationParams p;
  p.estimator_name = o.get_string("estimator");
  p.estimator.window_length = static_cast<std::size_t>(o.get_int("window"));
  p.estimator.lambda_min = o.get_double("lambda-min");
  p.estimator.vff_kappa = o.get_double("vff-kappa");
  p.estimator.vff_c_m2 = o.get_double("vff-c");
  p.estimator.vff_change_threshold = o.get_double("vff-change-threshold");
  p.estimator.forgetting_factor = o.get_double("ff-lambda");
  p.estimator.converged_rel_sigma = o.get_double("converged-rel-sigma");
  p.builder.min_speed_mps = o.get_double("id-min-speed");
  p.builder.max_yaw_rate_rad_s = deg_to_rad(o.get_double("id-max-yaw-rate-deg-s"));
  p.builder.innovation_n_sigma = o.get_double("innovation-n-sigma");
  p.builder.gnss_velocity_sigma_mps = o.get_double("gnss-velocity-sigma");
  p.builder.max_interval_s = o.get_double("max-interval-s");
  p.builder.min_pulses = o.get_double("min-pulses");
  p.builder.reversing_samples = o.get_bool("reversing-samples");
  p.turn_slip_enabled = o.get_bool("turn-slip");
  p.braking_stop.enabled = o.get_bool("id-braking-stop");
  p.braking_stop.braking_mps2 = o.get_double("id-braking-stop-decel-mps2");
  bool estimate_latency = true;
  p.builder.gnss_latency_fixed_s = parse_gnss_latency_option(o.get_string("gnss-latency-s"), estimate_latency);
  p.builder.latency_estimation_enabled = estimate_latency;
  try {
    p.estimator.validate();
  } catch (const std::invalid_argument& e) {
    throw ConfigError(std::string("identification parameters: ") + e.what());
  }
  return p;
}

IdentificationParams identification_params_for(const Options& o, const IdentificationVehicleFacts& facts) {
  if (!std::isfinite(facts.nominal_k_m_per_pulse) || facts.nominal_k_m_per_pulse <= 0.0) {
    std::ostringstream m;
    m << "identification parameters: nominal K must be finite and > 0 m/pulse (got " << facts.nominal_k_m_per_pulse
      << ")";
    throw ConfigError(m.str());
  }
  IdentificationParams p = identification_params_from(o);
  p.builder.use_ins = facts.use_ins;
  p.builder.lever_arm_body_m = facts.lever_arm_body_m;
  p.builder.odometer_jump_gate.k_m_per_pulse = facts.nominal_k_m_per_pulse;
  p.run_all_estimators = facts.run_all_estimators;
  p.estimate_hold_off_s = estimate_hold_off_from(o);
  return p;
}

}  // namespace odonav::identification
