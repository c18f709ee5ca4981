#include "odonav/gateway/line_protocol.hpp"

#include <charconv>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <system_error>

#include "odonav/gateway/sensor_source.hpp"
#include "odonav/frames.hpp"
#include "odonav/printf_text.hpp"

namespace odonav::gateway {

const char* to_string(LineError error) {
  switch (error) {
    case LineError::kMalformed: return "malformed";
    case LineError::kBadChecksum: return "bad_checksum";
    case LineError::kTimeBackwards: return "time_backwards";
    case LineError::kOverlong: return "overlong";
    case LineError::kWrongFieldCount: return "wrong_field_count";
    case LineError::kNonFinite: return "non_finite";
  }
  return "unknown";
}

std::uint64_t LineCounters::total_errors() const {
  std::uint64_t n = 0;
  for (auto e : errors) n += e;
  return n;
}

std::uint8_t line_checksum(std::string_view text) {
  std::uint8_t x = 0;
  for (char c : text) x ^= static_cast<std::uint8_t>(c);
  return x;
}

int hex_digit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  return -1;
}

namespace {

std::vector<std::string_view> split_fields(std::string_view body) {
  std::vector<std::string_view> fields;
  std::size_t start = 0;
  for (std::size_t i = 0; i <= body.size(); ++i) {
    if (i == body.size() || body[i] == ',') {
      fields.push_back(body.substr(start, i - start));
      start = i + 1;
    }
  }
  return fields;
}

/// A field as a number: kOk, kNotNumber (text, empty, trailing junk), kNonFinite (nan, inf).
enum class NumberStatus { kOk, kNotNumber, kNonFinite };

NumberStatus parse_double(std::string_view field, double& value) {
  if (!field.empty() && field.front() == '+') field.remove_prefix(1);  // from_chars refuses '+'
  if (field.empty()) return NumberStatus::kNotNumber;
  const char* end = field.data() + field.size();
  const auto r = std::from_chars(field.data(), end, value);
  // Out of range (1e999) is a non-finite value too: the device meant something from_chars cannot hold.
  if (r.ec == std::errc::result_out_of_range && r.ptr == end) return NumberStatus::kNonFinite;
  if (r.ec != std::errc() || r.ptr != end) return NumberStatus::kNotNumber;
  return std::isfinite(value) ? NumberStatus::kOk : NumberStatus::kNonFinite;
}

bool parse_integer(std::string_view field, long long& value) {
  if (!field.empty() && field.front() == '+') field.remove_prefix(1);
  if (field.empty()) return false;
  const char* end = field.data() + field.size();
  const auto r = std::from_chars(field.data(), end, value);
  return r.ec == std::errc() && r.ptr == end;
}

std::string format_double(double v) {
  if (!std::isfinite(v)) throw std::invalid_argument("line protocol: cannot write a non-finite value");
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof(buf), v);  // shortest round-trip form
  return std::string(buf, r.ptr);
}

std::string finish_line(const std::string& body, bool checksum) {
  if (!checksum) return body;
  static const char kHex[] = "0123456789ABCDEF";
  const std::uint8_t x = line_checksum(body);
  std::string line = "$" + body + "*";
  line += kHex[x >> 4];
  line += kHex[x & 0xF];
  return line;
}

}  // namespace

ParsedLine LineDecoder::reject(LineError error, const std::string& what) {
  ++counters_.errors[static_cast<std::size_t>(error)];
  ParsedLine p;
  p.kind = ParsedLine::Kind::kError;
  p.error = error;
  p.detail = "line " + std::to_string(counters_.lines) + ": " + what;
  return p;
}

