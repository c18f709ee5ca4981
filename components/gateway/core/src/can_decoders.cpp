#include "odonav/gateway/can_decoders.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>

#include "odonav/gateway/line_protocol.hpp"

namespace odonav::gateway {

namespace {

bool parse_hex(std::string_view s, std::uint32_t& out) {
  if (s.empty() || s.size() > 8) return false;
  std::uint32_t v = 0;
  for (char c : s) {
    const int d = hex_digit(c);
    if (d < 0) return false;
    v = (v << 4) | static_cast<std::uint32_t>(d);
  }
  out = v;
  return true;
}

/// Hex byte pairs into frame.data; false on an odd count, a non-hex digit or more than max bytes.
bool parse_data(std::string_view s, std::size_t max_bytes, CanFrame& frame) {
  if (s.size() % 2 != 0 || s.size() / 2 > max_bytes) return false;
  for (std::size_t i = 0; i < s.size(); i += 2) {
    const int hi = hex_digit(s[i]), lo = hex_digit(s[i + 1]);
    if (hi < 0 || lo < 0) return false;
    frame.data[i / 2] = static_cast<std::uint8_t>(hi * 16 + lo);
  }
  frame.size = s.size() / 2;
  return true;
}

bool valid_fd_length(std::size_t n) {
  return n <= 8 || n == 12 || n == 16 || n == 20 || n == 24 || n == 32 || n == 48 || n == 64;
}

CandumpLine malformed(std::string why) {
  CandumpLine l;
  l.kind = CandumpLine::Kind::kMalformed;
  l.error = std::move(why);
  return l;
}

std::string quoted(std::string_view s) {
  std::string q;
  for (char c : s.substr(0, 40)) {
    if (c >= 0x20 && c < 0x7F)
      q += c;
    else {
      char b[8];
      std::snprintf(b, sizeof(b), "\\x%02X", static_cast<unsigned char>(c));
      q += b;
    }
  }
  if (s.size() > 40) q += "...";
  return "'" + q + "'";
}

/// The absolute bit positions of a signal, most significant first; false when one lies at or
/// beyond max_bytes * 8.
template <class F>
bool for_each_bit_msb_first(const SignalSpec& spec, std::size_t max_bytes, F&& f) {
  const long limit = static_cast<long>(max_bytes) * 8;
  if (spec.order == SignalSpec::ByteOrder::kIntel) {
    for (long i = static_cast<long>(spec.length_bits) - 1; i >= 0; --i) {
      const long pos = static_cast<long>(spec.start_bit) + i;
      if (pos >= limit) return false;
      f(static_cast<unsigned>(pos));
    }
    return true;
  }
  // Motorola (DBC @0): the start bit is the MSB; the next less significant bit is the one below
  // in the same byte, or bit 7 of the next byte after bit 0 (the "sawtooth" numbering).
  long pos = spec.start_bit;
  for (unsigned i = 0; i < spec.length_bits; ++i) {
    if (pos >= limit) return false;
    f(static_cast<unsigned>(pos));
    pos = (pos % 8 == 0) ? pos + 15 : pos - 1;
  }
  return true;
}

}  // namespace

CandumpLine parse_candump_line(std::string_view line) {
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  std::size_t b = 0;
  while (b < line.size() && (line[b] == ' ' || line[b] == '\t')) ++b;
  line.remove_prefix(b);
  if (line.empty() || line.front() == '#') return {};
  // Fields separated by single or repeated blanks: stamp, interface, frame, optional R/T.
  std::string_view fields[5];
  std::size_t n = 0;
  for (std::size_t i = 0; i < line.size();) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    if (i == line.size()) break;
    const std::size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
    if (n == 5) return malformed("more than 4 fields in " + quoted(line));
    fields[n++] = line.substr(start, i - start);
  }
  if (n < 3) return malformed("expected '(stamp) interface ID#data', got " + quoted(line));
  if (n == 4 && fields[3] != "R" && fields[3] != "T")
    return malformed("unexpected field " + quoted(fields[3]) + " after the frame");
  if (n == 5) return malformed("more than 4 fields in " + quoted(line));

