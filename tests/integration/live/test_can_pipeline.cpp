// The gateway's CAN input as a process on loopback DDS (domains 140-141):
//   1. a simulated drive's odometer counter turned into candump -L frames (a manufacturer's 32-bit
//      Motorola counter, with other traffic, a repeated frame and a malformed line mixed in),
//      replayed by `--source candump:<log> --candump-dataset <INS and GNSS>` at --speed max through
//      calibration, identification, dead reckoning and the recorder: the files equal odonav-offline
//      on the equivalent dataset (the odometer as the log carries it), row by row, to 1e-9;
//   2. `--source candump:-` reading the log on standard input (live mode): every odometer message
//      equals the log's sample, and Health counts the bad and foreign frames exactly;
//   3. `--source candump:-` with `--ins-source udp:...` (domain 142): INS lines arrive beside the CAN
//      odometer, ODO lines of the line source are dropped and counted.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "shm_clean_test.hpp"
#include "../nodes/node_test_support.hpp"
#include "odonav/gateway/can_decoders.hpp"
#include "odonav/gateway/line_protocol.hpp"
#include "live_test_support.hpp"
#include "output_rows_compare.hpp"
#include "odonav/results/output_files.hpp"

namespace odonav::test {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

/// The manufacturer's frame of the test: a 32-bit odometer counter, Motorola, MSB at bit 7 of
/// byte 0, in a proprietary-B J1939 frame (PGN 0xFF10 from source address 0x21).
constexpr std::uint32_t kCounterId = 0x18FF1021;
const char* const kChannel = "signal:id=18FF1021,start=7,length=32,order=motorola,as=counter";

gateway::SignalSpec counter_signal() {
  gateway::SignalSpec s;
  s.id = kCounterId;
  s.extended = true;
  s.start_bit = 7;
  s.length_bits = 32;
  s.order = gateway::SignalSpec::ByteOrder::kMotorola;
  return s;
}

/// A candump log of the drive's odometer and what the gateway must make of it.
struct CanLog {
  std::vector<OdometerSample> odometer;  ///< the samples the log carries (stamps as parsed from the text)
  std::size_t malformed = 0, unknown = 0, stale = 0;
};

/// Writes `path`: one counter frame per odometer sample (stamp with 6 decimals, as candump does), a
/// CCVS1 frame of another ECU every 10th sample (unknown to the channel), the 500th frame repeated
/// (stale) and one malformed line. Stamps round-trip through the text: the expected odometer holds
/// the parsed stamps.
CanLog write_can_log(const Dataset& d, const fs::path& path) {
  CanLog log;
  std::ofstream o(path);
  const gateway::SignalSpec sig = counter_signal();
  for (std::size_t i = 0; i < d.odometer.size(); ++i) {
    const OdometerSample& s = d.odometer[i];
    gateway::CanFrame f;
    f.extended = true;
    f.id = kCounterId;
    f.size = 8;
    f.data.fill(0xFF);
    char stamp[64];
    std::snprintf(stamp, sizeof(stamp), "%.6f", s.t_s);
    f.t_s = std::strtod(stamp, nullptr);
    gateway::insert_raw(f, sig, s.pulses);
    const std::string line = gateway::candump_line(f);
    o << line << "\n";
    log.odometer.push_back(OdometerSample{f.t_s, s.pulses, 1});
    if (i == 500) {
      o << line << "\n";  // the same frame again: stale
      ++log.stale;
    }
    if (i % 10 == 5) {
      o << "(" << stamp << ") can0 18FEF100#FF0024FFFFFFFFFF\n";  // CCVS1 of ECU 0x00: not read here
      ++log.unknown;
    }
    if (i == 777) {
      o << "(" << stamp << ") can0 18FF1021#00112233445566778899\n";  // 9 bytes: malformed
      ++log.malformed;
    }
  }
  return log;
}

fs::path simulate(const fs::path& dir, const std::string& scenario, const std::string& duration_s) {
  const fs::path data = dir / "sim";
  ChildProcess sim(binary("odonav-simulator"), {scenario, "--seed", "2", "--duration-s", duration_s, "--out",
                                                data.string(), "--log-level", "warn"});
  EXPECT_TRUE(sim.wait_exit(120s));
  EXPECT_EQ(sim.exit_code(), 0);
  return data;
}

/// A drive of odonav-simulator (scenario, duration) in dir and its candump log, dir/can.log.
struct CanDrive {
  Dataset d;
  fs::path can_log;
  CanLog log;
};
CanDrive can_drive(const fs::path& dir, const std::string& scenario, const std::string& duration_s) {
  CanDrive r;
  r.d = read_dataset(simulate(dir, scenario, duration_s).string(), BadRowPolicy::kFail);
  r.can_log = dir / "can.log";
  r.log = write_can_log(r.d, r.can_log);
  return r;
}

class CanPipeline : public odonav::test::ShmCleanTest {};

TEST_F(CanPipeline, ReplayedCandumpLogEqualsTheOfflineToolOnTheEquivalentDataset) {
  const fs::path dir = fresh_live_dir("can-pipeline");
  const auto [d, can_log, log] = can_drive(dir, "terrain", "90");
  ASSERT_TRUE(d.has_ins());
  // What odonav-offline reads: the drive with the odometer as the log carries it.
  Dataset equivalent = d;
  equivalent.odometer = log.odometer;
  write_dataset((dir / "equivalent").string(), equivalent);
  // What the gateway replays beside the log: INS and GNSS; its odometer.csv has 2 rows, which must
  // not be what is published (the reader needs the file).
  Dataset companion = d;
  companion.odometer = {d.odometer.front(), d.odometer.back()};
  write_dataset((dir / "companion").string(), companion);

  const int domain = 140;
  const std::vector<std::string> common{
      "--domain",     std::to_string(domain),
      "--profile",    std::string(ODONAV_SOURCE_DIR) + "/deploy/profiles/loopback.xml",
      "--vehicle-id", kVehicle};
  std::vector<std::string> node = common;
  node.insert(node.end(), {"--max-wait-s", "30"});
  if (d.meta.gnss_lever_arm_m) {
    char arm[128];
    const auto& a = *d.meta.gnss_lever_arm_m;
    std::snprintf(arm, sizeof(arm), "%.17g,%.17g,%.17g", a.x(), a.y(), a.z());
    node.insert(node.end(), {"--lever-arm", arm});
  }
  std::vector<std::string> with_k = node;
  if (d.meta.k_nominal_m_per_pulse) {
    char k[64];
    std::snprintf(k, sizeof(k), "%.17g", *d.meta.k_nominal_m_per_pulse);
    with_k.insert(with_k.end(), {"--nominal-k", k});
  }
  const fs::path out = dir / "out";
  const auto with = [](std::vector<std::string> a, std::vector<std::string> more) {
    a.insert(a.end(), more.begin(), more.end());
    return a;
  };
  struct Component {
    std::string name;
    std::unique_ptr<ChildProcess> process;
  };
  std::vector<Component> components;
  const auto start = [&](const std::string& name, const std::vector<std::string>& args) {
    components.push_back({name, start_logged(name, args, dir / (name + ".log"))});
  };
  start("odonav-recorder", with(common, {"--out", out.string()}));
  start("odonav-dead-reckoning", with(with_k, {"--state-dir", (dir / "state" / "dr").string()}));
  start("odonav-identification", with(with_k, {"--state-dir", (dir / "state" / "id").string()}));
  start("odonav-calibration", with(node, {"--state-dir", (dir / "state" / "cal").string()}));
  // As deploy/launch: the data starts once the recorder has matched every producer.
  const auto recorder_ready = [&] {
    return read_text(dir / "odonav-recorder.log").find("every producer matched") != std::string::npos;
  };
  for (int i = 0; i < 300 && !recorder_ready(); ++i) std::this_thread::sleep_for(200ms);
  ASSERT_TRUE(recorder_ready()) << read_text(dir / "odonav-recorder.log");

  ChildProcess gw(
      binary("odonav-gateway"),
      with(common, {"--source", "candump:" + can_log.string(), "--candump-dataset", (dir / "companion").string(),
                    "--can-odometer", kChannel, "--speed", "max", "--wait-for-readers", "4"}),
      dir / "gateway.log", dir / "gateway.log");
  ASSERT_TRUE(gw.wait_exit(300s)) << "the gateway did not finish\n" << read_text(dir / "gateway.log");
  ASSERT_EQ(gw.exit_code(), 0) << read_text(dir / "gateway.log");
  // Data-flow order: each one's inputs are complete when it is told to stop.
  for (auto it = components.rbegin(); it != components.rend(); ++it) {
    it->process->signal(SIGINT);
    EXPECT_TRUE(it->process->wait_exit(120s)) << it->name;
    EXPECT_EQ(it->process->exit_code(), 0) << it->name << "\n" << read_text(dir / (it->name + ".log"));
  }
  const std::string gateway_log = read_text(dir / "gateway.log");
  char counts[256];
  std::snprintf(counts, sizeof(counts),
                "frames decoded into %zu odometer samples; %zu malformed, %zu unknown, 0 out of order, %zu stale, 0 "
                "undecodable",
                log.odometer.size(), log.malformed, log.unknown, log.stale);
  EXPECT_NE(gateway_log.find(counts), std::string::npos) << "expected '" << counts << "' in\n" << gateway_log;

  const fs::path offline = dir / "offline";
  ChildProcess off(binary("odonav-offline"), {(dir / "equivalent").string(), "--out", offline.string()},
                   dir / "offline.log", dir / "offline.log");
  ASSERT_TRUE(off.wait_exit(300s));
  ASSERT_EQ(off.exit_code(), 0) << read_text(dir / "offline.log");
  // The pipeline's files against odonav-offline's, row by row (as tests/integration/pipeline does).
  expect_estimate_rows_equal(results::read_output_rows(out.string()), results::read_output_rows(offline.string()),
                             1e-9);
}

TEST_F(CanPipeline, LiveStandardInputPublishesEveryFrameAndCountsTheBadOnes) {
  const fs::path dir = fresh_live_dir("can-stdin");
  const Dataset d = read_dataset(simulate(dir, "straight", "12").string(), BadRowPolicy::kFail);
  const fs::path can_log = dir / "can.log";
  const CanLog log = write_can_log(d, can_log);
  const int domain = 141;
  dds::Participant p(test_participant(domain));
  Collector<msg::Odometer> odo(p, topics::kOdometer);
  Collector<msg::Health> health(p, topics::kHealth);
  // As `candump -L can0 | odonav-gateway --source candump:-`: the log arrives on a pipe after the
  // reader had time to match (the writers keep 3000 samples for a late reader anyway).
  const std::string command = "sleep 2; cat '" + can_log.string() + "'";
  std::string gateway = binary("odonav-gateway");
  for (const std::string& a : node_args(domain, 30.0, {"--source", "candump:-", "--can-odometer", kChannel}))
    gateway += " '" + a + "'";
  ChildProcess gw("/bin/sh", {"-c", "(" + command + ") | " + gateway}, dir / "gateway.log", dir / "gateway.log");
  ASSERT_TRUE(gw.wait_exit(60s)) << read_text(dir / "gateway.log");
  EXPECT_EQ(gw.exit_code(), 0) << read_text(dir / "gateway.log");
  ASSERT_TRUE(odo.wait_until([&log = log](const auto& v) { return v.size() >= log.odometer.size(); }, 10s))
      << odo.size() << " of " << log.odometer.size();
  const auto got = odo.samples();
  ASSERT_EQ(got.size(), log.odometer.size());
  for (std::size_t i = 0; i < got.size(); ++i) {
    ASSERT_EQ(dds::to_seconds(got[i].header().stamp()), wire_time(log.odometer[i].t_s)) << i;
    ASSERT_EQ(got[i].pulses(), log.odometer[i].pulses) << i;
  }
  ASSERT_TRUE(health.wait_until(
      [](const auto& v) { return !v.empty() && v.back().state() == msg::HEALTH_STATE_STOPPING; }, 10s));
  const msg::Health last = health.samples().back();
  EXPECT_EQ(counter(last, "odometer_published"), static_cast<double>(log.odometer.size()));
  EXPECT_EQ(counter(last, "can_odometer_samples"), static_cast<double>(log.odometer.size()));
  EXPECT_EQ(counter(last, "can_frames_malformed"), static_cast<double>(log.malformed));
  EXPECT_EQ(counter(last, "can_frames_unknown"), static_cast<double>(log.unknown));
  EXPECT_EQ(counter(last, "can_frames_stale"), static_cast<double>(log.stale));
  EXPECT_EQ(counter(last, "can_frames_out_of_order"), 0.0);
  EXPECT_NE(last.reason().find("end of CAN input"), std::string::npos) << last.reason();
}

TEST_F(CanPipeline, LiveCanOdometerWithInsLinesOverUdp) {
  const fs::path dir = fresh_live_dir("can-stdin-ins");
  const auto [d, can_log, log] = can_drive(dir, "straight", "5");
  ASSERT_TRUE(d.has_ins());
  const int domain = 142;
  dds::Participant p(test_participant(domain));
  Collector<msg::Odometer> odo(p, topics::kOdometer);
  Collector<msg::InsAttitude> ins(p, topics::kInsAttitude);
  Collector<msg::Health> health(p, topics::kHealth);
  const int port = free_loopback_port(SOCK_DGRAM);
  // Standard input stays open 8 s after the log, while the INS lines come over UDP; its end ends the run.
  const std::string command = "sleep 2; cat '" + can_log.string() + "'; sleep 8";
  std::string gateway = binary("odonav-gateway");
  for (const std::string& a : node_args(domain, 30.0,
                                        {"--source", "candump:-", "--can-odometer", kChannel, "--ins-source",
                                         "udp:127.0.0.1:" + std::to_string(port)}))
    gateway += " '" + a + "'";
  ChildProcess gw("/bin/sh", {"-c", "(" + command + ") | " + gateway}, dir / "gateway.log", dir / "gateway.log");
  ASSERT_TRUE(ins.reader().wait_for_matched(1, 20s)) << read_text(dir / "gateway.log");
  std::this_thread::sleep_for(500ms);
  const LoopbackUdpSender udp(port);
  ASSERT_TRUE(udp.is_open());
  const auto send = [&](const std::string& line) { udp.send(line + "\n"); };
  send(gateway::odometer_line(d.odometer.front(), false));  // the CAN input gives the odometer: ignored
  for (std::size_t i = 0; i < d.ins.size(); ++i) {
    send(gateway::ins_line(d.ins[i], false));
    if (i % 50 == 49) std::this_thread::sleep_for(5ms);
  }
  EXPECT_TRUE(ins.wait_until([&d = d](const auto& v) { return v.size() >= d.ins.size(); }, 10s))
      << ins.size() << " of " << d.ins.size() << " INS";
  ASSERT_TRUE(gw.wait_exit(30s)) << read_text(dir / "gateway.log");
  EXPECT_EQ(gw.exit_code(), 0) << read_text(dir / "gateway.log");
  EXPECT_TRUE(odo.wait_until([&log = log](const auto& v) { return v.size() >= log.odometer.size(); }, 10s));
  EXPECT_EQ(odo.size(), log.odometer.size()) << "the CAN samples, not the ODO line as well";
  ASSERT_TRUE(health.wait_until(
      [](const auto& v) { return !v.empty() && v.back().state() == msg::HEALTH_STATE_STOPPING; }, 10s));
  const msg::Health last = health.samples().back();
  EXPECT_EQ(counter(last, "ins_published"), static_cast<double>(d.ins.size()));
  EXPECT_EQ(counter(last, "odometer_lines_ignored"), 1.0);
  EXPECT_EQ(counter(last, "odometer_published"), static_cast<double>(log.odometer.size()));
}

}  // namespace
}  // namespace odonav::test