ParsedLine LineDecoder::parse_line(std::string_view line) {
  ++counters_.lines;
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  if (line.size() > kMaxLineBytes)
    return reject(LineError::kOverlong,
                  std::to_string(line.size()) + " bytes, more than " + std::to_string(kMaxLineBytes));
  if (line.empty() || line.front() == '#') return ParsedLine{};

  // Optional NMEA-style framing: "$<body>*HH".
  std::string_view body = line;
  if (body.front() == '$') body.remove_prefix(1);
  if (const std::size_t star = body.find('*'); star != std::string_view::npos) {
    const std::string_view hh = body.substr(star + 1);
    body = body.substr(0, star);
    if (hh.size() != 2 || hex_digit(hh[0]) < 0 || hex_digit(hh[1]) < 0)
      return reject(LineError::kBadChecksum, "checksum '*" + std::string(hh.substr(0, 8)) + "' is not two hex digits");
    const int given = hex_digit(hh[0]) * 16 + hex_digit(hh[1]);
    const int computed = line_checksum(body);
    if (given != computed) {
      return reject(LineError::kBadChecksum, printf_text("checksum %02X, computed %02X", given, computed));
    }
  } else if (line.front() == '$') {
    return reject(LineError::kBadChecksum, "'$' line without '*HH' checksum");
  }

  const std::vector<std::string_view> f = split_fields(body);
  const std::string_view type = f[0];
  int stream = -1;
  std::size_t min_fields = 0, max_fields = 0;
  if (type == "ODO")
    stream = 0, min_fields = 3, max_fields = 4;
  else if (type == "ATT")
    stream = 1, min_fields = 5, max_fields = 5;
  else if (type == "GNSS")
    stream = 2, min_fields = 9, max_fields = 11;
  else
    return reject(LineError::kMalformed, "unknown line type '" + std::string(type.substr(0, 16)) + "'");
  if (f.size() < min_fields || f.size() > max_fields || (stream == 2 && f.size() == 10))
    return reject(LineError::kWrongFieldCount, std::string(type) + " with " + std::to_string(f.size()) +
                                                   " fields, expected " +
                                                   (stream == 0   ? "3 or 4"
                                                    : stream == 1 ? "5"
                                                                  : "9 or 11"));

  // Every field but the integers is a real number: check them all first, naming the field.
  static const char* const kNames[3][11] = {
      {"type", "t", "pulses", "direction"},
      {"type", "t", "heading_deg", "pitch_deg", "roll_deg"},
      {"type", "t", "lat_deg", "lon_deg", "height_m", "ve", "vn", "vu", "fix", "pos_std_m", "vel_std_mps"}};
  std::vector<double> v(f.size(), 0.0);
  for (std::size_t i = 1; i < f.size(); ++i) {
    const NumberStatus s = parse_double(f[i], v[i]);
    if (s == NumberStatus::kNonFinite)
      return reject(LineError::kNonFinite, std::string(type) + " field " + kNames[stream][i] + " is not finite");
    if (s == NumberStatus::kNotNumber)
      return reject(LineError::kMalformed, std::string(type) + " field " + kNames[stream][i] + " '" +
                                               std::string(f[i].substr(0, 24)) + "' is not a number");
  }
  const double t_s = v[1];

  ParsedLine p;
  switch (stream) {
    case 0: {
      long long pulses = 0, direction = 1;
      if (!parse_integer(f[2], pulses) || pulses < 0 || pulses > std::numeric_limits<std::uint32_t>::max())
        return reject(LineError::kMalformed, "ODO field pulses '" + std::string(f[2].substr(0, 24)) +
                                                 "' is not an integer in [0, 4294967295]");
      if (f.size() == 4 && (!parse_integer(f[3], direction) || direction < -1 || direction > 1))
        return reject(LineError::kMalformed,
                      "ODO field direction '" + std::string(f[3].substr(0, 24)) + "' is not -1, 0 or 1");
      p.kind = ParsedLine::Kind::kOdometer;
      p.odometer.t_s = t_s;
      p.odometer.pulses = static_cast<std::uint32_t>(pulses);
      p.odometer.direction = static_cast<int>(direction);
      break;
    }
    case 1:
      if (v[3] < -90.0 || v[3] > 90.0) return reject(LineError::kMalformed, "ATT field pitch_deg outside [-90, 90]");
      p.kind = ParsedLine::Kind::kIns;
      p.ins.t_s = t_s;
      p.ins.attitude = Attitude{deg_to_rad(v[2]), deg_to_rad(v[3]), deg_to_rad(v[4])};
      break;
    case 2: {
      if (v[2] < -90.0 || v[2] > 90.0) return reject(LineError::kMalformed, "GNSS field lat_deg outside [-90, 90]");
      long long fix = 0;
      if (!parse_integer(f[8], fix) || fix < 0 || fix > 255)
        return reject(LineError::kMalformed,
                      "GNSS field fix '" + std::string(f[8].substr(0, 24)) + "' is not an integer in [0, 255]");
      if (f.size() == 11 && (v[9] < 0.0 || v[10] < 0.0))
        return reject(LineError::kMalformed, "GNSS accuracies must not be negative");
      p.kind = ParsedLine::Kind::kGnss;
      p.gnss.t_s = t_s;
      // Any longitude is the meridian it names: held in [-180, 180) as every position odonav holds.
      p.gnss.position = Geodetic{deg_to_rad(v[2]), deg_to_rad(normalize_lon_deg(v[3])), v[4]};
      p.gnss.vel_enu_mps = Eigen::Vector3d(v[5], v[6], v[7]);
      p.gnss.fix = static_cast<int>(fix);
      if (f.size() == 11) {
        p.gnss.pos_std_m = v[9];
        p.gnss.vel_std_mps = v[10];
      }
      break;
    }
  }
  // Per stream: each stream has its own clock edge (a GNSS line may lag the odometer by 100 ms).
  auto& last = last_t_s_[static_cast<std::size_t>(stream)];
  if (last && !(t_s > *last)) {
    return reject(LineError::kTimeBackwards, printf_text("%s t=%.9g s does not increase (previous %.9g s)",
                                                         std::string(type).c_str(), t_s, *last));
  }
  last = t_s;
  ++counters_.samples[static_cast<std::size_t>(stream)];
  return p;
}

