#pragma once
// NMEA 0183 output of simulated GNSS fixes (GGA, RMC, VTG, GST), for feeding gpsd (gpsfake) and
// any receiver-facing tool with a scenario's GNSS.
//
// Time: a fix stamped t_s (dataset time base) is reported at UTC utc_epoch_s + t_s, where
// utc_epoch_s is seconds since 1970-01-01T00:00:00Z (leap seconds ignored, as NMEA does).
// Height: GGA carries the ellipsoidal height as altitude above MSL with a geoid separation of 0,
// so altitude + separation (what gpsd reports as altHAE) is the dataset's ellipsoidal height.
// Precision: latitude/longitude minutes with 7 decimals (about 0.2 mm), height 0.001 m, speed
// 0.001 knot (0.5 mm/s), track 0.01 deg, time 0.01 s. The vertical velocity is not carried (NMEA
// 0183 has no field for it).
#include <cstdint>
#include <string>
#include <vector>

#include "odonav/dataset.hpp"

namespace odonav::simulator {

/// Settings of the NMEA writer.
struct NmeaSettings {
  double utc_epoch_s = 1767225600.0;  ///< UTC of t = 0: 2026-01-01T00:00:00Z by default; finite, >= 0.
  std::string talker = "GP";          ///< two letters: GP (GPS), GN (multi-constellation).
  int satellites = 10;                ///< GGA satellites in use, 0..99.
  double hdop = 0.9;                  ///< GGA horizontal dilution of precision, >= 0.
};

/// The sentences of one fix, in the order GGA, RMC, VTG, and GST when the fix has pos_std_m; each
/// "$...*HH" without a line end. A fix with quality 0 gives empty position fields and status V
/// (what receivers send without a fix). Throws std::invalid_argument naming the field for a
/// non-finite time, position or velocity, or settings out of their range.
std::vector<std::string> nmea_sentences(const GnssSample& fix, const NmeaSettings& settings);

/// "$" + body + "*HH": HH the XOR of the body's bytes in two upper-case hex digits.
std::string nmea_frame(const std::string& body);

}  // namespace odonav::simulator
