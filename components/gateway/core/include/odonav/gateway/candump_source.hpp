#pragma once
// odonav-gateway's middleware-free core, part 8: the odometer from a CAN bus logged by can-utils'
// `candump -L` (README.md, "CAN input"). `--source candump:<file>` decodes a whole log and replays
// it like a dataset (any --speed); `--source candump:-` reads standard input as it arrives (a live
// bus: `candump -L can0 | odonav-gateway --source candump:-`).
//
// One or more odometer channels (decoders, can_decoders.hpp) each give an accumulated count of
// pulses, either read from a counter or integrated from a speed; the odometer stream is their
// mean, published at the stamps of the first channel's frames (see CanOdometer).
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "odonav/gateway/can_decoders.hpp"
#include "odonav/dataset.hpp"

namespace odonav::gateway {

/// One odometer channel: which frames, and how they become pulses.
struct CanChannelSpec {
  enum class Kind {
    kCcvs1,          ///< J1939 CCVS1 wheel-based vehicle speed (m/s) x pulses_per_m.
    kEtc1,           ///< J1939 ETC1 output shaft speed: x etc1_pulses_per_rev, or via gear ratio and sprocket radius.
    kSignalCounter,  ///< a manufacturer's pulse counter: raw value, wrapping at counter_width_bits.
    kSignalSpeed,    ///< a manufacturer's speed signal in m/s (after scale and offset) x pulses_per_m.
  };
  Kind kind = Kind::kCcvs1;
  std::optional<std::uint8_t> source_address;  ///< J1939: only frames of this sender (default: any).
  SignalSpec signal;                           ///< signal kinds: where the value is.
  unsigned counter_width_bits = 0;             ///< kSignalCounter: wrap width, 1..64 (default: the length).
};

/// "ccvs1", "etc1:sa=3", "signal:id=18FF1021,start=0,length=32,as=counter"...
std::string to_string(const CanChannelSpec& spec);

/// Parses the --can-odometer text: channels separated by ';', each one of
///   ccvs1[:sa=<0..255>]
///   etc1[:sa=<0..255>]
///   signal:id=<3 or 8 hex digits>,start=<bit>,length=<bits>,as=counter|speed
///          [,order=intel|motorola][,signed=0|1][,scale=<x>][,offset=<x>][,wrap=<bits>]
/// Throws ConfigError naming --can-odometer and what is wrong.
std::vector<CanChannelSpec> parse_can_channels(const std::string& text);

/// The conversion of the channels into pulses and the gateway's CAN flags.
struct CanOdometerConfig {
  std::vector<CanChannelSpec> channels;  ///< at least one.
  double pulses_per_m = 100.0;           ///< speed channels: pulses per metre, (0, 1e6].
  double gear_ratio = 1.0;               ///< ETC1: output shaft revolutions per sprocket (wheel) revolution, (0, 1000].
  double sprocket_radius_m = 0.3;        ///< ETC1: effective sprocket (wheel) radius, m, (0, 5].
  double etc1_pulses_per_rev = 0.0;      ///< ETC1: > 0: pulses per output shaft revolution instead of the speed.
};

/// Throws ConfigError naming the flag when a value is out of its range.
void validate(const CanOdometerConfig& config);

/// Counts of a CAN input, cumulative.
struct CanCounters {
  std::uint64_t lines = 0;         ///< lines read, including empty and comment lines.
  std::uint64_t frames = 0;        ///< well-formed frames (any identifier).
  std::uint64_t decoded = 0;       ///< frames that gave a value to at least one channel.
  std::uint64_t samples = 0;       ///< odometer samples produced.
  std::uint64_t malformed = 0;     ///< lines that are not candump -L frames (or longer than kMaxCandumpLineBytes).
  std::uint64_t unknown = 0;       ///< frames no channel reads (other traffic, remote and error frames).
  std::uint64_t out_of_order = 0;  ///< stamped before the previous frame of the log: dropped.
  std::uint64_t stale = 0;         ///< a channel's frame not after that channel's last one (a repeat): dropped.
  std::uint64_t undecodable = 0;   ///< a channel's frame without a value: too short, J1939 not available / error.
  /// Problems that need a look (Health WARN): not unknown frames, which any shared bus carries.
  std::uint64_t problems() const { return malformed + out_of_order + stale + undecodable; }
};

/// Longest accepted candump line, bytes (a CAN FD frame with 64 bytes is about 170).
inline constexpr std::size_t kMaxCandumpLineBytes = 256;

/// Frames -> odometer samples.
///
/// Each channel keeps an accumulated count: a counter channel its first raw value plus every
/// increment modulo 2^width (a wrap is not a jump); a speed channel the integral of its rate
/// (pulses/s) over time by the trapezoid rule between its frames, starting at 0. The published
/// count is floor(mean of the channels' counts) modulo 2^32: whole pulses, as an incremental
/// encoder's counter shows them and as the dataset format and the simulator write them
/// (docs/DATASET.md, odometer.csv). A speed channel's count at another channel's stamp is
/// extrapolated with its last rate. A sample is produced at each accepted frame of the first
/// channel, once every channel has a value, stamped with that frame's stamp. Direction: -1 while
/// the mean rate of the speed channels is negative (a signed speed), else +1 (counters: +1).
/// Never throws on input: every bad line is counted (CanCounters) and the first 20 problems are
/// logged (spdlog warn) naming their line number.
class CanOdometer {
 public:
  /// Throws ConfigError (validate) on a bad configuration.
  explicit CanOdometer(CanOdometerConfig config);

