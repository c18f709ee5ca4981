// odonav-ground serve against REAL vehicle pipelines (gateway with a simulated drive, calibration,
// identification, dead reckoning as processes on loopback DDS, domains 180-181), the web server
// bound to 127.0.0.1 on a free port:
//   1. a Foxglove client (@foxglove/ws-protocol, CDR decoded with @foxglove/rosmsg2-serialization):
//      both subprotocol names, the documented channels, NavSatFix equal to the dead reckoning of the
//      same stamp (read by this test's own DDS reader) to 1e-9 deg, ScaleFactor's K equal to the
//      pipeline's, DiagnosticArray naming every component, reconnect, a client that never reads
//      not slowing the others, a SIGKILLed identification STALE within two deadline periods;
//   2. the fleet page in Debian's chromium (puppeteer-core), two vehicles: K within 1 % of the
//      simulator's truth, every component OK, set K refused without the token and acknowledged with
//      it (DR navigates with it), a SIGKILLed identification STALE; a screenshot in the build folder.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <set>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <regex>

#include "shm_clean_test.hpp"
#include "ground_test_support.hpp"
#include "odonav/dds/endpoints.hpp"
#include "odonav/dds/time.hpp"
#include "odonav/msg/DeadReckoning.h"
#include "odonav/msg/ScaleFactor.h"

using namespace odonav::test;

namespace {

/// node_modules with the web tests' npm packages, installed the first time (under a lock). One
/// retry, verbose: a registry that fails once (it did, silently, in a CI run) must not fail the tests.
std::optional<fs::path> npm_web_modules() {
  if (std::system("command -v node >/dev/null 2>&1 && command -v npm >/dev/null 2>&1") != 0) {
    ADD_FAILURE() << "node and npm are needed (Debian 12: apt-get install nodejs npm)";
    return std::nullopt;
  }
  const fs::path dir = fs::path(ODONAV_BINARY_DIR) / "tests" / "ground-web-npm";
  fs::create_directories(dir);
  const std::string packages =
      "@foxglove/ws-protocol ws @foxglove/rosmsg @foxglove/rosmsg2-serialization puppeteer-core";
  const std::string cmd = "cd '" + dir.string() +
                          "' && flock .lock sh -c 'test -d node_modules/@foxglove/ws-protocol -a -d node_modules/ws "
                          "-a -d node_modules/puppeteer-core -a -d node_modules/@foxglove/rosmsg2-serialization || "
                          "npm install --no-audit --no-fund --silent " +
                          packages + " || { sleep 5; npm install --no-audit --no-fund " + packages +
                          "; }' >npm-install.log 2>&1";
  if (std::system(cmd.c_str()) != 0) {
    ADD_FAILURE() << "npm install of " << packages << " failed: " << read_text(dir / "npm-install.log");
    return std::nullopt;
  }
  return dir / "node_modules";
}

std::string node_path() {
  FILE* p = popen("command -v node", "r");
  char buf[512] = {0};
  if (p) {
    if (!fgets(buf, sizeof buf, p)) buf[0] = 0;
    pclose(p);
  }
  std::string s(buf);
  while (!s.empty() && (s.back() == '\n' || s.back() == '\r')) s.pop_back();
  return s;
}

/// The JSON lines a running node script printed so far.
std::vector<json> json_lines(const fs::path& file) {
  std::vector<json> lines;
  std::istringstream in(read_text(file));
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    try {
      lines.push_back(json::parse(line));
    } catch (const json::exception&) {
      break;  // a line being written
    }
  }
  return lines;
}
std::optional<json> event(const fs::path& file, const std::string& name) {
  for (const auto& j : json_lines(file))
    if (j.value("event", "") == name || j.value("event", "") == "error") return j;
  return std::nullopt;
}
/// Waits (bounded) for an event line of a running script; fails with the script's output if not.
json wait_event(const fs::path& out, const fs::path& err, const std::string& name, double seconds) {
  const auto t0 = std::chrono::steady_clock::now();
  while (seconds_since(t0) < seconds) {
    if (auto e = event(out, name)) {
      EXPECT_NE(e->value("event", ""), "error") << e->dump(1) << read_text(err);
      return *e;
    }
    std::this_thread::sleep_for(100ms);
  }
  ADD_FAILURE() << "no '" << name << "' from the script within " << seconds << " s\n"
                << read_text(out) << read_text(err);
  return json();
}

