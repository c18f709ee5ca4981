// The live sources without DDS: --source parsing (loopback rule), then the read loop fed through a
// real UDP socket on 127.0.0.1 and a real pseudo-terminal (openpty), collecting what it accepts.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <pty.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

#include "odonav/gateway/live_input.hpp"
#include "odonav/gateway/sensor_source.hpp"
#include "odonav/config.hpp"

namespace odonav::gateway {
namespace {

TEST(LiveSource, ParsesUdpAndSerialAndKeepsUdpOnLoopback) {
  const LiveSourceSpec a = parse_live_source("udp:5600", false);
  EXPECT_EQ(a.kind, LiveSourceSpec::Kind::kUdp);
  EXPECT_EQ(a.bind_address, "127.0.0.1");
  EXPECT_EQ(a.port, 5600);
  EXPECT_EQ(parse_live_source("udp:127.0.0.2:65535", false).port, 65535);
  EXPECT_THROW(parse_live_source("udp:0.0.0.0:5600", false), ConfigError);
  EXPECT_THROW(parse_live_source("udp:192.168.1.10:5600", false), ConfigError);
  EXPECT_EQ(parse_live_source("udp:0.0.0.0:5600", true).bind_address, "0.0.0.0");
  for (const char* bad : {"udp:", "udp:0", "udp:65536", "udp:127.0.0.1:x", "udp:localhost:5600", "udp:::1:5600",
                          "serial:", "serial:/dev/ttyUSB0:1234", "serial:/dev/ttyUSB0:fast", "tcp:1"}) {
    try {
      parse_live_source(bad, true);
      ADD_FAILURE() << bad << " accepted";
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
    }
  }
  const LiveSourceSpec s = parse_live_source("serial:/dev/ttyUSB0:9600", false);
  EXPECT_EQ(s.kind, LiveSourceSpec::Kind::kSerial);
  EXPECT_EQ(s.device, "/dev/ttyUSB0");
  EXPECT_EQ(s.baud, 9600);
  EXPECT_EQ(parse_live_source("serial:/dev/ttyS0", false).baud, 115200);
  EXPECT_TRUE(is_live_source("udp:1"));
  EXPECT_FALSE(is_live_source("replay:udp:1"));
}

TEST(LiveSource, OpeningAMissingDeviceNamesIt) {
  try {
    open_live_source(parse_live_source("serial:/nonexistent/tty:9600", false));
    FAIL() << "opened";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("serial:/nonexistent/tty at 9600 baud: open"), std::string::npos) << e.what();
  }
}

/// Collects what the loop accepts.
struct VectorSink : SampleSink {
  std::vector<OdometerSample> odo;
  std::vector<InsSample> att;
  std::vector<GnssSample> fixes;
  void odometer(const OdometerSample& s) override { odo.push_back(s); }
  void ins(const InsSample& s) override { att.push_back(s); }
  void gnss(const GnssSample& s) override { fixes.push_back(s); }
  std::size_t size() const { return odo.size() + att.size() + fixes.size(); }
};

/// The lines every test sends: 50 odometer, 50 attitude, 5 GNSS, with garbage in between.
std::vector<std::string> test_lines() {
  std::vector<std::string> lines;
  for (int i = 0; i < 50; ++i) {
    OdometerSample o;
    o.t_s = 100.0 + 0.01 * i;
    o.pulses = 4294967200u + 3u * static_cast<unsigned>(i);  // wraps through 2^32
    lines.push_back(odometer_line(o, i % 2 == 0));
    InsSample a;
    a.t_s = o.t_s;
    a.attitude = Attitude{0.1 * i, 0.01, -0.02};
    lines.push_back(ins_line(a, true));
    if (i % 10 == 0) {
      GnssSample g;
      g.t_s = o.t_s;
      g.position = Geodetic{0.9, 0.5, 120.0};
      g.vel_enu_mps = Eigen::Vector3d(3.0, 4.0, 0.1);
      lines.push_back(gnss_line(g, false));
      lines.push_back("GNSS,garbage");
      lines.push_back(odometer_line(o, false));  // time does not increase
    }
  }
  return lines;
}

void check_received(const VectorSink& sink, const LineDecoder& d) {
  ASSERT_EQ(sink.odo.size(), 50u);
  ASSERT_EQ(sink.att.size(), 50u);
  ASSERT_EQ(sink.fixes.size(), 5u);
  for (int i = 0; i < 50; ++i) {
    EXPECT_EQ(sink.odo[static_cast<std::size_t>(i)].pulses, 4294967200u + 3u * static_cast<unsigned>(i));
    EXPECT_EQ(sink.att[static_cast<std::size_t>(i)].attitude.heading_rad, recorded_radians(0.1 * i));
  }
  EXPECT_EQ(sink.fixes[2].vel_enu_mps, Eigen::Vector3d(3.0, 4.0, 0.1));
  EXPECT_EQ(d.counters().errors[static_cast<int>(LineError::kWrongFieldCount)], 5u);
  EXPECT_EQ(d.counters().errors[static_cast<int>(LineError::kTimeBackwards)], 5u);
}

/// Runs the loop on `source` in a thread until `expected` samples arrived or 10 s passed.
void run_until(std::unique_ptr<ByteSource> source, LineDecoder& d, VectorSink& sink, std::size_t expected,
               const std::function<void()>& send) {
  std::atomic<std::size_t> received{0};
  struct CountingSink : SampleSink {
    VectorSink& inner;
    std::atomic<std::size_t>& n;
    CountingSink(VectorSink& i, std::atomic<std::size_t>& c) : inner(i), n(c) {}
    void odometer(const OdometerSample& s) override { inner.odometer(s), ++n; }
    void ins(const InsSample& s) override { inner.ins(s), ++n; }
    void gnss(const GnssSample& s) override { inner.gnss(s), ++n; }
  } counting(sink, received);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  std::thread sender(send);
  LiveInputStats stats;
  run_live_input(
      std::move(source), d, counting,
      [&] { return received >= expected || std::chrono::steady_clock::now() > deadline; }, [] {},
      []() -> std::unique_ptr<ByteSource> { throw std::runtime_error("no reopen in this test"); }, stats);
  sender.join();
  EXPECT_EQ(stats.source_failures, 0u) << stats.last_failure;
}

TEST(LiveSource, UdpDatagramsOnLoopbackReachTheSink) {
  // A free port: bind port 0, read what the kernel chose, release it.
  int probe = ::socket(AF_INET, SOCK_DGRAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(::bind(probe, reinterpret_cast<sockaddr*>(&a), sizeof(a)), 0);
  socklen_t len = sizeof(a);
  ::getsockname(probe, reinterpret_cast<sockaddr*>(&a), &len);
  ::close(probe);
  const int port = ntohs(a.sin_port);

  auto source = open_live_source(parse_live_source("udp:127.0.0.1:" + std::to_string(port), false));
  LineDecoder d;
  VectorSink sink;
  const std::vector<std::string> lines = test_lines();
  run_until(std::move(source), d, sink, 105, [&] {
    int s = ::socket(AF_INET, SOCK_DGRAM, 0);
    // Datagrams of one line without '\n', and of three lines with a final unterminated one.
    for (std::size_t i = 0; i < lines.size();) {
      std::string datagram;
      const std::size_t n = (i % 2 == 0) ? 1 : 3;
      for (std::size_t k = 0; k < n && i < lines.size(); ++k, ++i) datagram += (k ? "\n" : "") + lines[i];
      ::sendto(s, datagram.data(), datagram.size(), 0, reinterpret_cast<sockaddr*>(&a), sizeof(a));
      std::this_thread::sleep_for(std::chrono::microseconds(200));  // loopback UDP can drop bursts
    }
    ::close(s);
  });
  check_received(sink, d);
}

TEST(LiveSource, SerialPseudoTerminalReachesTheSink) {
  int master = -1, slave = -1;
  char name[256];
  ASSERT_EQ(::openpty(&master, &slave, name, nullptr, nullptr), 0);
  auto source = open_live_source(parse_live_source(std::string("serial:") + name + ":57600", false));
  LineDecoder d;
  VectorSink sink;
  const std::vector<std::string> lines = test_lines();
  run_until(std::move(source), d, sink, 105, [&] {
    std::string all;
    for (const auto& l : lines) all += l + "\r\n";
    // In odd-sized pieces: lines arrive split across reads.
    for (std::size_t pos = 0; pos < all.size(); pos += 37) {
      const std::string piece = all.substr(pos, 37);
      ASSERT_EQ(::write(master, piece.data(), piece.size()), static_cast<ssize_t>(piece.size()));
      std::this_thread::sleep_for(std::chrono::microseconds(100));
    }
  });
  ::close(slave);
  ::close(master);
  check_received(sink, d);
}

}  // namespace
}  // namespace odonav::gateway
