#pragma once
// Helpers of the live-source tests: gpsfake on a loopback port, a socat pty pair, free ports, a
// test directory.
#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "../nodes/node_test_support.hpp"

namespace odonav::test {

inline std::filesystem::path fresh_live_dir(const std::string& name) {
  const std::filesystem::path dir = std::filesystem::path(ODONAV_BINARY_DIR) / "test-out" / "live" / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

/// A free port on 127.0.0.1 of the given socket type (bound to port 0, then released).
inline int free_loopback_port(int type) {
  const int s = ::socket(AF_INET, type, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ::bind(s, reinterpret_cast<sockaddr*>(&a), sizeof(a));
  socklen_t len = sizeof(a);
  ::getsockname(s, reinterpret_cast<sockaddr*>(&a), &len);
  ::close(s);
  return ntohs(a.sin_port);
}

/// A UDP socket sending datagrams to 127.0.0.1:port; closed with the object.
class LoopbackUdpSender {
 public:
  explicit LoopbackUdpSender(int port) : fd_(::socket(AF_INET, SOCK_DGRAM, 0)) {
    to_.sin_family = AF_INET;
    to_.sin_port = htons(static_cast<uint16_t>(port));
    to_.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  }
  ~LoopbackUdpSender() {
    if (fd_ >= 0) ::close(fd_);
  }
  LoopbackUdpSender(const LoopbackUdpSender&) = delete;
  LoopbackUdpSender& operator=(const LoopbackUdpSender&) = delete;

  bool is_open() const { return fd_ >= 0; }
  /// True when the whole datagram went out.
  bool send(const std::string& datagram) const {
    return ::sendto(fd_, datagram.data(), datagram.size(), 0, reinterpret_cast<const sockaddr*>(&to_), sizeof(to_)) ==
           static_cast<ssize_t>(datagram.size());
  }

 private:
  int fd_;
  sockaddr_in to_{};
};

/// True once something accepts TCP connections on 127.0.0.1:port (bounded wait).
inline bool wait_tcp_listening(int port, std::chrono::milliseconds timeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < end) {
    const int s = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    const bool ok = ::connect(s, reinterpret_cast<sockaddr*>(&a), sizeof(a)) == 0;
    ::close(s);
    if (ok) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return false;
}

inline constexpr const char* kGpsfake = "/usr/bin/gpsfake";

/// The NMEA checksum frame "$body*HH".
inline std::string nmea_framed(const std::string& body) {
  unsigned x = 0;
  for (char c : body) x ^= static_cast<unsigned char>(c);
  char hh[4];
  std::snprintf(hh, sizeof(hh), "%02X", x & 0xFF);
  return "$" + body + "*" + hh;
}

/// Copies `log` to `out` between a lead-in and a trailer of `$GPTXT` sentences (text messages:
/// no fix, no time). Why: gpsfake starts feeding its pty at once, and gpsd drops what arrived
/// before its first client watched; the lead-in gives the gateway time to connect (at -c 0.01 s,
/// 400 sentences are 4 s or more), the trailer time to read the last fix before gpsfake exits.
inline void write_gpsfake_input(const std::filesystem::path& log, const std::filesystem::path& out) {
  std::ifstream in(log, std::ios::binary);
  std::ofstream o(out, std::ios::binary | std::ios::trunc);
  const std::string txt = nmea_framed("GPTXT,01,01,02,odonav test lead-in") + "\r\n";
  for (int i = 0; i < 400; ++i) o << txt;
  o << in.rdbuf();
  for (int i = 0; i < 150; ++i) o << txt;
}

/// gpsfake in a process group of its own: the destructor ends the whole group (gpsfake and the gpsd
/// it started), SIGTERM first, then SIGKILL, so no daemon outlives a failing test.
class GpsfakeProcess {
 public:
  explicit GpsfakeProcess(const std::vector<std::string>& args) : process_(kGpsfake, args, {}, {}, true) {}
  ~GpsfakeProcess() {
    if (!process_.started()) return;
    const pid_t group = process_.pid();
    ::kill(-group, SIGTERM);
    if (!process_.wait_exit(std::chrono::seconds(5))) ::kill(-group, SIGKILL);
    process_.wait_exit(std::chrono::seconds(5));
    ::kill(-group, SIGKILL);  // anything of the group still alive (the daemon)
  }
  GpsfakeProcess(const GpsfakeProcess&) = delete;
  GpsfakeProcess& operator=(const GpsfakeProcess&) = delete;
  bool started() const { return process_.started(); }
  /// Waits for gpsfake's exit (it ends after the log with -1); true if it exited.
  bool wait_exit(std::chrono::milliseconds timeout) { return process_.wait_exit(timeout); }
  int exit_code() const { return process_.exit_code(); }

 private:
  ChildProcess process_;
};

/// A pseudo-terminal pair made by socat, as a serial device and its cable: the gateway opens
/// gateway_end() as its serial source, the test writes what the device would send with write().
/// The device end stays open for the pair's life: closing it makes socat hang up the other end.
class PtyPair {
 public:
  /// socat: its path; dir: where the two links (gateway-tty, device-tty) are made.
  PtyPair(const std::string& socat, const std::filesystem::path& dir)
      : gateway_end_((dir / "gateway-tty").string()),
        device_end_((dir / "device-tty").string()),
        socat_(socat, {"-d", "pty,raw,echo=0,link=" + gateway_end_, "pty,raw,echo=0,link=" + device_end_}) {
    if (!socat_.started()) {
      error_ = "cannot start " + socat;
      return;
    }
    const auto both = [&] { return std::filesystem::exists(gateway_end_) && std::filesystem::exists(device_end_); };
    for (int i = 0; i < 250 && !both(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(20));
    if (!both()) {
      error_ = "socat made no pty pair in 5 s";
      return;
    }
    fd_ = ::open(device_end_.c_str(), O_WRONLY | O_NOCTTY);
    if (fd_ < 0) error_ = "cannot open " + device_end_ + " for writing";
  }
  ~PtyPair() {
    if (fd_ >= 0) ::close(fd_);
  }
  PtyPair(const PtyPair&) = delete;
  PtyPair& operator=(const PtyPair&) = delete;

  /// Whether the pair is ready; error() says why not.
  bool ok() const { return fd_ >= 0; }
  const std::string& error() const { return error_; }
  const std::string& gateway_end() const { return gateway_end_; }
  /// Writes all of text to the device end; false if the write was short or failed.
  bool write(const std::string& text) {
    return ::write(fd_, text.data(), text.size()) == static_cast<ssize_t>(text.size());
  }

 private:
  std::string gateway_end_;
  std::string device_end_;
  ChildProcess socat_;
  int fd_ = -1;
  std::string error_;
};

/// gpsfake replaying `input` once (-1) into a gpsd on 127.0.0.1:port, one sentence every 10 ms.
/// Why -W 3: with a client still connected, gpsfake waits for the device to be released after the
/// log ends; -W makes it end (exit status 1, "Test timed out") 3 s after the last sentence.
inline std::vector<std::string> gpsfake_args(int port, const std::filesystem::path& input) {
  return {"-1", "-q", "-c", "0.01", "-W", "3", "-P", std::to_string(port), input.string()};
}

}  // namespace odonav::test