/// odonav-ground serve on a free port: the port from its first line of output.
struct Serve {
  std::unique_ptr<ChildProcess> process;
  int port = 0;
};
Serve start_serve(int domain, const fs::path& dir, std::vector<std::string> extra) {
  Serve s;
  extra.insert(extra.begin(), {"--port", "0", "--bind", "127.0.0.1"});
  auto args = ground_args("serve", domain, extra);
  args.push_back("--log-level");
  args.push_back("info");
  s.process = std::make_unique<ChildProcess>(binary("odonav-ground"), args, dir / "serve.out", dir / "serve.err");
  const auto t0 = std::chrono::steady_clock::now();
  const std::regex port_re("http://127\\.0\\.0\\.1:([0-9]+)/");
  while (seconds_since(t0) < 20.0 && s.port == 0) {
    std::smatch m;
    const std::string text = read_text(dir / "serve.out");
    if (std::regex_search(text, m, port_re)) s.port = std::stoi(m[1]);
    std::this_thread::sleep_for(50ms);
  }
  EXPECT_GT(s.port, 0) << "serve printed no address: " << read_text(dir / "serve.err");
  return s;
}

class GroundWeb : public odonav::test::ShmCleanTest {};

}  // namespace

// ---- 1. a Foxglove client against one real vehicle ----

