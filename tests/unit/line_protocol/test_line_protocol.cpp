// The gateway's line protocol: exact round trip of simulated samples, the NMEA checksum, each
// error kind counted, per-stream time order, the length limit, and a garbage stream survived.
#include <gtest/gtest.h>

#include <cstdio>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "odonav/gateway/line_protocol.hpp"
#include "odonav/gateway/sensor_source.hpp"
#include "odonav/simulator/simulator.hpp"

namespace odonav::gateway {
namespace {

Dataset short_drive(double duration_s) {
  simulator::SimulationConfig cfg = simulator::scenario_config("terrain");
  cfg.duration_s = duration_s;
  cfg.seed = 7;
  return as_recorded(simulator::simulate(cfg));
}

std::vector<ParsedLine> feed_all(LineDecoder& d, const std::string& bytes) {
  std::vector<ParsedLine> out;
  d.feed(bytes, out);
  return out;
}

TEST(LineProtocol, SimulatedSamplesRoundTripExactly) {
  const Dataset ds = short_drive(20.0);
  ASSERT_GT(ds.odometer.size(), 1000u);
  ASSERT_GT(ds.gnss.size(), 100u);
  LineDecoder d;
  for (std::size_t i = 0; i < ds.odometer.size(); ++i) {
    const ParsedLine p = d.parse_line(odometer_line(ds.odometer[i], i % 2 == 0));
    ASSERT_EQ(p.kind, ParsedLine::Kind::kOdometer) << p.detail;
    EXPECT_EQ(p.odometer.t_s, ds.odometer[i].t_s);
    EXPECT_EQ(p.odometer.pulses, ds.odometer[i].pulses);
    EXPECT_EQ(p.odometer.direction, ds.odometer[i].direction);
  }
  for (std::size_t i = 0; i < ds.ins.size(); ++i) {
    const ParsedLine p = d.parse_line(ins_line(ds.ins[i], i % 3 == 0));
    ASSERT_EQ(p.kind, ParsedLine::Kind::kIns) << p.detail;
    EXPECT_EQ(p.ins.t_s, ds.ins[i].t_s);
    // as_recorded angles are exactly what the degrees of a dataset file give back.
    EXPECT_EQ(p.ins.attitude.heading_rad, ds.ins[i].attitude.heading_rad);
    EXPECT_EQ(p.ins.attitude.pitch_rad, ds.ins[i].attitude.pitch_rad);
    EXPECT_EQ(p.ins.attitude.roll_rad, ds.ins[i].attitude.roll_rad);
  }
  for (std::size_t i = 0; i < ds.gnss.size(); ++i) {
    const ParsedLine p = d.parse_line(gnss_line(ds.gnss[i], i % 2 == 1));
    ASSERT_EQ(p.kind, ParsedLine::Kind::kGnss) << p.detail;
    const GnssSample& g = ds.gnss[i];
    EXPECT_EQ(p.gnss.t_s, g.t_s);
    EXPECT_EQ(p.gnss.position.lat_rad, g.position.lat_rad);
    EXPECT_EQ(p.gnss.position.lon_rad, g.position.lon_rad);
    EXPECT_EQ(p.gnss.position.height_m, g.position.height_m);
    EXPECT_EQ(p.gnss.vel_enu_mps, g.vel_enu_mps);
    EXPECT_EQ(p.gnss.fix, g.fix);
    EXPECT_EQ(p.gnss.pos_std_m.has_value(), g.pos_std_m.has_value() && g.vel_std_mps.has_value());
    if (p.gnss.pos_std_m) {
      EXPECT_EQ(*p.gnss.pos_std_m, *g.pos_std_m);
      EXPECT_EQ(*p.gnss.vel_std_mps, *g.vel_std_mps);
    }
  }
  const LineCounters& c = d.counters();
  EXPECT_EQ(c.total_errors(), 0u);
  EXPECT_EQ(c.samples[0], ds.odometer.size());
  EXPECT_EQ(c.samples[1], ds.ins.size());
  EXPECT_EQ(c.samples[2], ds.gnss.size());
}

TEST(LineProtocol, ChecksumIsTheNmeaXor) {
  // The textbook GGA sentence and its published checksum 47.
  EXPECT_EQ(line_checksum("GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"), 0x47);
  LineDecoder d;
  const std::string body = "ODO,12.5,1000,1";
  char hh[3];
  std::snprintf(hh, sizeof(hh), "%02X", line_checksum(body));
  EXPECT_EQ(d.parse_line("$" + body + "*" + hh).kind, ParsedLine::Kind::kOdometer);
  // Lower-case hex digits and no '$' are accepted too.
  std::snprintf(hh, sizeof(hh), "%02x", line_checksum("ODO,13,1001"));
  EXPECT_EQ(d.parse_line(std::string("ODO,13,1001*") + hh).kind, ParsedLine::Kind::kOdometer);
  // A changed character in the body, a '$' without a checksum, bad hex digits, one digit.
  // One character changed ('5' -> '6') always changes the XOR.
  std::snprintf(hh, sizeof(hh), "%02X", line_checksum(body));
  const ParsedLine flipped = d.parse_line("$ODO,12.6,1000,1*" + std::string(hh));
  EXPECT_EQ(flipped.kind, ParsedLine::Kind::kError);
  EXPECT_EQ(flipped.error, LineError::kBadChecksum);
  EXPECT_EQ(d.parse_line("$ODO,15,1002").error, LineError::kBadChecksum);
  EXPECT_EQ(d.parse_line("$ODO,15,1002*G1").error, LineError::kBadChecksum);
  EXPECT_EQ(d.parse_line("$ODO,15,1002*1").error, LineError::kBadChecksum);
  EXPECT_EQ(d.counters().errors[static_cast<int>(LineError::kBadChecksum)], 4u);
  EXPECT_EQ(d.counters().samples[0], 2u);
}

TEST(LineProtocol, EachErrorKindIsClassifiedAndNamesTheField) {
  LineDecoder d;
  struct Case {
    const char* line;
    LineError error;
    const char* detail_part;
  };
  const Case cases[] = {
      {"XYZ,1,2", LineError::kMalformed, "unknown line type 'XYZ'"},
      {"ODO,1.0,abc", LineError::kMalformed, "pulses"},
      {"ODO,1.0,-5", LineError::kMalformed, "pulses"},
      {"ODO,1.0,4294967296", LineError::kMalformed, "pulses"},
      {"ODO,1.0,5,2", LineError::kMalformed, "direction"},
      {"ODO,1x,5", LineError::kMalformed, "field t"},
      {"ATT,1.0,10,95,0", LineError::kMalformed, "pitch_deg"},
      {"GNSS,1.0,91,10,100,0,0,0,1", LineError::kMalformed, "lat_deg"},
      {"GNSS,1.0,45,10,100,0,0,0,1.5", LineError::kMalformed, "fix"},
      {"ODO,1.0", LineError::kWrongFieldCount, "ODO with 2 fields"},
      {"ODO,1.0,5,1,9", LineError::kWrongFieldCount, "ODO with 5 fields"},
      {"ATT,1.0,10,0", LineError::kWrongFieldCount, "ATT with 4 fields"},
      {"GNSS,1.0,45,10,100,0,0,0,1,0.5", LineError::kWrongFieldCount, "GNSS with 10 fields"},
      {"ATT,1.0,nan,0,0", LineError::kNonFinite, "heading_deg"},
      {"GNSS,1.0,45,10,inf,0,0,0,1", LineError::kNonFinite, "height_m"},
      {"ODO,1e999,5", LineError::kNonFinite, "field t"},
  };
  std::size_t line_number = 0;
  for (const Case& c : cases) {
    ++line_number;
    const ParsedLine p = d.parse_line(c.line);
    ASSERT_EQ(p.kind, ParsedLine::Kind::kError) << c.line;
    EXPECT_EQ(p.error, c.error) << c.line << " -> " << p.detail;
    EXPECT_NE(p.detail.find(c.detail_part), std::string::npos) << p.detail;
    EXPECT_EQ(p.detail.rfind("line " + std::to_string(line_number) + ": ", 0), 0u) << p.detail;
  }
  const LineCounters& n = d.counters();
  EXPECT_EQ(n.errors[static_cast<int>(LineError::kMalformed)], 9u);
  EXPECT_EQ(n.errors[static_cast<int>(LineError::kWrongFieldCount)], 4u);
  EXPECT_EQ(n.errors[static_cast<int>(LineError::kNonFinite)], 3u);
  EXPECT_EQ(n.lines, std::size(cases));
  // Empty lines, comments and a lone '\r' are ignored, not errors; '+' signs and CRLF are accepted.
  EXPECT_EQ(d.parse_line("").kind, ParsedLine::Kind::kIgnored);
  EXPECT_EQ(d.parse_line("# device v1.2").kind, ParsedLine::Kind::kIgnored);
  EXPECT_EQ(d.parse_line("\r").kind, ParsedLine::Kind::kIgnored);
  const ParsedLine ok = d.parse_line("ODO,+2.5,17,+1\r");
  ASSERT_EQ(ok.kind, ParsedLine::Kind::kOdometer) << ok.detail;
  EXPECT_EQ(ok.odometer.t_s, 2.5);
  EXPECT_EQ(ok.odometer.pulses, 17u);
  EXPECT_EQ(n.total_errors(), std::size(cases));
}

TEST(LineProtocol, TimeMustIncreasePerStream) {
  LineDecoder d;
  EXPECT_EQ(d.parse_line("ODO,10,100").kind, ParsedLine::Kind::kOdometer);
  // Another stream has its own clock edge: an earlier GNSS time is fine.
  EXPECT_EQ(d.parse_line("GNSS,9.9,45,10,100,1,2,0,1").kind, ParsedLine::Kind::kGnss);
  EXPECT_EQ(d.parse_line("ATT,9.8,350,1,-2").kind, ParsedLine::Kind::kIns);
  const ParsedLine same = d.parse_line("ODO,10,101");
  EXPECT_EQ(same.error, LineError::kTimeBackwards);
  EXPECT_NE(same.detail.find("t=10 s does not increase"), std::string::npos) << same.detail;
  EXPECT_EQ(d.parse_line("ODO,9.5,101").error, LineError::kTimeBackwards);
  EXPECT_EQ(d.parse_line("GNSS,9.0,45,10,100,1,2,0,1").error, LineError::kTimeBackwards);
  // The rejected lines do not move the edge: 10.01 follows 10.
  const ParsedLine next = d.parse_line("ODO,10.01,102");
  ASSERT_EQ(next.kind, ParsedLine::Kind::kOdometer) << next.detail;
  EXPECT_EQ(d.counters().errors[static_cast<int>(LineError::kTimeBackwards)], 3u);
  EXPECT_EQ(d.counters().samples[0], 2u);
}

TEST(LineProtocol, LinesOfAtMost256BytesPassLongerOnesAreSkippedToTheirEnd) {
  // "ODO,1.000...0,5": t padded with zeros to an exact length.
  auto padded = [](std::size_t length) {
    std::string line = "ODO,1.";
    const std::string tail = ",5";
    line += std::string(length - line.size() - tail.size(), '0');
    return line + tail;
  };
  ASSERT_EQ(padded(256).size(), 256u);
  LineDecoder d;
  const auto a = feed_all(d, padded(256) + "\r\n");
  ASSERT_EQ(a.size(), 1u);
  EXPECT_EQ(a[0].kind, ParsedLine::Kind::kOdometer) << a[0].detail;
  // 257 bytes, and 10 kB without a line end: each is one overlong error; the next line still flows.
  const auto b = feed_all(d, padded(257) + "\n" + std::string(10000, 'A') + "\nODO,2,6\n");
  ASSERT_EQ(b.size(), 3u);
  EXPECT_EQ(b[0].error, LineError::kOverlong);
  EXPECT_EQ(b[1].error, LineError::kOverlong);
  ASSERT_EQ(b[2].kind, ParsedLine::Kind::kOdometer);
  EXPECT_EQ(b[2].odometer.pulses, 6u);
  EXPECT_EQ(d.counters().errors[static_cast<int>(LineError::kOverlong)], 2u);
  // parse_line alone applies the same limit.
  EXPECT_EQ(d.parse_line(padded(300)).error, LineError::kOverlong);
}

TEST(LineProtocol, DatagramEndsItsLastLine) {
  LineDecoder d;
  std::vector<ParsedLine> out;
  d.feed("ODO,1,10\nODO,2,20", out);
  EXPECT_EQ(out.size(), 1u);
  d.end_of_record(out);
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(out[1].odometer.pulses, 20u);
  // Nothing buffered: no extra line.
  d.end_of_record(out);
  EXPECT_EQ(out.size(), 2u);
}

TEST(LineProtocol, GarbageStreamIsSurvivedAndGoodLinesStillFlow) {
  const Dataset ds = short_drive(10.0);
  std::mt19937 rng(20260921);
  std::uniform_int_distribution<int> byte(0, 255);
  std::uniform_int_distribution<int> garbage_length(0, 600);  // up to twice the line limit
  std::string stream;
  std::size_t good = 0;
  for (std::size_t i = 0; i < ds.odometer.size(); ++i) {
    const int n = garbage_length(rng);
    for (int k = 0; k < n; ++k) stream.push_back(static_cast<char>(byte(rng)));
    // A good line after garbage needs a line end first: the garbage's last partial line is lost.
    stream += "\n" + odometer_line(ds.odometer[i], i % 2 == 0) + "\n";
    ++good;
  }
  // Feed in random chunks, as a serial port delivers them.
  LineDecoder d;
  std::vector<ParsedLine> out;
  std::uniform_int_distribution<std::size_t> chunk(1, 97);
  for (std::size_t pos = 0; pos < stream.size();) {
    const std::size_t n = std::min(chunk(rng), stream.size() - pos);
    d.feed(std::string_view(stream).substr(pos, n), out);
    pos += n;
  }
  std::vector<OdometerSample> accepted;
  std::size_t errors = 0, ignored = 0;
  for (const ParsedLine& p : out) {
    if (p.kind == ParsedLine::Kind::kOdometer)
      accepted.push_back(p.odometer);
    else if (p.kind == ParsedLine::Kind::kError)
      ++errors;
    else if (p.kind == ParsedLine::Kind::kIgnored)
      ++ignored;
  }
  ASSERT_EQ(accepted.size(), good);
  for (std::size_t i = 0; i < good; ++i) {
    EXPECT_EQ(accepted[i].t_s, ds.odometer[i].t_s);
    EXPECT_EQ(accepted[i].pulses, ds.odometer[i].pulses);
  }
  const LineCounters& c = d.counters();
  EXPECT_EQ(c.samples[0], good);
  EXPECT_EQ(c.total_errors(), errors);
  EXPECT_EQ(c.lines, good + errors + ignored);
  // Random bytes give malformed lines and, between rare '\n's (1 byte in 256), overlong ones.
  EXPECT_GT(c.errors[static_cast<int>(LineError::kMalformed)], 0u);
  EXPECT_GT(c.errors[static_cast<int>(LineError::kOverlong)], 0u);
  std::printf("garbage stream: %zu bytes, %llu lines, %zu good, %llu malformed, %llu overlong, %llu other errors\n",
              stream.size(), static_cast<unsigned long long>(c.lines), good,
              static_cast<unsigned long long>(c.errors[0]), static_cast<unsigned long long>(c.errors[3]),
              static_cast<unsigned long long>(c.total_errors() - c.errors[0] - c.errors[3]));
}

TEST(LineProtocol, WritersRefuseNonFiniteValues) {
  OdometerSample o;
  o.t_s = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(odometer_line(o, false), std::invalid_argument);
  GnssSample g;
  g.vel_enu_mps.x() = std::numeric_limits<double>::infinity();
  EXPECT_THROW(gnss_line(g, true), std::invalid_argument);
}

TEST(LineProtocol, AnyLongitudeIsHeldInMinus180To180) {
  LineDecoder d;
  ParsedLine p = d.parse_line("GNSS,1.0,65,180,100,0,0,0,1");
  ASSERT_EQ(p.kind, ParsedLine::Kind::kGnss) << p.detail;
  EXPECT_EQ(p.gnss.position.lon_rad, deg_to_rad(-180.0));
  p = d.parse_line("GNSS,2.0,65,190.5,100,0,0,0,1");
  ASSERT_EQ(p.kind, ParsedLine::Kind::kGnss) << p.detail;
  EXPECT_EQ(p.gnss.position.lon_rad, deg_to_rad(-169.5));
  p = d.parse_line("GNSS,3.0,90,-179.25,100,0,0,0,1");  // on the pole: kept as given
  ASSERT_EQ(p.kind, ParsedLine::Kind::kGnss) << p.detail;
  EXPECT_EQ(p.gnss.position.lon_rad, deg_to_rad(-179.25));
}

}  // namespace
}  // namespace odonav::gateway
