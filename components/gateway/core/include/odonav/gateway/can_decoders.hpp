#pragma once
// odonav-gateway's middleware-free core, part 7: CAN frames and the decoders of odometer signals
// carried on them (README.md, "CAN input"). Plain functions over plain structs, no state: the
// stateful part (counters, unwrapping, integration, several channels) is in candump_source.hpp.
//
//   - the text form of can-utils' `candump -L`: "(1700000000.123456) can0 18FEF100#0011223344556677";
//   - J1939: the PGN and source address of a 29-bit identifier, CCVS1 wheel-based vehicle speed
//     (PGN 65265, SPN 84), ETC1 transmission output shaft speed (PGN 61442, SPN 191);
//   - a signal of a manufacturer's frame as a DBC describes it (start bit, length, byte order,
//     signedness, scale, offset).
#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace odonav::gateway {

/// Largest payload: 8 bytes for classic CAN, 64 for CAN FD.
inline constexpr std::size_t kMaxCanDataBytes = 64;

/// One CAN frame as candump logs it.
struct CanFrame {
  double t_s = 0.0;          ///< the log's stamp, s (candump: since 1970, microsecond resolution).
  std::uint32_t id = 0;      ///< 11-bit (classic) or 29-bit (extended) identifier, without flags.
  bool extended = false;     ///< 29-bit identifier (8 hex digits in the log), else 11-bit (3 digits).
  bool fd = false;           ///< CAN FD frame ("ID##<flags><data>").
  bool remote = false;       ///< remote transmission request ("ID#R"): no data.
  bool error_frame = false;  ///< an error frame (CAN_ERR_FLAG set in the 8-digit identifier).
  std::size_t size = 0;      ///< data bytes, 0..8 classic, 0..64 FD.
  std::array<std::uint8_t, kMaxCanDataBytes> data{};
};

/// The result of one candump line.
struct CandumpLine {
  enum class Kind { kFrame, kIgnored, kMalformed };
  Kind kind = Kind::kIgnored;  ///< kIgnored: an empty line or a '#' comment.
  CanFrame frame;              ///< kFrame.
  std::string error;           ///< kMalformed: what is wrong (without the line number).
};

/// Parses one line of `candump -L` (terminator removed; a trailing '\r' is tolerated):
///   (<seconds>.<fraction>) <interface> <ID>#<data>            classic data frame, 0-8 bytes
///   (<seconds>.<fraction>) <interface> <ID>#R[<dlc>]          remote frame
///   (<seconds>.<fraction>) <interface> <ID>##<flags><data>    CAN FD, flags one hex digit, 0-64 bytes
/// ID: 3 hex digits (11-bit, at most 7FF) or 8 (29-bit; 2xxxxxxx with CAN_ERR_FLAG is an error
/// frame); data: pairs of hex digits, CAN FD lengths only (0-8, 12, 16, 20, 24, 32, 48, 64). An
/// optional trailing " R" or " T" (candump -x: received / transmitted) is accepted. Never throws.
CandumpLine parse_candump_line(std::string_view line);

/// The candump -L text of a frame (the inverse of parse_candump_line; stamp with 6 decimals).
std::string candump_line(const CanFrame& frame, const std::string& interface_name = "can0");

// ---- J1939 ----------------------------------------------------------------------------------

/// The parameter group number of a 29-bit identifier: bits 8-25 (EDP, DP, PF, PS). When PF < 240
/// (PDU1) PS is a destination address, not part of the PGN: PGN = (id >> 8) & 0x3FF00.
std::uint32_t j1939_pgn(std::uint32_t id);
/// The source address: the low 8 bits.
inline std::uint8_t j1939_source_address(std::uint32_t id) { return static_cast<std::uint8_t>(id & 0xFF); }

inline constexpr std::uint32_t kPgnCcvs1 = 65265;  ///< 0xFEF1, cruise control / vehicle speed 1.
inline constexpr std::uint32_t kPgnEtc1 = 61442;   ///< 0xF002, electronic transmission controller 1.

/// Why a decoder gave no value.
enum class DecodeStatus { kOk, kTooShort, kNotAvailable, kError };
const char* to_string(DecodeStatus status);

/// A decoded physical value.
struct Decoded {
  DecodeStatus status = DecodeStatus::kOk;
  double value = 0.0;
};

/// A J1939 16-bit parameter at bytes [first, first+1] (0-based), little-endian: raw * resolution.
/// Raw 0xFE00-0xFEFF: kError (the sender's error indicator); 0xFF00-0xFFFF: kNotAvailable; a
/// payload shorter than first + 2: kTooShort.
Decoded j1939_u16(const CanFrame& frame, std::size_t first, double resolution);

/// CCVS1 SPN 84, wheel-based vehicle speed: bytes 2-3 (J1939 numbering; 0-based 1-2), 1/256 km/h
/// per bit, 0..250.996 km/h. Returned in m/s.
Decoded ccvs1_wheel_speed_mps(const CanFrame& frame);

/// ETC1 SPN 191, transmission output shaft speed: bytes 2-3 (0-based 1-2), 0.125 rpm per bit,
/// 0..8031.875 rpm. Returned in revolutions per second.
Decoded etc1_output_shaft_rev_per_s(const CanFrame& frame);

// ---- DBC signals ----------------------------------------------------------------------------

/// A signal as a DBC line describes it: "SG_ name : start|length@order sign (scale,offset)".
struct SignalSpec {
  enum class ByteOrder { kIntel, kMotorola };  ///< DBC @1 (little-endian) / @0 (big-endian).
  std::uint32_t id = 0;                        ///< the frame's identifier.
  bool extended = false;                       ///< a 29-bit identifier.
  unsigned start_bit = 0;    ///< DBC start bit: Intel the LSB, Motorola the MSB (bit b = byte b/8, bit b%8).
  unsigned length_bits = 1;  ///< 1..64.
  ByteOrder order = ByteOrder::kIntel;
  bool is_signed = false;  ///< two's complement.
  double scale = 1.0;      ///< physical = raw * scale + offset.
  double offset = 0.0;
};

/// Checks a spec against a frame size of `max_bytes` (8 classic, 64 FD): "" when usable, else why.
std::string check_signal(const SignalSpec& spec, std::size_t max_bytes = kMaxCanDataBytes);

/// The raw bits of the signal (unsigned, right-aligned); nullopt when a bit lies beyond the frame's
/// payload. The spec must pass check_signal.
std::optional<std::uint64_t> extract_raw(const CanFrame& frame, const SignalSpec& spec);

/// The raw value with its sign: two's complement of length_bits when is_signed.
std::int64_t signed_raw(std::uint64_t raw, const SignalSpec& spec);

/// raw (sign applied) * scale + offset; kTooShort when the payload does not hold the signal.
Decoded decode_signal(const CanFrame& frame, const SignalSpec& spec);

/// Puts `raw` (the low length_bits bits) into the frame's data at the signal's place (tests,
/// simulated buses). The frame's size must already cover the signal.
void insert_raw(CanFrame& frame, const SignalSpec& spec, std::uint64_t raw);

/// The increment of a counter of width_bits (1..64) from `previous` to `current`, modulo 2^width:
/// a counter that wrapped from its maximum to 0 moved forward, not back.
std::uint64_t counter_increment(std::uint64_t previous, std::uint64_t current, unsigned width_bits);

}  // namespace odonav::gateway
