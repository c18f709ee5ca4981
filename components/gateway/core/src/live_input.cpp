#include "odonav/gateway/live_input.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <stdexcept>
#include <thread>
#include <vector>

#include "odonav/config.hpp"

namespace odonav::gateway {

namespace {

constexpr const char* kForms = "udp:<port>, udp:<IPv4 address>:<port>, serial:<device> or serial:<device>:<baud>";

bool parse_uint(const std::string& s, unsigned long max, unsigned long& out) {
  if (s.empty() || s.size() > 10 || s.find_first_not_of("0123456789") != std::string::npos) return false;
  out = std::stoul(s);
  return out <= max;
}

speed_t baud_constant(int baud) {
  switch (baud) {
    case 1200: return B1200;
    case 2400: return B2400;
    case 4800: return B4800;
    case 9600: return B9600;
    case 19200: return B19200;
    case 38400: return B38400;
    case 57600: return B57600;
    case 115200: return B115200;
    case 230400: return B230400;
    case 460800: return B460800;
    case 921600: return B921600;
    default: return 0;
  }
}

std::string system_error(const std::string& where, const char* call) {
  return where + ": " + call + ": " + std::strerror(errno);
}

/// Closes a file descriptor on scope exit.
class FileDescriptor {
 public:
  explicit FileDescriptor(int fd) : fd_(fd) {}
  ~FileDescriptor() {
    if (fd_ >= 0) ::close(fd_);
  }
  FileDescriptor(const FileDescriptor&) = delete;
  FileDescriptor& operator=(const FileDescriptor&) = delete;
  int get() const { return fd_; }

 private:
  int fd_;
};

/// Waits for input on fd; true when readable. Throws on a hang-up or error of the descriptor.
bool wait_readable(int fd, int timeout_ms, const std::string& where) {
  pollfd p{fd, POLLIN, 0};
  const int r = ::poll(&p, 1, timeout_ms);
  if (r < 0) {
    if (errno == EINTR) return false;  // a signal: the caller checks its stop request
    throw std::runtime_error(system_error(where, "poll"));
  }
  if (r == 0) return false;
  if (p.revents & POLLIN) return true;
  if (p.revents & (POLLHUP | POLLERR | POLLNVAL)) throw std::runtime_error(where + ": device hung up or failed");
  return false;
}

class UdpSource : public ByteSource {
 public:
  explicit UdpSource(const LiveSourceSpec& spec) : where_(to_string(spec)), fd_(::socket(AF_INET, SOCK_DGRAM, 0)) {
    if (fd_.get() < 0) throw std::runtime_error(system_error(where_, "socket"));
    // Why a larger buffer: 300 datagrams/s from the devices must survive the gateway being
    // descheduled for a while. The kernel caps it at net.core.rmem_max; less is no error.
    const int buffer_bytes = 4 << 20;
    ::setsockopt(fd_.get(), SOL_SOCKET, SO_RCVBUF, &buffer_bytes, sizeof(buffer_bytes));
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(spec.port);
    if (::inet_pton(AF_INET, spec.bind_address.c_str(), &a.sin_addr) != 1)
      throw std::runtime_error(where_ + ": not an IPv4 address");
    if (::bind(fd_.get(), reinterpret_cast<const sockaddr*>(&a), sizeof(a)) != 0)
      throw std::runtime_error(system_error(where_, "bind"));
  }
  std::string read(int timeout_ms) override {
    if (!wait_readable(fd_.get(), timeout_ms, where_)) return {};
    char buf[65536];
    const ssize_t n = ::recv(fd_.get(), buf, sizeof(buf), 0);
    if (n < 0) {
      if (errno == EINTR || errno == EAGAIN) return {};
      throw std::runtime_error(system_error(where_, "recv"));
    }
    return std::string(buf, static_cast<std::size_t>(n));
  }
  bool record_oriented() const override { return true; }

 private:
  std::string where_;
  FileDescriptor fd_;
};

class SerialSource : public ByteSource {
 public:
  explicit SerialSource(const LiveSourceSpec& spec)
      : where_(to_string(spec)), fd_(::open(spec.device.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC)) {
    if (fd_.get() < 0) throw std::runtime_error(system_error(where_, "open"));
    termios tio{};
    if (::tcgetattr(fd_.get(), &tio) != 0) throw std::runtime_error(system_error(where_, "tcgetattr (not a tty?)"));
    // Raw: no echo, no line editing, no CR/LF translation, 8 data bits, no parity, no flow control.
    ::cfmakeraw(&tio);
    tio.c_cflag |= CLOCAL | CREAD;
    tio.c_cflag &= ~static_cast<tcflag_t>(CSTOPB | CRTSCTS);
    tio.c_iflag &= ~static_cast<tcflag_t>(IXON | IXOFF | IXANY);
    tio.c_cc[VMIN] = 0;
    tio.c_cc[VTIME] = 0;
    const speed_t speed = baud_constant(spec.baud);
    if (::cfsetispeed(&tio, speed) != 0 || ::cfsetospeed(&tio, speed) != 0)
      throw std::runtime_error(system_error(where_, "cfsetspeed"));
    if (::tcsetattr(fd_.get(), TCSANOW, &tio) != 0) throw std::runtime_error(system_error(where_, "tcsetattr"));
    ::tcflush(fd_.get(), TCIFLUSH);  // bytes from before we listened are half lines at best
  }
  std::string read(int timeout_ms) override {
    if (!wait_readable(fd_.get(), timeout_ms, where_)) return {};
    char buf[4096];
    const ssize_t n = ::read(fd_.get(), buf, sizeof(buf));
    if (n < 0) {
      if (errno == EINTR || errno == EAGAIN) return {};
      throw std::runtime_error(system_error(where_, "read"));
    }
    if (n == 0) throw std::runtime_error(where_ + ": end of file (device closed)");
    return std::string(buf, static_cast<std::size_t>(n));
  }
  bool record_oriented() const override { return false; }

