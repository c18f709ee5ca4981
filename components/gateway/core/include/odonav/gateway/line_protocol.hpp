#pragma once
// odonav-gateway's middleware-free core, part 3: the line protocol of live sensors (README.md).
//
// One sample per text line, fields separated by ',', terminated by '\n' (a '\r' before it is
// ignored), at most kMaxLineBytes bytes:
//   ODO,<t>,<pulses>[,<direction>]
//   ATT,<t>,<heading_deg>,<pitch_deg>,<roll_deg>
//   GNSS,<t>,<lat_deg>,<lon_deg>,<height_m>,<ve>,<vn>,<vu>,<fix>[,<pos_std_m>,<vel_std_mps>]
// optionally wrapped like NMEA: a leading '$' and a trailing '*HH', HH the XOR of every character
// between the '$' (or the line start) and the '*', two hexadecimal digits. Units and conventions
// are those of docs/DATASET.md (t in seconds on the one time base of the vehicle, angles in degrees).
// Empty lines and lines starting with '#' are ignored.
//
// Why a parser that never throws: a live device sends noise (a cable plugged in mid-line, a wrong
// baud rate, a reset). Each bad line is classified, counted and dropped; the next good line flows.
#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "odonav/dataset.hpp"

namespace odonav::gateway {

/// Longest accepted line, bytes, without its terminator. A GNSS line with 17 significant digits
/// per field is about 200 bytes.
inline constexpr std::size_t kMaxLineBytes = 256;

/// Why a line was rejected.
enum class LineError {
  kMalformed = 0,        ///< unknown type, a field that is not a number, or a value out of its range.
  kBadChecksum = 1,      ///< '*HH' present but not two hex digits, or not the XOR of the line.
  kTimeBackwards = 2,    ///< t not greater than the previous accepted t of the same stream.
  kOverlong = 3,         ///< more than kMaxLineBytes before the terminator (the line is skipped).
  kWrongFieldCount = 4,  ///< a known type with the wrong number of fields.
  kNonFinite = 5,        ///< a NaN or infinite number.
};
inline constexpr std::size_t kLineErrorCount = 6;

/// "malformed", "bad_checksum", "time_backwards", "overlong", "wrong_field_count", "non_finite".
const char* to_string(LineError error);

/// The result of one line.
struct ParsedLine {
  enum class Kind { kOdometer, kIns, kGnss, kIgnored, kError };
  Kind kind = Kind::kIgnored;
  OdometerSample odometer;  ///< kOdometer: t_s, pulses, direction.
  InsSample ins;            ///< kIns: attitude in radians (deg_to_rad of the line's degrees), no velocity.
  GnssSample gnss;          ///< kGnss: position in radians, ENU velocity, fix, accuracies when given.
  LineError error = LineError::kMalformed;  ///< kError: the kind of error.
  std::string detail;  ///< kError: "line N: <what is wrong>" (N counts lines of this decoder from 1).
};

/// Counts of a LineDecoder, cumulative.
struct LineCounters {
  std::uint64_t lines = 0;                              ///< lines seen, including ignored and rejected ones.
  std::array<std::uint64_t, 3> samples{};               ///< accepted: odometer, INS, GNSS.
  std::array<std::uint64_t, kLineErrorCount> errors{};  ///< rejected, indexed by LineError.
  std::uint64_t total_errors() const;
};

/// Turns a byte stream (serial) or datagrams (UDP) into samples. Never throws on input.
class LineDecoder {
 public:
  /// Parses one complete line, terminator removed (a trailing '\r' is tolerated). Updates the
  /// counters and, for accepted samples, the stream's last time.
  ParsedLine parse_line(std::string_view line);

  /// Appends bytes of a stream; every complete line is parsed and appended to `out`. A line that
  /// grows beyond kMaxLineBytes gives one kOverlong error and is skipped up to its '\n'.
  void feed(std::string_view bytes, std::vector<ParsedLine>& out);

  /// The end of a datagram is the end of its last line even without '\n' (UDP: one datagram
  /// holds whole lines). Parses what is buffered, if anything, into `out`.
  void end_of_record(std::vector<ParsedLine>& out);

  const LineCounters& counters() const { return counters_; }

 private:
  ParsedLine reject(LineError error, const std::string& what);

  LineCounters counters_;
  std::array<std::optional<double>, 3> last_t_s_;  // per stream: odometer, INS, GNSS
  std::string pending_;                            // bytes of the line being received
  bool skipping_overlong_ = false;                 // discarding up to the next '\n'
};

/// XOR of the bytes of `text`: the NMEA checksum of the characters between '$' and '*'.
std::uint8_t line_checksum(std::string_view text);

/// The value of a hexadecimal digit (0-9, A-F, a-f), -1 for any other character (NMEA checksums
/// here, CAN identifiers and payloads in can_decoders.cpp).
int hex_digit(char c);

// Writers of the protocol (simulated devices, tests). Numbers are written in shortest
// round-trip form, angles as the degrees the dataset files hold (recorded_degrees), so parsing
// the line gives back exactly what read_dataset gives for the same sample. With `checksum`, the
// line is "$<body>*HH". No terminator is appended. Throws std::invalid_argument on a non-finite value.

/// "ODO,<t>,<pulses>,<direction>".
std::string odometer_line(const OdometerSample& s, bool checksum);
/// "ATT,<t>,<heading_deg>,<pitch_deg>,<roll_deg>" (the INS velocity is not carried).
std::string ins_line(const InsSample& s, bool checksum);
/// "GNSS,<t>,<lat>,<lon>,<h>,<ve>,<vn>,<vu>,<fix>" plus ",<pos_std_m>,<vel_std_mps>" when both are known.
std::string gnss_line(const GnssSample& s, bool checksum);

}  // namespace odonav::gateway
