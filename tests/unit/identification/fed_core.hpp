#pragma once
// An identification core that has run: shared by the identification's lifecycle tests and the
// checkpoint tests (tests/unit/{identification,checkpoint}).
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

#include "odonav/identification/identification_core.hpp"
#include "synthetic_drive.hpp"

namespace odonav::test {

/// An identification core (main estimator `estimator`) fed a straight 10 m/s drive of `epochs` GNSS
/// epochs at 10 Hz (velocity noise 2 cm/s, noise seed `seed`), everything processed.
inline std::unique_ptr<identification::IdentificationCore> fed_core(std::size_t epochs,
                                                                    const std::string& estimator = "vff_lm_rls",
                                                                    uint32_t seed = 1) {
  identification::IdentificationParams p;
  p.estimator_name = estimator;
  auto core = std::make_unique<identification::IdentificationCore>(p);
  synthetic::SensorConfig c;
  c.duration_s = 0.1 * static_cast<double>(epochs);
  c.velocity_noise_mps = 0.02;
  c.seed = seed;
  const synthetic::SyntheticData d = synthetic::simulate(synthetic::straight(0.5, 0.0, 10.0, 0.0), c);
  synthetic::add_whole_drive(*core, d);
  core->finish();
  return core;
}

}  // namespace odonav::test
