#include "odonav/simulator/nmea.hpp"

#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "odonav/frames.hpp"

namespace odonav::simulator {

namespace {

constexpr double kMetresPerSecondPerKnot = 1852.0 / 3600.0;

void require_finite(double v, const char* what) {
  if (!std::isfinite(v)) throw std::invalid_argument(std::string("NMEA output: ") + what + " is not finite");
}

/// Civil date of a day count since 1970-01-01 (proleptic Gregorian; H. Hinnant's days_from_civil inverse).
void civil_from_days(long long z, int& year, int& month, int& day) {
  z += 719468;
  const long long era = (z >= 0 ? z : z - 146096) / 146097;
  const long long doe = z - era * 146097;
  const long long yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
  const long long doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
  const long long mp = (5 * doy + 2) / 153;
  day = static_cast<int>(doy - (153 * mp + 2) / 5 + 1);
  month = static_cast<int>(mp < 10 ? mp + 3 : mp - 9);
  year = static_cast<int>(yoe + era * 400 + (month <= 2 ? 1 : 0));
}

/// "ddmm.mmmmmmm,N" / "dddmm.mmmmmmm,E": rounded once, in units of 1e-7 minute, so 59.99999999
/// minutes cannot print as "60.0000000".
std::string angle_field(double deg, int degree_digits, char positive, char negative) {
  const long long units = std::llround(std::fabs(deg) * 60.0 * 1e7);
  const long long per_degree = 60LL * 10000000LL;
  char buf[48];
  std::snprintf(buf, sizeof(buf), "%0*lld%02lld.%07lld,%c", degree_digits, units / per_degree,
                (units % per_degree) / 10000000LL, units % 10000000LL, deg < 0.0 ? negative : positive);
  return buf;
}

}  // namespace

std::string nmea_frame(const std::string& body) {
  unsigned x = 0;
  for (char c : body) x ^= static_cast<unsigned char>(c);
  char hh[4];
  std::snprintf(hh, sizeof(hh), "%02X", x & 0xFF);
  return "$" + body + "*" + hh;
}

std::vector<std::string> nmea_sentences(const GnssSample& fix, const NmeaSettings& settings) {
  require_finite(fix.t_s, "t");
  require_finite(fix.position.lat_rad, "latitude");
  require_finite(fix.position.lon_rad, "longitude");
  require_finite(fix.position.height_m, "height");
  require_finite(fix.vel_enu_mps.x(), "ve");
  require_finite(fix.vel_enu_mps.y(), "vn");
  if (!std::isfinite(settings.utc_epoch_s) || settings.utc_epoch_s < 0.0)
    throw std::invalid_argument("NMEA output: utc_epoch_s must be finite and >= 0");
  if (settings.talker.size() != 2) throw std::invalid_argument("NMEA output: talker must be two letters");
  if (settings.satellites < 0 || settings.satellites > 99 || !(settings.hdop >= 0.0))
    throw std::invalid_argument("NMEA output: satellites must be in 0..99 and hdop >= 0");
  const double utc_s = settings.utc_epoch_s + fix.t_s;
  if (utc_s < 0.0) throw std::invalid_argument("NMEA output: t is before 1970");

  // Time of day and date from one rounding to 0.01 s (a fix at 23:59:59.996 is the next day).
  const long long centis = std::llround(utc_s * 100.0);
  const long long day_count = centis / 8640000LL;
  const long long in_day = centis % 8640000LL;
  char time_field[16];
  std::snprintf(time_field, sizeof(time_field), "%02lld%02lld%02lld.%02lld", in_day / 360000LL,
                (in_day / 6000LL) % 60LL, (in_day / 100LL) % 60LL, in_day % 100LL);
  int year = 0, month = 0, day = 0;
  civil_from_days(day_count, year, month, day);
  char date_field[8];
  std::snprintf(date_field, sizeof(date_field), "%02d%02d%02d", day, month, year % 100);

  const bool has_fix = fix.fix != 0;
  const std::string lat = has_fix ? angle_field(rad_to_deg(fix.position.lat_rad), 2, 'N', 'S') : ",";
  const std::string lon = has_fix ? angle_field(rad_to_deg(fix.position.lon_rad), 3, 'E', 'W') : ",";
  const double speed_mps = std::hypot(fix.vel_enu_mps.x(), fix.vel_enu_mps.y());
  double track_deg = rad_to_deg(std::atan2(fix.vel_enu_mps.x(), fix.vel_enu_mps.y()));
  if (track_deg < 0.0) track_deg += 360.0;
  // FAA mode: A autonomous, D differential, R RTK fixed, F RTK float, E dead reckoning, N none.
  const char mode = fix.fix == 0   ? 'N'
                    : fix.fix == 2 ? 'D'
                    : fix.fix == 4 ? 'R'
                    : fix.fix == 5 ? 'F'
                    : fix.fix == 6 ? 'E'
                                   : 'A';
  const std::string& tk = settings.talker;
  char buf[256];
  std::vector<std::string> out;

  if (has_fix)
    std::snprintf(buf, sizeof(buf), "%sGGA,%s,%s,%s,%d,%02d,%.1f,%.3f,M,0.000,M,,", tk.c_str(), time_field, lat.c_str(),
                  lon.c_str(), fix.fix, settings.satellites, settings.hdop, fix.position.height_m);
  else
    std::snprintf(buf, sizeof(buf), "%sGGA,%s,,,,,0,00,,,M,,M,,", tk.c_str(), time_field);
  out.push_back(nmea_frame(buf));

  std::snprintf(buf, sizeof(buf), "%sRMC,%s,%c,%s,%s,%.3f,%.2f,%s,,,%c", tk.c_str(), time_field, has_fix ? 'A' : 'V',
                lat.c_str(), lon.c_str(), speed_mps / kMetresPerSecondPerKnot, track_deg, date_field, mode);
  out.push_back(nmea_frame(buf));

  std::snprintf(buf, sizeof(buf), "%sVTG,%.2f,T,,M,%.3f,N,%.3f,K,%c", tk.c_str(), track_deg,
                speed_mps / kMetresPerSecondPerKnot, speed_mps * 3.6, mode);
  out.push_back(nmea_frame(buf));

  if (fix.pos_std_m && std::isfinite(*fix.pos_std_m)) {
    // One-sigma horizontal accuracy split evenly over latitude and longitude (a circular error).
    const double axis_m = *fix.pos_std_m / std::sqrt(2.0);
    std::snprintf(buf, sizeof(buf), "%sGST,%s,%.3f,%.3f,%.3f,0.0,%.3f,%.3f,", tk.c_str(), time_field, *fix.pos_std_m,
                  axis_m, axis_m, axis_m, axis_m);
    out.push_back(nmea_frame(buf));
  }
  return out;
}

}  // namespace odonav::simulator
