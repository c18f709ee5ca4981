#pragma once
// odonav-gateway's middleware-free core, part 4: live sources of protocol lines (line_protocol.hpp).
//
//   udp:<port> | udp:<bind IPv4 address>:<port>   datagrams of whole lines; binds 127.0.0.1 by
//                                                  default and refuses a non-loopback address
//                                                  unless explicitly allowed (--allow-non-loopback)
//   serial:<device>[:<baud>]                       a tty in raw mode (termios), 115200 baud by default
//
// The loop (run_live_input) reads with a short timeout so a stop request and periodic work (health)
// stay responsive, decodes lines and hands each accepted sample to a SampleSink (the DDS writers in
// the gateway; a vector in tests). A device that fails (unplugged, pty closed) is counted, reported
// and reopened with back-off; it never ends the loop.
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "odonav/gateway/line_protocol.hpp"
#include "odonav/dataset.hpp"

namespace odonav::gateway {

/// What a live `--source` names.
struct LiveSourceSpec {
  enum class Kind { kUdp, kSerial };
  Kind kind = Kind::kUdp;
  std::string bind_address = "127.0.0.1";  ///< kUdp: IPv4 address to bind.
  std::uint16_t port = 0;                  ///< kUdp: 1..65535.
  std::string device;                      ///< kSerial: path of the tty, e.g. /dev/ttyUSB0.
  int baud = 115200;                       ///< kSerial: one of the standard rates 1200..921600.
};

/// True for "udp:..." and "serial:..." (the live sources), false otherwise.
bool is_live_source(const std::string& text);

/// Parses "udp:<port>", "udp:<IPv4>:<port>", "serial:<device>" or "serial:<device>:<baud>".
/// Throws ConfigError naming --source and the accepted forms on a bad port, address or baud rate,
/// and naming --allow-non-loopback when the bind address is not in 127.0.0.0/8 and not allowed.
LiveSourceSpec parse_live_source(const std::string& text, bool allow_non_loopback);

/// "udp:127.0.0.1:5600", "serial:/dev/ttyUSB0 at 115200 baud".
std::string to_string(const LiveSourceSpec& spec);

/// A byte source: a UDP socket (one read = one datagram) or a serial device (a read = what arrived).
class ByteSource {
 public:
  virtual ~ByteSource() = default;
  /// Waits at most timeout_ms for data; returns the bytes read (empty on timeout).
  /// Throws std::runtime_error naming the source and the system error when the device fails.
  virtual std::string read(int timeout_ms) = 0;
  /// True when each read() is a whole record (a datagram): its end ends its last line.
  virtual bool record_oriented() const = 0;
};

/// Opens the source: binds the UDP socket, or opens and configures the tty (raw, 8N1, no flow
/// control, the baud rate). Throws std::runtime_error naming the address or device and the system
/// error (e.g. "serial:/dev/ttyUSB0: open: No such file or directory").
std::unique_ptr<ByteSource> open_live_source(const LiveSourceSpec& spec);

/// Where accepted samples go.
class SampleSink {
 public:
  virtual ~SampleSink() = default;
  virtual void odometer(const OdometerSample& s) = 0;
  virtual void ins(const InsSample& s) = 0;
  virtual void gnss(const GnssSample& s) = 0;
};

/// Counters of a live run, beyond the line counters.
struct LiveInputStats {
  std::uint64_t source_failures = 0;  ///< read or open errors (each followed by a reopen attempt).
  std::uint64_t reopens = 0;          ///< successful reopenings after a failure.
  std::string last_failure;           ///< the last failure's message, empty if none.
};

/// Reads `source` until stop() is true: decodes lines with `decoder`, gives every accepted sample to
/// `sink` in arrival order, logs the first 20 rejected lines (spdlog warn; all are counted in the
/// decoder). periodic() is called at least every 100 ms. On a source failure the source is reopened
/// with `reopen` after a back-off of 0.2 s doubling to 5 s. Exceptions of sink, periodic and reopen
/// propagate.
void run_live_input(std::unique_ptr<ByteSource> source, LineDecoder& decoder, SampleSink& sink,
                    const std::function<bool()>& stop, const std::function<void()>& periodic,
                    const std::function<std::unique_ptr<ByteSource>()>& reopen, LiveInputStats& stats);

}  // namespace odonav::gateway
