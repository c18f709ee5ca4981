#include "odonav/calibration/calibration_options.hpp"

#include <cmath>
#include <cstdlib>
#include <sstream>

namespace odonav::calibration {

void add_calibration_options(Options& o) {
  const MisalignmentCalibratorParams d;
  o.add_double("cal-min-speed", d.min_speed_mps, "calibration gate: minimum forward speed (m/s)", 0.1, 100.0);
  o.add_double("cal-max-yaw-rate-deg-s", rad_to_deg(d.max_yaw_rate_rad_s),
               "calibration gate: maximum |yaw rate| (deg/s): straight segments only", 0.01, 1000.0);
  o.add_double("cal-converged-sigma-deg", rad_to_deg(d.converged_sigma_rad),
               "misalignment converged when both sigmas are below this (deg)", 1e-5, 10.0);
  o.add_int("cal-min-samples", static_cast<int64_t>(d.min_samples),
            "misalignment converged only after this many epochs", 1, 100000000);
  o.add_bool("cal-braking-stop", d.braking_stop.enabled,
             "a braking that ends in a standstill leaves the misalignment as it was before the braking");
}

MisalignmentCalibratorParams calibration_params_from(const Options& o) {
  MisalignmentCalibratorParams p;
  p.min_speed_mps = o.get_double("cal-min-speed");
  p.max_yaw_rate_rad_s = deg_to_rad(o.get_double("cal-max-yaw-rate-deg-s"));
  p.converged_sigma_rad = deg_to_rad(o.get_double("cal-converged-sigma-deg"));
  p.min_samples = static_cast<uint64_t>(o.get_int("cal-min-samples"));
  p.lever_arm_body_m = lever_arm_from(o);
  p.braking_stop.enabled = o.get_bool("cal-braking-stop");
  return p;
}

}  // namespace odonav::calibration