  CandumpLine out;
  CanFrame& f = out.frame;
  const std::string_view stamp = fields[0];
  if (stamp.size() < 3 || stamp.front() != '(' || stamp.back() != ')')
    return malformed("stamp " + quoted(stamp) + " is not '(seconds.fraction)'");
  const std::string_view digits = stamp.substr(1, stamp.size() - 2);
  for (char c : digits)
    if (!(c >= '0' && c <= '9') && c != '.') return malformed("stamp " + quoted(stamp) + " is not a decimal number");
  const auto r = std::from_chars(digits.data(), digits.data() + digits.size(), f.t_s);
  if (r.ec != std::errc() || r.ptr != digits.data() + digits.size() || !std::isfinite(f.t_s))
    return malformed("stamp " + quoted(stamp) + " is not a decimal number");

  const std::string_view frame = fields[2];
  const std::size_t hash = frame.find('#');
  if (hash == std::string_view::npos) return malformed("frame " + quoted(frame) + " has no '#'");
  const std::string_view id = frame.substr(0, hash);
  if (id.size() != 3 && id.size() != 8)
    return malformed("identifier " + quoted(id) + " is neither 3 hex digits (11-bit) nor 8 (29-bit)");
  if (!parse_hex(id, f.id)) return malformed("identifier " + quoted(id) + " is not hexadecimal");
  f.extended = id.size() == 8;
  if (!f.extended && f.id > 0x7FF) return malformed("11-bit identifier " + quoted(id) + " above 7FF");
  if (f.extended && f.id > 0x1FFFFFFF) {
    // candump prints an error frame's identifier with CAN_ERR_FLAG (0x20000000) set.
    if ((f.id & 0xE0000000u) != 0x20000000u) return malformed("29-bit identifier " + quoted(id) + " above 1FFFFFFF");
    f.error_frame = true;
    f.id &= 0x1FFFFFFF;
  }
  std::string_view rest = frame.substr(hash + 1);
  if (!rest.empty() && rest.front() == '#') {  // CAN FD: "##<flags><data>"
    if (rest.size() < 2 || hex_digit(rest[1]) < 0)
      return malformed("CAN FD frame " + quoted(frame) + " without its flags digit");
    f.fd = true;
    if (!parse_data(rest.substr(2), kMaxCanDataBytes, f) || !valid_fd_length(f.size))
      return malformed("CAN FD data " + quoted(rest.substr(2)) + " is not 0-8, 12, 16, 20, 24, 32, 48 or 64 hex bytes");
  } else if (!rest.empty() && (rest.front() == 'R' || rest.front() == 'r')) {
    if (rest.size() > 2 || (rest.size() == 2 && hex_digit(rest[1]) < 0))
      return malformed("remote frame " + quoted(frame) + " is not 'ID#R' or 'ID#R<dlc>'");
    f.remote = true;
  } else {
    // A classic frame may carry "_<dlc>" for a DLC 9..15 with 8 bytes (candump -8): accepted.
    const std::size_t underscore = rest.find('_');
    if (underscore != std::string_view::npos) {
      if (underscore + 2 != rest.size() || hex_digit(rest.back()) < 9)
        return malformed("data " + quoted(rest) + " has a bad '_<dlc>' suffix");
      rest = rest.substr(0, underscore);
    }
    if (!parse_data(rest, 8, f)) return malformed("data " + quoted(rest) + " is not 0-8 bytes in hex pairs");
  }
  out.kind = CandumpLine::Kind::kFrame;
  return out;
}

std::string candump_line(const CanFrame& frame, const std::string& interface_name) {
  char head[64];
  std::snprintf(head, sizeof(head), "(%.6f) ", frame.t_s);
  char id[16];
  if (frame.extended)
    std::snprintf(id, sizeof(id), "%08X", frame.id | (frame.error_frame ? 0x20000000u : 0u));
  else
    std::snprintf(id, sizeof(id), "%03X", frame.id);
  std::string s = std::string(head) + interface_name + " " + id + (frame.fd ? "##0" : "#");
  if (frame.remote) return s + "R";
  char byte[4];
  for (std::size_t i = 0; i < frame.size && i < kMaxCanDataBytes; ++i) {
    std::snprintf(byte, sizeof(byte), "%02X", frame.data[i]);
    s += byte;
  }
  return s;
}

std::uint32_t j1939_pgn(std::uint32_t id) {
  const std::uint32_t pf = (id >> 16) & 0xFF;
  return pf < 240 ? (id >> 8) & 0x3FF00 : (id >> 8) & 0x3FFFF;
}