void LineDecoder::feed(std::string_view bytes, std::vector<ParsedLine>& out) {
  for (char c : bytes) {
    if (c == '\n') {
      if (skipping_overlong_)
        skipping_overlong_ = false;  // already counted when it overflowed
      else
        out.push_back(parse_line(pending_));
      pending_.clear();
      continue;
    }
    if (skipping_overlong_) continue;
    pending_.push_back(c);
    // +1: a '\r' before the '\n' is not part of the line.
    if (pending_.size() > kMaxLineBytes + 1) {
      ++counters_.lines;
      out.push_back(reject(LineError::kOverlong, "more than " + std::to_string(kMaxLineBytes) +
                                                     " bytes without a line end (skipped to the next)"));
      pending_.clear();
      skipping_overlong_ = true;
    }
  }
}

void LineDecoder::end_of_record(std::vector<ParsedLine>& out) {
  if (!pending_.empty() && !skipping_overlong_) out.push_back(parse_line(pending_));
  pending_.clear();
  skipping_overlong_ = false;
}

std::string odometer_line(const OdometerSample& s, bool checksum) {
  return finish_line("ODO," + format_double(s.t_s) + "," + std::to_string(s.pulses) + "," + std::to_string(s.direction),
                     checksum);
}

std::string ins_line(const InsSample& s, bool checksum) {
  return finish_line("ATT," + format_double(s.t_s) + "," + format_double(recorded_degrees(s.attitude.heading_rad)) +
                         "," + format_double(recorded_degrees(s.attitude.pitch_rad)) + "," +
                         format_double(recorded_degrees(s.attitude.roll_rad)),
                     checksum);
}

std::string gnss_line(const GnssSample& s, bool checksum) {
  std::string body = "GNSS," + format_double(s.t_s) + "," + format_double(recorded_degrees(s.position.lat_rad)) + "," +
                     format_double(recorded_degrees(s.position.lon_rad)) + "," + format_double(s.position.height_m) +
                     "," + format_double(s.vel_enu_mps.x()) + "," + format_double(s.vel_enu_mps.y()) + "," +
                     format_double(s.vel_enu_mps.z()) + "," + std::to_string(s.fix);
  if (s.pos_std_m && s.vel_std_mps) body += "," + format_double(*s.pos_std_m) + "," + format_double(*s.vel_std_mps);
  return finish_line(body, checksum);
}

}  // namespace odonav::gateway