 private:
  std::string where_;
  FileDescriptor fd_;
};

}  // namespace

bool is_live_source(const std::string& text) { return text.rfind("udp:", 0) == 0 || text.rfind("serial:", 0) == 0; }

LiveSourceSpec parse_live_source(const std::string& text, bool allow_non_loopback) {
  LiveSourceSpec spec;
  auto bad = [&](const std::string& why) {
    return ConfigError("--source '" + text + "': " + why + " (accepted: " + kForms + ")");
  };
  if (text.rfind("udp:", 0) == 0) {
    spec.kind = LiveSourceSpec::Kind::kUdp;
    const std::string rest = text.substr(4);
    const std::size_t colon = rest.rfind(':');
    const std::string port = colon == std::string::npos ? rest : rest.substr(colon + 1);
    if (colon != std::string::npos) spec.bind_address = rest.substr(0, colon);
    unsigned long p = 0;
    if (!parse_uint(port, 65535, p) || p == 0) throw bad("port '" + port + "' is not in 1..65535");
    spec.port = static_cast<std::uint16_t>(p);
    in_addr a{};
    if (::inet_pton(AF_INET, spec.bind_address.c_str(), &a) != 1)
      throw bad("bind address '" + spec.bind_address + "' is not an IPv4 address");
    // Why refuse: the gateway trusts what it receives; listening on a vehicle network must be a decision.
    const bool loopback = (ntohl(a.s_addr) >> 24) == 127;
    if (!loopback && !allow_non_loopback)
      throw ConfigError("--source '" + text + "': bind address " + spec.bind_address +
                        " is not a loopback address; give --allow-non-loopback to listen on it");
    return spec;
  }
  if (text.rfind("serial:", 0) == 0) {
    spec.kind = LiveSourceSpec::Kind::kSerial;
    std::string rest = text.substr(7);
    const std::size_t colon = rest.rfind(':');
    if (colon != std::string::npos) {
      unsigned long b = 0;
      const std::string baud = rest.substr(colon + 1);
      if (!parse_uint(baud, 4000000, b) || baud_constant(static_cast<int>(b)) == 0)
        throw bad("baud rate '" + baud +
                  "' is not one of 1200 2400 4800 9600 19200 38400 57600 115200 230400 460800 921600");
      spec.baud = static_cast<int>(b);
      rest = rest.substr(0, colon);
    }
    if (rest.empty()) throw bad("no device");
    spec.device = rest;
    return spec;
  }
  throw bad("not a live source");
}

std::string to_string(const LiveSourceSpec& spec) {
  if (spec.kind == LiveSourceSpec::Kind::kUdp) return "udp:" + spec.bind_address + ":" + std::to_string(spec.port);
  return "serial:" + spec.device + " at " + std::to_string(spec.baud) + " baud";
}

std::unique_ptr<ByteSource> open_live_source(const LiveSourceSpec& spec) {
  if (spec.kind == LiveSourceSpec::Kind::kUdp) return std::make_unique<UdpSource>(spec);
  return std::make_unique<SerialSource>(spec);
}

void run_live_input(std::unique_ptr<ByteSource> source, LineDecoder& decoder, SampleSink& sink,
                    const std::function<bool()>& stop, const std::function<void()>& periodic,
                    const std::function<std::unique_ptr<ByteSource>()>& reopen, LiveInputStats& stats) {
  using Clock = std::chrono::steady_clock;
  std::vector<ParsedLine> lines;
  std::size_t logged = 0;
  double backoff_s = 0.2;
  Clock::time_point retry_at{};
  while (!stop()) {
    periodic();
    if (!source) {
      if (Clock::now() < retry_at) {
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
        continue;
      }
      try {
        source = reopen();
        ++stats.reopens;
        backoff_s = 0.2;
        spdlog::info("live source reopened");
      } catch (const std::exception& e) {
        ++stats.source_failures;
        stats.last_failure = e.what();
        backoff_s = std::min(backoff_s * 2.0, 5.0);
        retry_at = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(backoff_s));
      }
      continue;
    }
    std::string bytes;
    try {
      bytes = source->read(100);
    } catch (const std::exception& e) {
      ++stats.source_failures;
      stats.last_failure = e.what();
      spdlog::warn("{}; reopening in {} s", e.what(), backoff_s);
      source.reset();
      retry_at = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(backoff_s));
      continue;
    }
    if (bytes.empty()) continue;
    lines.clear();
    decoder.feed(bytes, lines);
    if (source->record_oriented()) decoder.end_of_record(lines);
    for (const ParsedLine& p : lines) {
      switch (p.kind) {
        case ParsedLine::Kind::kOdometer: sink.odometer(p.odometer); break;
        case ParsedLine::Kind::kIns: sink.ins(p.ins); break;
        case ParsedLine::Kind::kGnss: sink.gnss(p.gnss); break;
        case ParsedLine::Kind::kIgnored: break;
        case ParsedLine::Kind::kError:
          if (++logged <= 20) spdlog::warn("rejected {}: {}", to_string(p.error), p.detail);
          if (logged == 20) spdlog::warn("further rejected lines are only counted (health)");
          break;
      }
    }
  }
}

}  // namespace odonav::gateway
