// odonav-gateway with a live source, as a process on loopback DDS: a drive written by odonav-simulator is
// sent as protocol lines (with malformed and bad-checksum lines mixed in) over UDP on 127.0.0.1 and
// through a socat pseudo-terminal pair; every published message must equal the dataset's sample
// (stamp, counter, angles, position), and Health must count exactly the bad lines sent.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <arpa/inet.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

#include "../nodes/node_test_support.hpp"
#include "live_test_support.hpp"
#include "odonav/gateway/line_protocol.hpp"
#include "odonav/gateway/sensor_source.hpp"

namespace odonav::test {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

fs::path fresh_dir(const std::string& name) {
  const fs::path dir = fs::path(ODONAV_BINARY_DIR) / "test-out" / "live" / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

/// A 12 s straight drive written by odonav-simulator and read back as the gateway's consumers see it.
Dataset simulated_drive(const fs::path& dir) {
  ChildProcess sim(binary("odonav-simulator"),
                   {"straight", "--seed", "5", "--duration-s", "12", "--out", dir.string(), "--log-level", "warn"});
  EXPECT_TRUE(sim.wait_exit(60s));
  EXPECT_EQ(sim.exit_code(), 0);
  return read_dataset(dir.string(), BadRowPolicy::kFail);
}

/// The protocol lines of the drive in time order, with 1 malformed line every 150 and 1 line with
/// a wrong checksum every 250 (both dropped by the gateway, counted in Health).
struct LineScript {
  std::vector<std::string> lines;
  std::vector<std::size_t> odometer_so_far;  ///< per line: good odometer lines sent up to and including it
  std::size_t malformed = 0;
  std::size_t bad_checksum = 0;
};
LineScript line_script(const Dataset& d) {
  LineScript s;
  std::size_t n = 0, odometer_count = 0;
  for (const gateway::SensorEvent& e : gateway::interleave(d)) {
    std::string line;
    switch (e.stream) {
      case gateway::SensorEvent::Stream::kOdometer:
        line = gateway::odometer_line(d.odometer[e.index], n % 2 == 0);
        break;
      case gateway::SensorEvent::Stream::kIns: line = gateway::ins_line(d.ins[e.index], n % 2 == 0); break;
      case gateway::SensorEvent::Stream::kGnss: line = gateway::gnss_line(d.gnss[e.index], n % 2 == 0); break;
    }
    s.lines.push_back(line);
    s.odometer_so_far.push_back(odometer_count += e.stream == gateway::SensorEvent::Stream::kOdometer ? 1 : 0);
    if (++n % 150 == 0) {
      s.lines.push_back("ODO,not-a-time,12");
      s.odometer_so_far.push_back(odometer_count);
      ++s.malformed;
    }
    if (n % 250 == 0) {
      std::string body = "ODO,1,2";
      char hh[3];
      std::snprintf(hh, sizeof(hh), "%02X", gateway::line_checksum(body) ^ 0x5A);
      s.lines.push_back("$" + body + "*" + hh);
      s.odometer_so_far.push_back(odometer_count);
      ++s.bad_checksum;
    }
  }
  return s;
}

/// Sends the lines in bursts of 100 and waits (at most 10 s) after each until the gateway published
/// every odometer sample sent so far: flow control, so a loaded machine cannot overflow a socket
/// buffer. `write` sends some text.
using WaitForOdometer = std::function<void(std::size_t)>;
void send_paced(const LineScript& script, const std::string& line_end,
                const std::function<void(const std::string&)>& write, const WaitForOdometer& wait_for_odometer,
                bool one_write_per_line) {
  std::string chunk;
  for (std::size_t i = 0; i < script.lines.size(); ++i) {
    chunk += script.lines[i] + line_end;
    if (one_write_per_line) write(chunk), chunk.clear();
    if (i % 100 == 99 || i + 1 == script.lines.size()) {
      if (!chunk.empty()) write(chunk), chunk.clear();
      wait_for_odometer(script.odometer_so_far[i]);
    }
  }
}

/// Starts the gateway on `source`, waits until it serves our readers, runs `send`, then checks
/// everything published against the dataset and the Health counters against the script.
void run_and_compare(int domain, const std::string& source, const Dataset& d, const LineScript& script,
                     const std::function<void(const WaitForOdometer&)>& send) {
  shm_clean();
  dds::Participant p(test_participant(domain));
  Collector<msg::Odometer> odo(p, topics::kOdometer);
  Collector<msg::InsAttitude> ins(p, topics::kInsAttitude);
  Collector<msg::GnssFix> gnss(p, topics::kGnssFix);
  Collector<msg::Health> health(p, topics::kHealth);
  ChildProcess gw(binary("odonav-gateway"), node_args(domain, 1.0, {"--source", source}));
  ASSERT_TRUE(gw.started());
  ASSERT_TRUE(odo.reader().wait_for_matched(1, 20s) && ins.reader().wait_for_matched(1, 20s) &&
              gnss.reader().wait_for_matched(1, 20s))
      << "the gateway's writers never matched (exit " << (gw.running() ? -1 : gw.exit_code()) << ")";
  std::this_thread::sleep_for(1s);  // let the gateway's writers discover our readers too
  send([&](std::size_t n) { odo.wait_until([n](const auto& v) { return v.size() >= n; }, 10s); });
  const bool all = odo.wait_until([&](const auto& v) { return v.size() >= d.odometer.size(); }, 30s) &&
                   ins.wait_until([&](const auto& v) { return v.size() >= d.ins.size(); }, 10s) &&
                   gnss.wait_until([&](const auto& v) { return v.size() >= d.gnss.size(); }, 10s);
  EXPECT_TRUE(all) << "received odometer " << odo.size() << "/" << d.odometer.size() << ", INS " << ins.size() << "/"
                   << d.ins.size() << ", GNSS " << gnss.size() << "/" << d.gnss.size();
  gw.signal(SIGINT);
  ASSERT_TRUE(gw.wait_exit(15s));
  EXPECT_EQ(gw.exit_code(), 0);

  const auto o = odo.samples();
  const auto a = ins.samples();
  const auto g = gnss.samples();
  ASSERT_EQ(o.size(), d.odometer.size());
  ASSERT_EQ(a.size(), d.ins.size());
  ASSERT_EQ(g.size(), d.gnss.size());
  for (std::size_t i = 0; i < o.size(); ++i) {
    ASSERT_EQ(o[i].header().stamp(), dds::to_time_msg(d.odometer[i].t_s)) << "odometer " << i;
    ASSERT_EQ(o[i].pulses(), d.odometer[i].pulses) << "odometer " << i;
    ASSERT_EQ(o[i].direction(), d.odometer[i].direction) << "odometer " << i;
  }
  for (std::size_t i = 0; i < a.size(); ++i) {
    ASSERT_EQ(a[i].header().stamp(), dds::to_time_msg(d.ins[i].t_s)) << "INS " << i;
    // Exactly the radians read_dataset gives for the file's degrees.
    ASSERT_EQ(a[i].heading_rad(), d.ins[i].attitude.heading_rad) << "INS " << i;
    ASSERT_EQ(a[i].pitch_rad(), d.ins[i].attitude.pitch_rad) << "INS " << i;
    ASSERT_EQ(a[i].roll_rad(), d.ins[i].attitude.roll_rad) << "INS " << i;
  }
  for (std::size_t i = 0; i < g.size(); ++i) {
    const GnssSample& s = d.gnss[i];
    ASSERT_EQ(g[i].header().stamp(), dds::to_time_msg(s.t_s)) << "GNSS " << i;
    ASSERT_EQ(deg_to_rad(g[i].latitude_deg()), s.position.lat_rad) << "GNSS " << i;
    ASSERT_EQ(deg_to_rad(g[i].longitude_deg()), s.position.lon_rad) << "GNSS " << i;
    ASSERT_EQ(g[i].height_m(), s.position.height_m) << "GNSS " << i;
    ASSERT_EQ(g[i].velocity_north_mps(), s.vel_enu_mps.y()) << "GNSS " << i;
    ASSERT_EQ(g[i].fix_quality(), s.fix) << "GNSS " << i;
    ASSERT_EQ(g[i].valid(), s.valid()) << "GNSS " << i;
  }

  // The last Health ("stopping") counts every line and every rejection.
  ASSERT_TRUE(health.wait_until(
      [](const auto& v) {
        for (const auto& h : v)
          if (h.component() == "odonav-gateway" && h.state() == msg::HEALTH_STATE_STOPPING) return true;
        return false;
      },
      5s));
  std::optional<msg::Health> last;
  for (const auto& h : health.samples())
    if (h.component() == "odonav-gateway") last = h;
  ASSERT_TRUE(last);
  EXPECT_EQ(counter(*last, "odometer_published"), static_cast<double>(d.odometer.size()));
  EXPECT_EQ(counter(*last, "ins_published"), static_cast<double>(d.ins.size()));
  EXPECT_EQ(counter(*last, "gnss_published"), static_cast<double>(d.gnss.size()));
  EXPECT_EQ(counter(*last, "lines_read"), static_cast<double>(script.lines.size()));
  EXPECT_EQ(counter(*last, "lines_malformed"), static_cast<double>(script.malformed));
  EXPECT_EQ(counter(*last, "lines_bad_checksum"), static_cast<double>(script.bad_checksum));
  EXPECT_EQ(counter(*last, "lines_time_backwards"), 0.0);
  EXPECT_EQ(last->level(), msg::HEALTH_LEVEL_WARN);  // bad lines were seen
  std::printf("%s: %zu lines -> %zu odometer, %zu INS, %zu GNSS published; %zu malformed, %zu bad checksums counted\n",
              source.c_str(), script.lines.size(), o.size(), a.size(), g.size(), script.malformed, script.bad_checksum);
}

TEST(LiveGateway, UdpOnLoopbackCarriesASimulatedDrive) {
  const Dataset d = simulated_drive(fresh_dir("udp-drive"));
  ASSERT_GT(d.odometer.size(), 1000u);
  const LineScript script = line_script(d);
  const int port = free_loopback_port(SOCK_DGRAM);
  run_and_compare(90, "udp:127.0.0.1:" + std::to_string(port), d, script, [&](const WaitForOdometer& wait) {
    const LoopbackUdpSender udp(port);
    send_paced(
        script, "\n", [&](const std::string& datagram) { ASSERT_TRUE(udp.send(datagram)); }, wait, true);
  });
}

TEST(LiveGateway, RefusesANonLoopbackBindAndAMissingDevice) {
  // Exit 2 (bad configuration) before anything is bound; never listens on 0.0.0.0.
  ChildProcess wide(binary("odonav-gateway"), node_args(92, 1.0, {"--source", "udp:0.0.0.0:5600"}));
  ASSERT_TRUE(wide.wait_exit(20s));
  EXPECT_EQ(wide.exit_code(), 2);
  // Exit 1 (unusable source), naming it in the log.
  ChildProcess missing(binary("odonav-gateway"), node_args(92, 1.0, {"--source", "serial:/nonexistent/tty0"}));
  ASSERT_TRUE(missing.wait_exit(20s));
  EXPECT_EQ(missing.exit_code(), 1);
}

TEST(LiveGateway, SerialThroughASocatPtyPairCarriesASimulatedDrive) {
  const std::string socat = "/usr/bin/socat";
  if (::access(socat.c_str(), X_OK) != 0) GTEST_SKIP() << "socat not installed (scripts/install-deps installs it)";
  const fs::path dir = fresh_dir("serial-drive");
  const Dataset d = simulated_drive(dir / "dataset");
  const LineScript script = line_script(d);
  PtyPair pty(socat, dir);
  ASSERT_TRUE(pty.ok()) << pty.error();
  run_and_compare(91, "serial:" + pty.gateway_end() + ":115200", d, script, [&](const WaitForOdometer& wait) {
    send_paced(
        script, "\r\n", [&](const std::string& text) { ASSERT_TRUE(pty.write(text)); }, wait, false);
  });
}

}  // namespace
}  // namespace odonav::test
