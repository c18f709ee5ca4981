#pragma once
// The sensor samples every core works on: odometer, GNSS, INS and truth, in SI units with radians,
// time t_s in seconds on one time base. They are the rows of the dataset files (odonav/dataset.hpp,
// docs/DATASET.md) and what the DDS nodes convert the topics into, so a core that takes them needs
// neither the dataset reader (odonav_io) nor DDS: this header is part of odonav_core.
#include <Eigen/Dense>
#include <cstdint>
#include <limits>
#include <optional>

#include "odonav/frames.hpp"
#include "odonav/geodesy.hpp"

namespace odonav {

/// One odometer sample (odometer.csv row, Odometer topic). pulses is the raw accumulated uint32
/// counter (wraps 4294967295 -> 0).
struct OdometerSample {
  double t_s = 0.0;
  uint32_t pulses = 0;
  int direction = 1;  ///< +1 forward (default), -1 reversing, 0 unknown.
};

/// One GNSS epoch (gnss.csv row, GnssFix topic). Position WGS-84, velocity in local ENU (m/s).
struct GnssSample {
  double t_s = 0.0;
  Geodetic position;
  Eigen::Vector3d vel_enu_mps = Eigen::Vector3d::Zero();
  std::optional<double> pos_std_m;    ///< one-sigma horizontal accuracy if given.
  std::optional<double> vel_std_mps;  ///< one-sigma velocity accuracy if given.
  int fix = 1;                        ///< NMEA GGA quality; 0, 6, 7 and 8 are not a reference.
  /// True when the row may be used as a reference: a measured fix. Not 0 (invalid), 6 (the
  /// receiver's own dead reckoning), 7 (a position typed in by hand) or 8 (the receiver's simulator
  /// mode); 3 (PPS) and 9 (SBAS) are measured fixes.
  bool valid() const { return fix != 0 && fix != 6 && fix != 7 && fix != 8; }
};

/// One INS attitude sample (ins.csv row, InsAttitude topic). Attitude of the body (see frames.hpp);
/// optional ENU velocity (m/s).
struct InsSample {
  double t_s = 0.0;
  Attitude attitude;
  std::optional<Eigen::Vector3d> vel_enu_mps;
};

/// One truth sample (truth.csv row; simulator and evaluation only). Columns other than t are
/// optional in the file: absent ones read as NaN.
struct TruthSample {
  double t_s = 0.0;
  Geodetic position{std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN(),
                    std::numeric_limits<double>::quiet_NaN()};
  Attitude attitude{std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN(),
                    std::numeric_limits<double>::quiet_NaN()};
  double k_true_m_per_pulse = std::numeric_limits<double>::quiet_NaN();
  double distance_m = std::numeric_limits<double>::quiet_NaN();
};

/// Counter increment from `from` to `to`, modulo 2^32 (a wrap is not a jump).
inline uint32_t pulse_increment(uint32_t from, uint32_t to) { return to - from; }

}  // namespace odonav