TEST_F(GroundWeb, FoxgloveClientReadsTheVehicleAsStandardRosMessages) {
  constexpr int kDomain = 180;
  constexpr double kHealthDeadlineS = 3.0;  // odonav_health_reader
  const fs::path dir = scratch_dir("web_foxglove");
  const auto modules = npm_web_modules();
  ASSERT_TRUE(modules.has_value());
  const std::string vehicle = "vehicle-01";

  // This test's own readers: the dead reckoning and K the pipeline publishes, by stamp.
  odonav::dds::Participant participant(participant_options(kDomain, "test-web-reference"));
  std::mutex mutex;
  std::map<long long, std::pair<double, double>> dr_by_stamp_us;   // stamp (us) -> lat, lon
  std::map<long long, std::pair<double, double>> nav_by_stamp_us;  // the anchored position
  std::map<long long, double> k_by_stamp_us;
  auto us = [](const std_msgs::msg::Header& h) { return std::llround(odonav::dds::to_seconds(h.stamp()) * 1e6); };
  // The vehicle's positions of a DeadReckoning or NavigationPosition message, into `by_stamp`.
  const auto positions_into = [&](std::map<long long, std::pair<double, double>>& by_stamp) {
    return [&](const auto& m) {
      if (m.vehicle_id() != vehicle) return;
      std::lock_guard<std::mutex> lock(mutex);
      by_stamp[us(m.header())] = {m.latitude_deg(), m.longitude_deg()};
    };
  };
  odonav::dds::Reader<msg::DeadReckoning> dr_reader(
      participant, topics::kDeadReckoning.name, topics::kGroundBestEffortReaderProfile, positions_into(dr_by_stamp_us));
  odonav::dds::Reader<msg::NavigationPosition> nav_reader(participant, topics::kNavigationPosition.name,
                                                          topics::kGroundBestEffortReaderProfile,
                                                          positions_into(nav_by_stamp_us));
  odonav::dds::Reader<msg::ScaleFactor> k_reader(participant, topics::kScaleFactor.name, topics::kEstimateReaderProfile,
                                                 [&](const msg::ScaleFactor& k) {
                                                   if (k.vehicle_id() != vehicle) return;
                                                   std::lock_guard<std::mutex> lock(mutex);
                                                   k_by_stamp_us[us(k.header())] = k.k_m_per_pulse();
                                                 });

  PipelineOptions o;
  o.speed = "2";
  VehiclePipeline pipeline(kDomain, vehicle, dir, o);
  pipeline.start_consumers();
  pipeline.start_gateway();
  // A small per-client queue, so the client that never reads overflows it within seconds.
  Serve serve = start_serve(kDomain, dir, {"--client-queue-kib", "64"});
  ASSERT_GT(serve.port, 0);

  setenv("NODE_PATH", modules->c_str(), 1);
  const fs::path out = dir / "ws_client.out", err = dir / "ws_client.err";
  ChildProcess client(node_path(),
                      {std::string(ODONAV_SOURCE_DIR) + "/tests/integration/ground/ws_client.js",
                       std::to_string(serve.port), vehicle, "6"},
                      out, err);
  ASSERT_TRUE(client.started());

  const json sub = wait_event(out, err, "subprotocols", 30);
  EXPECT_EQ(sub["v1"]["protocol"], "foxglove.websocket.v1") << sub.dump();
  EXPECT_EQ(sub["sdk"]["protocol"], "foxglove.sdk.v1") << sub.dump();
  EXPECT_EQ(sub["v1"]["name"], "odonav-ground");
  EXPECT_TRUE(sub["unknown"]["refused"].get<bool>()) << sub.dump();

  // The documented channels of the vehicle: every odonav topic with a sample (the command topic
  // only once a command was sent), and the derived standard ones.
  const json ch = wait_event(out, err, "channels", 90);
  const std::vector<std::string> documented{
      "odometer",       "ins/attitude",        "gnss/fix", "misalignment",      "scale_factor",
      "dead_reckoning", "navigation_position", "health",   "navsat/navigation", "navsat/dead_reckoning",
      "navsat/gnss",    "diagnostics",         "k"};
  std::set<std::string> topics_seen;
  for (const auto& t : ch["topics"]) topics_seen.insert(t.get<std::string>());
  for (const auto& t : documented) EXPECT_TRUE(topics_seen.count("/odonav/" + vehicle + "/" + t)) << t << ch.dump(1);
  for (const auto& c : ch["channels"]) {
    const std::string topic = c["topic"];
    if (topic.find("/navsat/") != std::string::npos) {
      EXPECT_EQ(c["schemaName"], "sensor_msgs/msg/NavSatFix") << topic;
    } else if (topic.size() > 12 && topic.substr(topic.size() - 12) == "/diagnostics") {
      EXPECT_EQ(c["schemaName"], "diagnostic_msgs/msg/DiagnosticArray");
    } else if (topic.substr(topic.size() - 2) == "/k") {
      EXPECT_EQ(c["encoding"], "json");
      EXPECT_EQ(c["schemaEncoding"], "jsonschema");
      continue;
    }
    EXPECT_EQ(c["encoding"], "cdr") << topic;
    EXPECT_EQ(c["schemaEncoding"], "ros2msg") << topic;
  }
  const json re = wait_event(out, err, "reconnect", 30);
  EXPECT_EQ(re["topics"], ch["topics"]) << "a reconnected client is advertised the same channels";

  const json samples = wait_event(out, err, "samples", 60);
  // NavSatFix against this test's own readers, same stamp: navigation = the GNSS-anchored
  // NavigationPosition, dead_reckoning = the pure DeadReckoning.
  {
    std::lock_guard<std::mutex> lock(mutex);
    for (const auto& [name, reference] : {std::make_pair("navsat/navigation", &nav_by_stamp_us),
                                          std::make_pair("navsat/dead_reckoning", &dr_by_stamp_us)}) {
      SCOPED_TRACE(name);
      const json& fixes = samples[name];
      ASSERT_GT(fixes.size(), 50u) << samples.dump().substr(0, 2000);
      std::size_t compared = 0;
      for (const auto& f : fixes) {
        const auto it = reference->find(std::llround(f["stamp"].get<double>() * 1e6));
        if (it == reference->end()) continue;
        ++compared;
        ASSERT_NEAR(f["lat"].get<double>(), it->second.first, 1e-9);
        ASSERT_NEAR(f["lon"].get<double>(), it->second.second, 1e-9);
        EXPECT_EQ(f["frame_id"], "wgs84");
        // The navigation position is NO_FIX (-1) only in the 0.2 s before its first fix applies.
        if (std::string(name) == "navsat/dead_reckoning")
          EXPECT_EQ(f["status"], 0);
        else
          EXPECT_GE(f["status"].get<int>(), -1);
      }
      EXPECT_GT(compared, fixes.size() * 8 / 10) << "stamps not found in the DDS reader's " << name;
    }
    ASSERT_GT(samples["navsat/gnss"].size(), 5u);
    // ScaleFactor's K: the pipeline's, sample for sample.
    std::size_t compared = 0;
    ASSERT_GT(samples["scale_factor"].size(), 3u);
    for (const auto& k : samples["scale_factor"]) {
      const auto it = k_by_stamp_us.find(std::llround(k["stamp"].get<double>() * 1e6));
      if (it == k_by_stamp_us.end()) continue;
      ++compared;
      EXPECT_EQ(k["k"].get<double>(), it->second);
    }
    EXPECT_GT(compared, 2u);
    ASSERT_GT(samples["k"].size(), 3u);
    EXPECT_EQ(samples["k"].back()["vehicle_id"], vehicle);
  }
  // DiagnosticArray: every component with its level.
  ASSERT_FALSE(samples["diagnostics"].empty());
  const json& diag = samples["diagnostics"].back();
  for (const auto& c : kVehicleComponents) {
    bool found = false;
    for (const auto& s : diag["status"]) {
      if (s["name"] != vehicle + "/" + c) continue;
      found = true;
      EXPECT_EQ(s["hardware_id"], vehicle);
      EXPECT_LE(s["level"].get<int>(), 1) << s.dump();
    }
    EXPECT_TRUE(found) << c << " missing in " << diag.dump(1);
  }

  // A client that never reads: the others still get every dead-reckoning sample, its frames are dropped.
  const json slow = wait_event(out, err, "slow", 60);
  const auto& stamps = slow["dr_stamps"];
  ASSERT_GT(stamps.size(), 100u) << "the reading client starved while another did not read";
  double max_gap_s = 0.0;
  for (std::size_t i = 1; i < stamps.size(); ++i)
    max_gap_s = std::max(max_gap_s, stamps[i].get<double>() - stamps[i - 1].get<double>());
  EXPECT_LT(max_gap_s, 0.5) << "dead-reckoning stamps (100 Hz) missed by the reading client";
  EXPECT_GT(slow["server"]["frames_dropped"].get<double>(), 0) << slow.dump();

  // SIGKILL the identification: STALE in the diagnostics within two Health deadline periods.
  wait_event(out, err, "watching", 30);
  pipeline.process("odonav-identification").signal(SIGKILL);
  const double killed_ms =
      std::chrono::duration<double, std::milli>(std::chrono::system_clock::now().time_since_epoch()).count();
  std::optional<double> stale_after_s;
  const auto t0 = std::chrono::steady_clock::now();
  while (!stale_after_s && seconds_since(t0) < 20.0) {
    std::this_thread::sleep_for(100ms);
    for (const auto& j : json_lines(out)) {
      if (j.value("event", "") != "diagnostics" || j["recv_ms"].get<double>() < killed_ms) continue;
      for (const auto& s : j["status"]) {
        if (s["name"] == vehicle + "/odonav-identification" && s["level"] == 3) {
          stale_after_s = (j["recv_ms"].get<double>() - killed_ms) / 1000.0;
          EXPECT_NE(s["message"].get<std::string>().find("STALE"), std::string::npos);
        }
        if (s["name"] == vehicle + "/odonav-gateway") {
          EXPECT_LE(s["level"].get<int>(), 1) << "only the killed one is STALE";
        }
      }
      if (stale_after_s) break;
    }
  }
  ASSERT_TRUE(stale_after_s.has_value()) << read_text(out).substr(0, 4000);
  std::cerr << "DiagnosticArray STALE " << *stale_after_s << " s after the SIGKILL (Health deadline "
            << kHealthDeadlineS << " s)\n";
  // 2 deadline periods, plus one diagnostics period (0.5 s).
  EXPECT_LE(*stale_after_s, 2 * kHealthDeadlineS + 0.5);

  client.signal(SIGTERM);
  client.wait_exit(5s);
  serve.process->signal(SIGINT);
  ASSERT_TRUE(serve.process->wait_exit(15s));
  EXPECT_EQ(serve.process->exit_code(), 0) << read_text(dir / "serve.err");
}

