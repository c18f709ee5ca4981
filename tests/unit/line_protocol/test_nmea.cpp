// The simulator's NMEA writer: sentences parsed back independently (checksum, time, date, position,
// height, speed, track, accuracies) against the fix, to the precision the format carries.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <string>
#include <vector>

#include "odonav/simulator/nmea.hpp"
#include "odonav/frames.hpp"

namespace odonav::simulator {
namespace {

std::vector<std::string> fields_of(const std::string& sentence) {
  // Checks the frame and its checksum independently of nmea_frame.
  EXPECT_EQ(sentence.front(), '$');
  const std::size_t star = sentence.find('*');
  EXPECT_EQ(star, sentence.size() - 3) << sentence;
  unsigned x = 0;
  for (std::size_t i = 1; i < star; ++i) x ^= static_cast<unsigned char>(sentence[i]);
  EXPECT_EQ(std::strtoul(sentence.substr(star + 1).c_str(), nullptr, 16), x) << sentence;
  std::vector<std::string> f;
  std::string body = sentence.substr(1, star - 1), cur;
  for (char c : body) {
    if (c == ',')
      f.push_back(cur), cur.clear();
    else
      cur += c;
  }
  f.push_back(cur);
  return f;
}

double nmea_degrees(const std::string& field, const std::string& hemisphere, int degree_digits) {
  const double deg = std::stod(field.substr(0, static_cast<std::size_t>(degree_digits)));
  const double min = std::stod(field.substr(static_cast<std::size_t>(degree_digits)));
  const double v = deg + min / 60.0;
  return (hemisphere == "S" || hemisphere == "W") ? -v : v;
}

GnssSample sample_fix() {
  GnssSample g;
  g.t_s = 3723.456;  // 01:02:03.46 after the epoch
  g.position = Geodetic{deg_to_rad(-33.8567844), deg_to_rad(151.2152967), 58.1234};
  g.vel_enu_mps = Eigen::Vector3d(-3.0, 4.0, 0.2);  // 5 m/s towards 323.13 deg
  g.fix = 4;
  g.pos_std_m = 0.02;
  return g;
}

TEST(Nmea, SentencesCarryTheFixToTheirPrecision) {
  const std::vector<std::string> s = nmea_sentences(sample_fix(), NmeaSettings{});
  ASSERT_EQ(s.size(), 4u);
  const auto gga = fields_of(s[0]);
  ASSERT_EQ(gga.size(), 15u);
  EXPECT_EQ(gga[0], "GPGGA");
  EXPECT_EQ(gga[1], "010203.46");
  EXPECT_NEAR(nmea_degrees(gga[2], gga[3], 2), -33.8567844, 1e-7 / 60.0);
  EXPECT_NEAR(nmea_degrees(gga[4], gga[5], 3), 151.2152967, 1e-7 / 60.0);
  EXPECT_EQ(gga[6], "4");
  EXPECT_NEAR(std::stod(gga[9]) + std::stod(gga[11]), 58.1234, 0.0005);  // altitude + separation = ellipsoidal
  const auto rmc = fields_of(s[1]);
  EXPECT_EQ(rmc[0], "GPRMC");
  EXPECT_EQ(rmc[2], "A");
  EXPECT_NEAR(std::stod(rmc[7]) * 1852.0 / 3600.0, 5.0, 0.0005 * 1852.0 / 3600.0);
  EXPECT_NEAR(std::stod(rmc[8]), 360.0 - rad_to_deg(std::atan2(3.0, 4.0)), 0.005);
  EXPECT_EQ(rmc[9], "010126");  // 2026-01-01 (the default epoch)
  EXPECT_EQ(rmc[12], "R");
  const auto vtg = fields_of(s[2]);
  EXPECT_EQ(vtg[0], "GPVTG");
  EXPECT_NEAR(std::stod(vtg[7]), 18.0, 0.0005);  // km/h
  const auto gst = fields_of(s[3]);
  EXPECT_EQ(gst[0], "GPGST");
  EXPECT_NEAR(std::hypot(std::stod(gst[6]), std::stod(gst[7])), 0.02, 0.001);
}

TEST(Nmea, DateRollsOverAtMidnightOfALeapDay) {
  NmeaSettings st;
  st.utc_epoch_s = 951782400.0;  // 2000-02-29T00:00:00Z (date -u -d @951782400)
  GnssSample g = sample_fix();
  g.t_s = 86399.996;  // rounds to 24:00:00.00: the next day, 1 March
  EXPECT_EQ(fields_of(nmea_sentences(g, st)[1])[9], "010300");
  EXPECT_EQ(fields_of(nmea_sentences(g, st)[1])[1], "000000.00");
  g.t_s = 86399.5;
  EXPECT_EQ(fields_of(nmea_sentences(g, st)[1])[9], "290200");
  EXPECT_EQ(fields_of(nmea_sentences(g, st)[1])[1], "235959.50");
}

TEST(Nmea, MinutesNeverPrintAsSixty) {
  GnssSample g = sample_fix();
  g.position.lat_rad = deg_to_rad(10.0 - 1e-12);  // 9 deg 59.99999999994 min
  const auto gga = fields_of(nmea_sentences(g, NmeaSettings{})[0]);
  EXPECT_EQ(gga[2], "1000.0000000");
  EXPECT_EQ(gga[3], "N");
}

TEST(Nmea, NoFixGivesEmptyPositionAndBadValuesThrow) {
  GnssSample g = sample_fix();
  g.fix = 0;
  g.pos_std_m.reset();
  const auto s = nmea_sentences(g, NmeaSettings{});
  ASSERT_EQ(s.size(), 3u);
  const auto gga = fields_of(s[0]);
  EXPECT_EQ(gga[2], "");
  EXPECT_EQ(gga[6], "0");
  EXPECT_EQ(fields_of(s[1])[2], "V");
  g.position.height_m = std::nan("");
  EXPECT_THROW(nmea_sentences(g, NmeaSettings{}), std::invalid_argument);
  NmeaSettings bad;
  bad.talker = "G";
  EXPECT_THROW(nmea_sentences(sample_fix(), bad), std::invalid_argument);
}

}  // namespace
}  // namespace odonav::simulator
