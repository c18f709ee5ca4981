// The secure pipeline starting under a discovery flood (docs/DDS.md §6, "Discovery floods").
//
// The five components (recorder, dead reckoning, identification, calibration together, then the
// gateway once the recorder has its producers, as deploy/launch starts them) start with DDS Security on the loopback (deploy/profiles/loopback-secure.xml, a PKI from
// deploy/security/make-pki) while a second process without credentials, odonav-spdp-flood,
// announces 200 participants to every discovery port of the domain once a second. Checked, by
// counts only:
// - every producer is matched: the recorder logs "every producer matched", the gateway its
//   readers, and the drive goes through: the recorder writes misalignment, scale factor and dead
//   reckoning rows, one dead-reckoning row per odometer increment the gateway published (a 20 s
//   drive at real time);
// - no legitimate lease expires: no component logs a legitimate participant "lost: its lease
//   expired", and no handshake among them stays incomplete;
// - the flood was there: every component discovered and refused all 200 (its DDS Security summary
//   line), and every component announced itself to the flood (the flood counts 5 responders);
// - no flood participant is held back: no handshake set-up waited for one of them.
// The times from the start to "every producer matched" and to the gateway's readers matched are
// printed as figures ([figure] lines) for
// BENCHMARKS.md, never asserted. Environment for the benchmark (scripts/bench flood):
// ODONAV_FLOOD_PARTICIPANTS (default 200; 0 = no flood), ODONAV_FLOOD_COMPONENT_BIN (the
// components' directory, default this build's bin/, e.g. an older build to compare) and
// ODONAV_FLOOD_IDENTITY_TOKEN=1 (the flood announces PKI-DH credentials it never backs with a
// handshake: every component prepares and sends a handshake to each; only matching, data and
// leases are then checked, the flood stays "handshake incomplete").
// Domain 210.
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "child_process.hpp"
#include "odonav/results/output_files.hpp"

namespace {

using namespace std::chrono_literals;
using odonav::test::ChildProcess;
using odonav::test::read_text;
using odonav::test::tail_of;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

const fs::path kSource = ODONAV_SOURCE_DIR;
constexpr int kDomain = 210;
constexpr const char* kVehicle = "test-vehicle";
constexpr double kDriveDuration_s = 20.0;
const std::vector<std::string> kComponents = {"odonav-recorder", "odonav-dead-reckoning", "odonav-identification",
                                              "odonav-calibration", "odonav-gateway"};

std::string env_or(const char* name, const std::string& fallback) {
  const char* v = std::getenv(name);
  return v == nullptr || *v == '\0' ? fallback : std::string(v);
}

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

/// The numbers of a component's "DDS Security summary" line (participant.cpp), -1 when absent.
struct Summary {
  long discovered = -1, without_credentials = -1, refused = -1, authenticated = -1;
  long spaced = -1, delayed = -1;
  double wait_s = -1.0;
};
Summary summary_of(const std::string& log) {
  static const std::regex re(
      "DDS Security summary: (\\d+) participants discovered, (\\d+) without credentials, (\\d+) refused, (\\d+) "
      "authenticated; (\\d+) handshake set-ups spaced, (\\d+) held back for ([0-9.]+) s");
  Summary s;
  std::smatch m;
  if (std::regex_search(log, m, re)) {
    s.discovered = std::stol(m[1]);
    s.without_credentials = std::stol(m[2]);
    s.refused = std::stol(m[3]);
    s.authenticated = std::stol(m[4]);
    s.spaced = std::stol(m[5]);
    s.delayed = std::stol(m[6]);
    s.wait_s = std::stod(m[7]);
  }
  return s;
}

}  // namespace