  /// One candump line (terminator removed), counted as the next line (1-based in messages).
  std::optional<OdometerSample> parse_line(std::string_view line);
  /// One frame, from line `line_number` (for messages).
  std::optional<OdometerSample> process(const CanFrame& frame, std::uint64_t line_number);
  /// A line longer than kMaxCandumpLineBytes (skipped): counted as the next line, malformed.
  void overlong_line();

  const CanCounters& counters() const { return counters_; }
  const CanOdometerConfig& config() const { return config_; }

 private:
  struct Channel {
    bool has_value = false;
    double last_t_s = 0.0;
    std::uint64_t last_raw = 0;  // counters
    double count = 0.0;          // accumulated pulses
    double rate = 0.0;           // speed channels: last rate, pulses/s (signed)
  };
  bool matches(const CanChannelSpec& spec, const CanFrame& frame) const;
  /// The rate (pulses/s, signed) or counter raw value of a channel's frame.
  Decoded value(const CanChannelSpec& spec, const CanFrame& frame) const;
  void problem(std::uint64_t line_number, const std::string& what);

  CanOdometerConfig config_;
  std::vector<Channel> channels_;
  CanCounters counters_;
  std::optional<double> last_frame_t_s_;
  int direction_ = 1;
  std::uint64_t logged_ = 0;
};

/// Splits a byte stream (standard input, a pipe) into candump lines for a CanOdometer.
class CandumpStream {
 public:
  explicit CandumpStream(CanOdometer& odometer) : odometer_(odometer) {}
  /// Every complete line of `bytes` (with what was buffered) is decoded; samples go to `out`.
  void feed(std::string_view bytes, std::vector<OdometerSample>& out);
  /// End of the stream: a last line without '\n' is decoded too.
  void finish(std::vector<OdometerSample>& out);

 private:
  CanOdometer& odometer_;
  std::string pending_;
  bool skipping_overlong_ = false;
};

/// Decodes a whole candump log file. Throws DatasetError naming the file when it cannot be read
/// (missing, not a regular file, larger than kMaxDatasetFileBytes, a read error); bad lines are
/// only counted.
std::vector<OdometerSample> read_candump_file(const std::string& path, CanOdometer& odometer);

/// The recorded drive of `--source candump:<file>`: the odometer decoded from the log; the INS
/// and GNSS of `companion_dir` (a dataset directory, read_dataset with `policy`, its odometer.csv
/// replaced) when not empty, else none (odometer only). Throws DatasetError naming the file.
Dataset load_candump_source(const std::string& log_path, CanOdometer& odometer, const std::string& companion_dir,
                            BadRowPolicy policy, DatasetReadReport* report = nullptr);

}  // namespace odonav::gateway