// ---- 2. the fleet page in a real browser, two vehicles ----

TEST_F(GroundWeb, FleetPageInChromiumWithTwoVehiclesCommandsAndStale) {
  constexpr int kDomain = 181;
  const fs::path dir = scratch_dir("web_page");
  ASSERT_TRUE(fs::exists("/usr/bin/chromium")) << "Debian's chromium is needed (scripts/install-deps installs it)";
  const auto modules = npm_web_modules();
  ASSERT_TRUE(modules.has_value());
  const ScenarioTruth truth = scenario_truth("terrain", 1, dir / "truth");
  const std::vector<std::string> vehicles{"vehicle-01", "vehicle-02"};
  const std::string token = "t0k3n-for-the-test";
  const double set_k = 1.01 * truth.k_m_per_pulse;

  std::vector<std::unique_ptr<VehiclePipeline>> fleet;
  for (const auto& id : vehicles) {
    PipelineOptions o;
    o.speed = "2";
    fleet.push_back(std::make_unique<VehiclePipeline>(kDomain, id, dir, o));
  }
  for (auto& v : fleet) v->start_consumers();
  for (auto& v : fleet) v->start_gateway();
  std::ofstream(dir / "token") << token << "\n";
  Serve serve = start_serve(kDomain, dir, {"--token-file", (dir / "token").string()});
  ASSERT_GT(serve.port, 0);

  setenv("NODE_PATH", modules->c_str(), 1);
  const fs::path out = dir / "page.out", err = dir / "page.err";
  char k_text[32];
  std::snprintf(k_text, sizeof k_text, "%.8f", set_k);
  const fs::path screenshot = dir / "fleet-page.png";
  ChildProcess page(node_path(),
                    {std::string(ODONAV_SOURCE_DIR) + "/tests/integration/ground/page_check.js",
                     std::to_string(serve.port), token, screenshot.string(), vehicles[0] + "," + vehicles[1], k_text},
                    out, err);
  ASSERT_TRUE(page.started());

  const json ready = wait_event(out, err, "ready", 150);
  ASSERT_TRUE(ready.contains("rows")) << ready.dump(1) << fleet[0]->logs_tail();
  EXPECT_TRUE(ready["outside_or_failed_requests"].empty()) << ready["outside_or_failed_requests"].dump();
  for (const auto& id : vehicles) {
    SCOPED_TRACE(id);
    const json& row = ready["rows"][id];
    const double k = std::stod(row["k"].get<std::string>());
    EXPECT_NEAR(k / truth.k_m_per_pulse, 1.0, 0.01) << row.dump();
    for (const auto& c : kVehicleComponents) EXPECT_EQ(row["components"][c], "OK") << c;
    EXPECT_FALSE(row["stale"].get<bool>());
  }

  const json refused = wait_event(out, err, "refused", 60);
  EXPECT_EQ(refused["log"]["outcome"], "REFUSED") << refused.dump();
  EXPECT_NE(refused["log"]["text"].get<std::string>().find("token"), std::string::npos) << refused.dump();
  const json set = wait_event(out, err, "set_k", 60);
  EXPECT_EQ(set["log"]["outcome"], "ACCEPTED") << set.dump();
  EXPECT_NE(set["dr_k"].get<std::string>().find(std::string(k_text).substr(0, 7)), std::string::npos) << set.dump();

  wait_event(out, err, "kill-now", 30);
  fleet[0]->process("odonav-identification").signal(SIGKILL);
  const json stale = wait_event(out, err, "stale", 60);
  ASSERT_TRUE(stale.contains("rows")) << stale.dump(1);
  std::cerr << "page: SIGKILLed identification STALE after " << stale["after_s"] << " s\n";
  EXPECT_TRUE(stale["rows"][vehicles[0]]["stale"].get<bool>());
  EXPECT_EQ(stale["rows"][vehicles[1]]["components"]["odonav-identification"], "OK") << "the other vehicle stays live";
  const json done = wait_event(out, err, "done", 30);
  EXPECT_TRUE(fs::exists(screenshot));
  EXPECT_GT(fs::file_size(screenshot), 10000u);
  std::cerr << "screenshot: " << screenshot << "\n";
  ASSERT_TRUE(page.wait_exit(30s));
  EXPECT_EQ(page.exit_code(), 0) << read_text(err);

  serve.process->signal(SIGINT);
  ASSERT_TRUE(serve.process->wait_exit(15s));
  EXPECT_EQ(serve.process->exit_code(), 0) << read_text(dir / "serve.err");
  // The commands of the page went through the existing command path, logged without the token.
  EXPECT_EQ(read_text(dir / "serve.err").find(token), std::string::npos);
}