TEST(SecureStartUnderFlood, EveryProducerMatchedAndNoLegitimateLeaseLost) {
  const int flood_participants = std::stoi(env_or("ODONAV_FLOOD_PARTICIPANTS", "200"));
  const fs::path component_bin = env_or("ODONAV_FLOOD_COMPONENT_BIN", odonav::test::binary(""));
  const bool with_token = env_or("ODONAV_FLOOD_IDENTITY_TOKEN", "0") == "1";
  const fs::path dir = odonav::test::fresh_dir("flood", "secure");
  const fs::path pki = dir / "pki";
  const std::string make_pki = (kSource / "deploy/security/make-pki").string() + " --out " + pki.string() +
                               " --org odonav-test >" + (dir / "pki.log").string() + " 2>&1";
  ASSERT_EQ(std::system(make_pki.c_str()), 0) << make_pki << "\n" << read_text(dir / "pki.log");
  odonav::test::shm_clean();

  const auto log_of = [&](const std::string& name) { return dir / (name + ".log"); };
  std::unique_ptr<ChildProcess> flood;
  if (flood_participants > 0) {
    flood = std::make_unique<ChildProcess>(
        odonav::test::binary("odonav-spdp-flood"),
        std::vector<std::string>{"--domain", std::to_string(kDomain), "--participants",
                                 std::to_string(flood_participants), "--duration-s", "600",
                                 with_token ? "--identity-token" : "--no-identity-token"},
        dir / "flood.out", log_of("flood"));
    ASSERT_TRUE(flood->started());
  }
  // Let the flood's first round go out: the components start into a flood that is already on.
  std::this_thread::sleep_for(1500ms);

  const std::vector<std::string> common = {"--domain",       std::to_string(kDomain),
                                           "--profile",      (kSource / "deploy/profiles/loopback-secure.xml").string(),
                                           "--profile-name", "loopback_secure",
                                           "--vehicle-id",   kVehicle,
                                           "--security-dir", pki.string(),
                                           "--log-level",    "info"};
  const auto with = [&](std::vector<std::string> extra) {
    std::vector<std::string> a = common;
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  };
  std::map<std::string, std::unique_ptr<ChildProcess>> procs;
  const auto start = [&](const std::string& name, const std::vector<std::string>& args) {
    procs[name] = std::make_unique<ChildProcess>((component_bin / name).string(), args, log_of(name), log_of(name));
    ASSERT_TRUE(procs[name]->started()) << name;
  };
  const Clock::time_point t0 = Clock::now();
  start("odonav-recorder", with({"--out", (dir / "out").string()}));
  // The nodes wait up to 30 s for a lagging input instead of the default 2 s: on a loaded machine
  // a stalled input must not cost rows, since the test counts every one.
  const std::vector<std::string> node = {"--max-wait-s", "30"};
  start("odonav-dead-reckoning", with(node));
  start("odonav-identification", with(node));
  start("odonav-calibration", with(node));
  // Time to "every producer matched" (recorder: calibration, identification and DR matched) from
  // the start of the four, then the gateway, started only then as deploy/launch does (the first
  // outputs of DR would otherwise miss a recorder whose reader matched DR's writer after the data
  // began: VOLATILE), and the time to its "readers matched" (logged after the counts stayed put
  // for 0.5 s) from its own start: figures.
  double recorder_matched_s = -1.0, gateway_matched_s = -1.0;
  const auto matched_deadline = t0 + 150s;
  while (Clock::now() < matched_deadline && recorder_matched_s < 0) {
    if (read_text(log_of("odonav-recorder")).find("every producer matched") != std::string::npos)
      recorder_matched_s = seconds_since(t0);
    std::this_thread::sleep_for(20ms);
  }
  const Clock::time_point t_gateway = Clock::now();
  if (recorder_matched_s >= 0) {
    start("odonav-gateway", with({"--source", "sim:straight", "--duration-s", std::to_string(kDriveDuration_s),
                                  "--speed", "1", "--wait-for-readers", "4", "--wait-for-readers-timeout-s", "120"}));
    while (Clock::now() < t_gateway + 150s && gateway_matched_s < 0) {
      if (read_text(log_of("odonav-gateway")).find("readers matched:") != std::string::npos)
        gateway_matched_s = seconds_since(t_gateway);
      if (!procs["odonav-gateway"]->running()) break;
      std::this_thread::sleep_for(20ms);
    }
  }
  std::cerr << "[figure] flood participants " << flood_participants << (with_token ? " with identity tokens" : "")
            << ": every producer matched (recorder) after " << recorder_matched_s << " s, gateway readers matched "
            << gateway_matched_s << " s after its start\n";
  ASSERT_GE(recorder_matched_s, 0.0) << "the recorder never logged 'every producer matched'\n"
                                     << tail_of(log_of("odonav-recorder"));
  ASSERT_GE(gateway_matched_s, 0.0) << "the gateway never matched its readers\n" << tail_of(log_of("odonav-gateway"));

  // The drive at real time (flow control at maximum speed is another matter: BENCHMARKS.md §5),
  // then the consumers in data-flow order.
  ChildProcess& gateway = *procs["odonav-gateway"];
  ASSERT_TRUE(gateway.wait_exit(120s)) << "the gateway did not reach the end of the data\n"
                                       << tail_of(log_of("odonav-gateway"));
  EXPECT_EQ(gateway.exit_code(), 0) << tail_of(log_of("odonav-gateway"));
  for (const char* c : {"odonav-calibration", "odonav-identification", "odonav-dead-reckoning", "odonav-recorder"}) {
    procs[c]->signal(SIGINT);
    ASSERT_TRUE(procs[c]->wait_exit(60s)) << c << " did not stop\n" << tail_of(log_of(c));
    EXPECT_EQ(procs[c]->exit_code(), 0) << c << "\n" << tail_of(log_of(c));
  }
  nlohmann::json flood_result;
  if (flood) {
    flood->signal(SIGINT);
    ASSERT_TRUE(flood->wait_exit(20s)) << read_text(log_of("flood"));
    EXPECT_EQ(flood->exit_code(), 0) << read_text(log_of("flood"));
    flood_result = nlohmann::json::parse(read_text(dir / "flood.out"), nullptr, false);
    ASSERT_FALSE(flood_result.is_discarded()) << read_text(dir / "flood.out") << read_text(log_of("flood"));
    std::cerr << "flood: " << flood_result.dump() << "\n";
  }
  odonav::test::shm_clean();

  // Every producer's data went through: the recorder has every kind of row, and DR one row per
  // odometer sample the gateway published.
  const auto rows = odonav::results::read_output_rows((dir / "out").string());
  EXPECT_GT(rows.misalignment.size(), 0u) << "nothing from calibration reached the recorder";
  EXPECT_GT(rows.scale_factor.size(), 0u) << "nothing from identification reached the recorder";
  const std::string gateway_log = read_text(log_of("odonav-gateway"));
  // The gateway's writers matched every consumer before the first sample (odometer: identification
  // and DR; INS and GNSS: calibration too).
  std::smatch matched;
  ASSERT_TRUE(
      std::regex_search(gateway_log, matched, std::regex("readers matched: odometer (\\d+), INS (\\d+), GNSS (\\d+)")))
      << gateway_log;
  EXPECT_EQ(matched.str(0), "readers matched: odometer 2, INS 3, GNSS 4");
  std::smatch published;
  ASSERT_TRUE(std::regex_search(gateway_log, published, std::regex("published (\\d+) odometer"))) << gateway_log;
  // The first odometer sample starts the integration (odonav-offline writes N - 1 rows too).
  EXPECT_EQ(rows.dead_reckoning.size() + 1, std::stoul(published[1])) << "DR rows vs odometer samples published";

  // No legitimate participant lost its lease, and every pair authenticated.
  const std::regex lost_re("participant '(odonav-[a-z-]+)' \\([0-9a-f.]+\\) lost: its lease expired");
  for (const auto& c : kComponents) {
    const std::string log = read_text(log_of(c));
    std::size_t lost = 0;
    for (auto it = std::sregex_iterator(log.begin(), log.end(), lost_re); it != std::sregex_iterator(); ++it) {
      ++lost;
      ADD_FAILURE() << c << ": " << it->str();
    }
    EXPECT_EQ(lost, 0u) << c;
    const Summary s = summary_of(log);
    std::cerr << "[figure] " << c << ": discovered " << s.discovered << ", without credentials "
              << s.without_credentials << ", refused " << s.refused << ", authenticated " << s.authenticated
              << ", set-ups spaced " << s.spaced << ", held back " << s.delayed << " for " << s.wait_s << " s\n";
    if (s.discovered < 0 || with_token) continue;  // an older build (no summary line), or the flood has credentials
    EXPECT_EQ(log.find("handshake with participant"), std::string::npos) << c << ": a handshake stayed incomplete";
    EXPECT_GE(s.authenticated, static_cast<long>(kComponents.size()) - 1) << c;
    EXPECT_EQ(s.without_credentials, flood_participants) << c << ": discovered the whole flood";
    EXPECT_GE(s.refused, flood_participants) << c;
    // Only the four legitimate peers go through the set-up spacing, never a flood participant.
    EXPECT_LE(s.spaced, static_cast<long>(kComponents.size()) - 1) << c;
  }
  if (flood) {
    EXPECT_EQ(flood_result.at("responders").get<int>(), static_cast<int>(kComponents.size()))
        << "every component discovered the flood and announced itself to it";
  }
}
