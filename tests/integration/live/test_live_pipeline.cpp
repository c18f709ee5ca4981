// The whole pipeline over a live source (domains 122-125): a simulated drive sent as ODO/ATT/GNSS
// protocol lines over UDP on 127.0.0.1, and through a socat pseudo-terminal pair (serial), through
// odonav-gateway, odonav-calibration, odonav-identification and odonav-dead-reckoning must reach the same K as the replay of the same
// dataset through the same processes. The lines carry exactly the numbers read_dataset gives
// (shortest round-trip decimals, angles as the files hold them), so the same samples arrive in the
// same order and the estimates must be identical.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <unistd.h>

#include <cstdio>
#include <functional>

#include "odonav/gateway/line_protocol.hpp"
#include "odonav/gateway/sensor_source.hpp"
#include "live_test_support.hpp"
#include "odonav/msg/ScaleFactor.h"

namespace odonav::test {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

/// The consumers' estimates of one run.
struct PipelineRun {
  std::vector<msg::ScaleFactor> k;  ///< distinct estimates (heartbeats dropped), in arrival order
};

/// Starts dead reckoning, identification and calibration on `domain`, runs `drive` (which starts the
/// gateway and returns when all its data is published), then stops the consumers in data-flow order.
PipelineRun run_pipeline(int domain, const std::function<void(dds::Participant&)>& drive) {
  shm_clean();
  PipelineRun run;
  dds::Participant p(test_participant(domain));
  Collector<msg::ScaleFactor> k(p, topics::kScaleFactor);
  Collector<msg::Health> health(p, topics::kHealth);
  const std::vector<std::string> names{"odonav-dead-reckoning", "odonav-identification", "odonav-calibration"};
  std::vector<std::unique_ptr<ChildProcess>> nodes;
  for (const auto& n : names) nodes.push_back(std::make_unique<ChildProcess>(binary(n), node_args(domain, 30.0)));
  const bool up = health.wait_until(
      [&](const std::vector<msg::Health>& v) {
        for (const auto& n : names) {
          bool seen = false;
          for (const auto& h : v) seen = seen || h.component() == n;
          if (!seen) return false;
        }
        return true;
      },
      30s);
  EXPECT_TRUE(up) << "the consumers did not all report health within 30 s";
  if (!up) return run;
  drive(p);
  // Data-flow order: each one's inputs are complete when it is told to stop.
  for (std::size_t i = nodes.size(); i-- > 0;) {
    nodes[i]->signal(SIGINT);
    EXPECT_TRUE(nodes[i]->wait_exit(60s)) << names[i];
    EXPECT_EQ(nodes[i]->exit_code(), 0) << names[i];
  }
  std::this_thread::sleep_for(300ms);
  run.k = without_repeats(k.samples());
  shm_clean();
  return run;
}

/// A simulated drive, its replay through the pipeline, and the same samples as protocol lines in
/// the replay's interleaved order (with the odometer count reached after each line, for pacing).
struct DriveAndReplay {
  Dataset d;
  PipelineRun replay;
  std::vector<std::string> lines;
  std::vector<std::size_t> odometer_so_far;
};

DriveAndReplay drive_and_replay(const std::string& name, int domain) {
  DriveAndReplay r;
  const fs::path dir = fresh_live_dir(name);
  const std::string data = (dir / "dataset").string();
  ChildProcess sim(binary("odonav-simulator"),
                   {"straight", "--seed", "5", "--duration-s", "60", "--out", data, "--log-level", "warn"});
  EXPECT_TRUE(sim.wait_exit(60s));
  EXPECT_EQ(sim.exit_code(), 0);
  r.d = read_dataset(data, BadRowPolicy::kFail);
  // Replay: the gateway reads the directory and waits for the three consumers itself.
  r.replay = run_pipeline(domain, [&](dds::Participant&) {
    ChildProcess gw(
        binary("odonav-gateway"),
        node_args(domain, 30.0, {"--source", "replay:" + data, "--speed", "max", "--wait-for-readers", "3"}));
    EXPECT_TRUE(gw.wait_exit(120s)) << "replay gateway did not finish";
    EXPECT_EQ(gw.exit_code(), 0);
  });
  std::size_t odometer_count = 0;
  for (const gateway::SensorEvent& e : gateway::interleave(r.d)) {
    switch (e.stream) {
      case gateway::SensorEvent::Stream::kOdometer:
        r.lines.push_back(gateway::odometer_line(r.d.odometer[e.index], false));
        ++odometer_count;
        break;
      case gateway::SensorEvent::Stream::kIns: r.lines.push_back(gateway::ins_line(r.d.ins[e.index], false)); break;
      case gateway::SensorEvent::Stream::kGnss: r.lines.push_back(gateway::gnss_line(r.d.gnss[e.index], false)); break;
    }
    r.odometer_so_far.push_back(odometer_count);
  }
  return r;
}

/// The live half: the gateway on `source`; `send` writes each line (with its end of line), paced by
/// what the gateway has published (bursts of 100 lines), so no socket or tty buffer overflows.
PipelineRun live_pipeline(int domain, const std::string& source, const DriveAndReplay& r,
                          const std::function<void(const std::string&)>& send) {
  return run_pipeline(domain, [&](dds::Participant& p) {
    Collector<msg::Odometer> odo(p, topics::kOdometer);
    ChildProcess gw(binary("odonav-gateway"), node_args(domain, 30.0, {"--source", source}));
    ASSERT_TRUE(odo.reader().wait_for_matched(1, 20s)) << "the live gateway's writers never matched";
    std::this_thread::sleep_for(2s);  // the consumers' readers are matched too by now (same discovery)
    for (std::size_t i = 0; i < r.lines.size(); ++i) {
      send(r.lines[i]);
      if (::testing::Test::HasFatalFailure()) return;
      if (i % 100 == 99 || i + 1 == r.lines.size()) {
        const std::size_t n = r.odometer_so_far[i];
        ASSERT_TRUE(odo.wait_until([n](const auto& v) { return v.size() >= n; }, 20s))
            << "the gateway published " << odo.size() << " of " << n << " odometer samples sent";
      }
    }
    std::this_thread::sleep_for(500ms);  // the GNSS and INS lines after the last odometer line
    gw.signal(SIGINT);
    EXPECT_TRUE(gw.wait_exit(15s));
    EXPECT_EQ(gw.exit_code(), 0);
  });
}

/// Same samples, same order: the same estimates, the last K to the last bit.
void expect_same_k(const DriveAndReplay& r, const PipelineRun& live, const char* what) {
  ASSERT_FALSE(r.replay.k.empty()) << "no K from the replay";
  ASSERT_FALSE(live.k.empty()) << "no K from the live run";
  const msg::ScaleFactor& a = r.replay.k.back();
  const msg::ScaleFactor& b = live.k.back();
  EXPECT_EQ(b.header().stamp(), a.header().stamp());
  EXPECT_EQ(b.samples_accepted(), a.samples_accepted());
  EXPECT_EQ(b.converged(), a.converged());
  const double dk = b.k_m_per_pulse() - a.k_m_per_pulse();
  EXPECT_EQ(dk, 0.0);
  EXPECT_EQ(live.k.size(), r.replay.k.size()) << "the same number of distinct estimates";
  const double k_true = r.d.truth.back().k_true_m_per_pulse;
  EXPECT_NEAR(a.k_m_per_pulse(), k_true, 0.01 * k_true) << "the replay's K is the scenario's (within 1 %)";
  std::printf(
      "final K (%s): replay %.12g, live %.12g m/pulse (difference %.3g, %zu / %zu estimates, converged %d), "
      "K_true %.12g\n",
      what, a.k_m_per_pulse(), b.k_m_per_pulse(), dk, r.replay.k.size(), live.k.size(), a.converged() ? 1 : 0, k_true);
}

TEST(LivePipeline, UdpLinesReachTheSameKAsTheReplay) {
  const DriveAndReplay r = drive_and_replay("pipeline", 122);
  if (HasFatalFailure()) return;
  const int port = free_loopback_port(SOCK_DGRAM);
  const LoopbackUdpSender udp(port);
  ASSERT_TRUE(udp.is_open());
  const PipelineRun live = live_pipeline(123, "udp:127.0.0.1:" + std::to_string(port), r,
                                         [&](const std::string& line) { ASSERT_TRUE(udp.send(line + "\n")); });
  expect_same_k(r, live, "udp");
}

TEST(LivePipeline, SerialLinesThroughAPtyPairReachTheSameKAsTheReplay) {
  const std::string socat = "/usr/bin/socat";
  ASSERT_EQ(::access(socat.c_str(), X_OK), 0) << "socat not installed (scripts/install-deps installs it)";
  const DriveAndReplay r = drive_and_replay("pipeline-serial", 124);
  if (HasFatalFailure()) return;
  const fs::path dir = fresh_live_dir("pipeline-serial-tty");
  PtyPair pty(socat, dir);
  ASSERT_TRUE(pty.ok()) << pty.error();
  const PipelineRun live = live_pipeline(125, "serial:" + pty.gateway_end() + ":115200", r,
                                         [&](const std::string& line) { ASSERT_TRUE(pty.write(line + "\r\n")); });
  expect_same_k(r, live, "serial");
}

}  // namespace
}  // namespace odonav::test