const char* to_string(DecodeStatus status) {
  switch (status) {
    case DecodeStatus::kOk: return "ok";
    case DecodeStatus::kTooShort: return "too short";
    case DecodeStatus::kNotAvailable: return "not available";
    case DecodeStatus::kError: return "error indicator";
  }
  return "unknown";
}

Decoded j1939_u16(const CanFrame& frame, std::size_t first, double resolution) {
  if (frame.size < first + 2) return {DecodeStatus::kTooShort, 0.0};
  const unsigned raw = frame.data[first] | (static_cast<unsigned>(frame.data[first + 1]) << 8);
  if (raw >= 0xFF00) return {DecodeStatus::kNotAvailable, 0.0};
  if (raw >= 0xFE00) return {DecodeStatus::kError, 0.0};
  return {DecodeStatus::kOk, raw * resolution};
}

Decoded ccvs1_wheel_speed_mps(const CanFrame& frame) {
  Decoded d = j1939_u16(frame, 1, 1.0 / 256.0);
  d.value /= 3.6;  // km/h -> m/s
  return d;
}

Decoded etc1_output_shaft_rev_per_s(const CanFrame& frame) {
  Decoded d = j1939_u16(frame, 1, 0.125);
  d.value /= 60.0;  // rpm -> rev/s
  return d;
}

std::string check_signal(const SignalSpec& spec, std::size_t max_bytes) {
  if (spec.extended ? spec.id > 0x1FFFFFFF : spec.id > 0x7FF)
    return spec.extended ? "29-bit identifier above 1FFFFFFF" : "11-bit identifier above 7FF";
  if (spec.length_bits < 1 || spec.length_bits > 64) return "length not in 1..64 bits";
  if (spec.start_bit >= max_bytes * 8) return "start bit beyond the frame";
  if (!std::isfinite(spec.scale) || spec.scale == 0.0) return "scale not finite and non-zero";
  if (!std::isfinite(spec.offset)) return "offset not finite";
  if (!for_each_bit_msb_first(spec, max_bytes, [](unsigned) {}))
    return "the signal runs beyond " + std::to_string(max_bytes) + " bytes";
  return "";
}

std::optional<std::uint64_t> extract_raw(const CanFrame& frame, const SignalSpec& spec) {
  std::uint64_t raw = 0;
  const bool inside = for_each_bit_msb_first(
      spec, frame.size, [&](unsigned pos) { raw = (raw << 1) | ((frame.data[pos / 8] >> (pos % 8)) & 1u); });
  if (!inside) return std::nullopt;
  return raw;
}

std::int64_t signed_raw(std::uint64_t raw, const SignalSpec& spec) {
  if (!spec.is_signed || spec.length_bits == 0 || spec.length_bits >= 64) return static_cast<std::int64_t>(raw);
  const std::uint64_t sign = std::uint64_t{1} << (spec.length_bits - 1);
  if (raw & sign) return static_cast<std::int64_t>(raw) - static_cast<std::int64_t>(sign << 1);
  return static_cast<std::int64_t>(raw);
}

Decoded decode_signal(const CanFrame& frame, const SignalSpec& spec) {
  const auto raw = extract_raw(frame, spec);
  if (!raw) return {DecodeStatus::kTooShort, 0.0};
  const double v = spec.is_signed ? static_cast<double>(signed_raw(*raw, spec)) : static_cast<double>(*raw);
  return {DecodeStatus::kOk, v * spec.scale + spec.offset};
}

void insert_raw(CanFrame& frame, const SignalSpec& spec, std::uint64_t raw) {
  int shift = static_cast<int>(spec.length_bits) - 1;
  for_each_bit_msb_first(spec, frame.size, [&](unsigned pos) {
    const std::uint8_t mask = static_cast<std::uint8_t>(1u << (pos % 8));
    if ((raw >> shift) & 1u)
      frame.data[pos / 8] |= mask;
    else
      frame.data[pos / 8] &= static_cast<std::uint8_t>(~mask);
    --shift;
  });
}

std::uint64_t counter_increment(std::uint64_t previous, std::uint64_t current, unsigned width_bits) {
  const std::uint64_t mask = width_bits >= 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << width_bits) - 1;
  return (current - previous) & mask;
}

}  // namespace odonav::gateway
