#pragma once
// A reference K for a recording without truth (the smartLoc drive), computed independently of the
// product: shared by the offline tests and odonav-bench-coverage.
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "odonav/dataset.hpp"
#include "odonav/geodesy.hpp"
#include "odonav/sensor_samples.hpp"

namespace odonav::test {

/// The path length of the reference trajectory (the sum of horizontal steps between consecutive
/// fixes on a sphere of the mean radius; the steps of the recordings are ~1 m, where the
/// sphere/ellipsoid difference is far below 0.1 %) over the pulses counted. It assumes one constant
/// K over the drive.
inline double reference_k_m_per_pulse(const Dataset& d) {
  double distance_m = 0.0;
  for (std::size_t i = 1; i < d.gnss.size(); ++i) {
    const Geodetic& a = d.gnss[i - 1].position;
    const Geodetic& b = d.gnss[i].position;
    distance_m += 6371000.0 * std::hypot(b.lat_rad - a.lat_rad, (b.lon_rad - a.lon_rad) * std::cos(a.lat_rad));
  }
  uint64_t pulses = 0;
  for (std::size_t i = 1; i < d.odometer.size(); ++i)
    pulses += pulse_increment(d.odometer[i - 1].pulses, d.odometer[i].pulses);
  return distance_m / static_cast<double>(pulses);
}

}  // namespace odonav::test
