// odonav-ground monitor and command as processes on loopback DDS, against synthetic vehicles
// published from this test (domains 60 and 62).
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>

#include "shm_clean_test.hpp"
#include "ground_test_support.hpp"
#include "odonav/dds/component.hpp"
#include "odonav/dds/endpoints.hpp"
#include "odonav/dds/health.hpp"
#include "odonav/dds/time.hpp"
#include "odonav/msg/Command.h"
#include "odonav/msg/GnssFix.h"
#include "odonav/msg/Misalignment.h"
#include "odonav/msg/ScaleFactor.h"

using namespace odonav::test;
using odonav::dds::HealthPublisher;
using odonav::dds::Participant;
using odonav::dds::Reader;
using odonav::dds::Writer;

namespace {

const std::vector<std::string> kVehicles{"veh-alpha", "veh-bravo"};
const std::vector<std::string> kComponents{"odonav-gateway", "odonav-calibration", "odonav-identification"};

/// Per vehicle: a known K and misalignment (so the snapshot can be checked), and a component state.
double k_of(std::size_t v) { return 0.0125 + 0.0001 * static_cast<double>(v); }
double heading_of(std::size_t v) { return 0.01 * static_cast<double>(v + 1); }
msg::HealthLevel level_of(std::size_t c) { return c == 2 ? msg::HEALTH_LEVEL_WARN : msg::HEALTH_LEVEL_OK; }
std::string reason_of(std::size_t v, std::size_t c) {
  return c == 2 ? "no gnss for " + std::to_string(v + 3) + " s" : "";
}

/// Two vehicles, three components each: Health at 4 Hz, ScaleFactor, Misalignment and GnssFix at
/// 5 Hz, from a background thread, until stopped; one component's Health can be silenced.
class SyntheticFleet {
 public:
  explicit SyntheticFleet(int domain) : participant_(participant_options(domain, "synthetic-fleet")) {
    for (const auto& v : kVehicles)
      for (const auto& c : kComponents) health_[{v, c}] = std::make_unique<HealthPublisher>(participant_, v, c, 100.0);
    scale_factor_ = std::make_unique<Writer<msg::ScaleFactor>>(participant_, topics::kScaleFactor.name,
                                                               topics::kScaleFactor.writer_profile);
    misalignment_ = std::make_unique<Writer<msg::Misalignment>>(participant_, topics::kMisalignment.name,
                                                                topics::kMisalignment.writer_profile);
    gnss_ =
        std::make_unique<Writer<msg::GnssFix>>(participant_, topics::kGnssFix.name, topics::kGnssFix.writer_profile);
    thread_ = std::thread([this] { loop(); });
  }
  ~SyntheticFleet() {
    stop_ = true;
    thread_.join();
  }
  /// Stops publishing one component's Health (its writer stays: a silent, not a dead, producer).
  void silence(const std::string& vehicle, const std::string& component) {
    std::lock_guard<std::mutex> lock(mutex_);
    silenced_ = {vehicle, component};
  }

 private:
  void loop() {
    int tick = 0;
    while (!stop_) {
      const double now = odonav::dds::unix_now_s();
      for (std::size_t v = 0; v < kVehicles.size(); ++v) {
        for (std::size_t c = 0; c < kComponents.size(); ++c) {
          {
            std::lock_guard<std::mutex> lock(mutex_);
            if (silenced_ && silenced_->first == kVehicles[v] && silenced_->second == kComponents[c]) continue;
          }
          health_[{kVehicles[v], kComponents[c]}]->publish_now(now, msg::HEALTH_STATE_RUNNING, level_of(c),
                                                               reason_of(v, c), {{"tick", tick}});
        }
        if (tick % 4 == 0) continue;  // estimates at ~3 Hz: inside their 1 s deadline
        msg::ScaleFactor k;
        k.header(odonav::dds::make_header(100.0 + tick, "odometer"));
        k.vehicle_id(kVehicles[v]);
        k.k_m_per_pulse(k_of(v));
        k.sigma_m_per_pulse(2e-6);
        k.forgetting_factor(0.985);
        k.window_fill(1.0);
        k.estimator("vff_lm_rls");
        k.converged(true);
        scale_factor_->write(k);
        msg::Misalignment m;
        m.header(odonav::dds::make_header(100.0 + tick, "body"));
        m.vehicle_id(kVehicles[v]);
        m.heading_rad(heading_of(v));
        m.pitch_rad(-0.005);
        m.heading_std_rad(1e-4);
        m.pitch_std_rad(-1.0);
        m.converged(true);
        m.state(msg::MISALIGNMENT_CONVERGED);
        misalignment_->write(m);
        msg::GnssFix g;
        g.header(odonav::dds::make_header(100.0 + tick, "wgs84"));
        g.vehicle_id(kVehicles[v]);
        g.velocity_east_mps(3.0);
        g.velocity_north_mps(4.0);
        g.fix_quality(4);
        g.valid(true);
        gnss_->write(g);
      }
      ++tick;
      std::this_thread::sleep_for(250ms);
    }
  }

  Participant participant_;
  std::map<std::pair<std::string, std::string>, std::unique_ptr<HealthPublisher>> health_;
  std::unique_ptr<Writer<msg::ScaleFactor>> scale_factor_;
  std::unique_ptr<Writer<msg::Misalignment>> misalignment_;
  std::unique_ptr<Writer<msg::GnssFix>> gnss_;
  std::mutex mutex_;
  std::optional<std::pair<std::string, std::string>> silenced_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

class GroundProcesses : public odonav::test::ShmCleanTest {};

}  // namespace

TEST_F(GroundProcesses, MonitorOnceJsonListsEveryVehicleAndComponentHealth) {
  constexpr int kDomain = 60;
  const auto dir = scratch_dir("monitor_once");
  SyntheticFleet fleet(kDomain);
  const RunResult r = run(binary("odonav-ground"),
                          ground_args("monitor", kDomain, {"--once", "--json", "--settle-s", "3"}), dir, "monitor");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);  // exactly one JSON document on stdout
  ASSERT_EQ(j.at("vehicles").size(), kVehicles.size()) << r.out;
  for (std::size_t v = 0; v < kVehicles.size(); ++v) {
    SCOPED_TRACE(kVehicles[v]);
    const nlohmann::json* jv = find_by(j["vehicles"], "vehicle_id", kVehicles[v]);
    ASSERT_NE(jv, nullptr);
    ASSERT_EQ(jv->at("components").size(), kComponents.size());
    for (std::size_t c = 0; c < kComponents.size(); ++c) {
      const nlohmann::json* jc = find_by(jv->at("components"), "component", kComponents[c]);
      ASSERT_NE(jc, nullptr) << kComponents[c];
      EXPECT_EQ(jc->at("state"), "RUNNING");
      EXPECT_EQ(jc->at("level"), c == 2 ? "WARN" : "OK");
      EXPECT_EQ(jc->at("reason"), reason_of(v, c));
      EXPECT_FALSE(jc->at("stale").get<bool>());
      EXPECT_TRUE(jc->at("counters").contains("tick"));
    }
    EXPECT_FALSE(jv->at("stale").get<bool>());
    EXPECT_EQ(jv->at("scale_factor").at("k_m_per_pulse").get<double>(), k_of(v));
    EXPECT_EQ(jv->at("scale_factor").at("estimator"), "vff_lm_rls");
    EXPECT_EQ(jv->at("scale_factor").at("forgetting_factor").get<double>(), 0.985);
    EXPECT_NEAR(jv->at("misalignment").at("heading_deg").get<double>(), heading_of(v) * 180.0 / M_PI, 1e-12);
    EXPECT_TRUE(jv->at("misalignment").at("pitch_std_deg").is_null());  // -1 on the wire = unknown
    EXPECT_EQ(jv->at("gnss").at("speed_mps").get<double>(), 5.0);       // |(3, 4)|
    EXPECT_EQ(jv->at("gnss").at("fix"), "rtk-fixed");
    // Health at 4 Hz per component, three components: about 12 Hz over the 2 s window.
    EXPECT_GT(jv->at("rates_hz").at("health").get<double>(), 6.0);
    EXPECT_LT(jv->at("rates_hz").at("health").get<double>(), 20.0);
  }
}

TEST_F(GroundProcesses, SilentComponentTurnsStaleWithinTwoDeadlinePeriods) {
  constexpr int kDomain = 61;
  constexpr double kHealthDeadlineS = 3.0;  // odonav_health_reader in qos.xml
  const auto dir = scratch_dir("monitor_stale");
  SyntheticFleet fleet(kDomain);
  ChildProcess monitor(binary("odonav-ground"), ground_args("monitor", kDomain, {"--json", "--refresh-s", "0.2"}),
                       dir / "monitor.out", dir / "monitor.err");
  ASSERT_TRUE(monitor.started());

  // The last complete JSON line printed so far.
  auto latest = [&] { return last_json_line(dir / "monitor.out"); };
  const auto component = snapshot_component;
  // Wait until every component of both vehicles is seen live.
  const auto seen_deadline = std::chrono::steady_clock::now() + 20s;
  bool all_live = false;
  while (!all_live && std::chrono::steady_clock::now() < seen_deadline) {
    std::this_thread::sleep_for(200ms);
    const auto snap = latest();
    if (!snap) continue;
    all_live = true;
    for (const auto& v : kVehicles)
      for (const auto& c : kComponents) {
        const nlohmann::json* jc = component(*snap, v, c);
        all_live = all_live && jc && !jc->at("stale").get<bool>();
      }
  }
  ASSERT_TRUE(all_live) << "monitor never showed every component live; stderr: " << monitor.err();

  fleet.silence("veh-bravo", "odonav-calibration");
  const auto silenced_at = std::chrono::steady_clock::now();
  std::optional<double> stale_after_s;
  while (!stale_after_s && std::chrono::steady_clock::now() - silenced_at < 15s) {
    std::this_thread::sleep_for(100ms);
    const auto snap = latest();
    const nlohmann::json* jc = snap ? component(*snap, "veh-bravo", "odonav-calibration") : nullptr;
    if (jc && jc->at("stale").get<bool>()) {
      stale_after_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - silenced_at).count();
      // Only the silent one: its siblings and the other vehicle stay live.
      for (const auto& v : kVehicles)
        for (const auto& c : kComponents) {
          if (v == "veh-bravo" && c == "odonav-calibration") continue;
          EXPECT_FALSE(component(*snap, v, c)->at("stale").get<bool>()) << v << " " << c;
        }
      EXPECT_TRUE(find_by(snap->at("vehicles"), "vehicle_id", "veh-bravo")->at("stale").get<bool>());
      EXPECT_FALSE(find_by(snap->at("vehicles"), "vehicle_id", "veh-alpha")->at("stale").get<bool>());
    }
  }
  ASSERT_TRUE(stale_after_s.has_value()) << "never STALE";
  // The spec: STALE within 2 deadline periods (plus one refresh of the display).
  EXPECT_LE(*stale_after_s, 2 * kHealthDeadlineS + 0.2) << "STALE after " << *stale_after_s << " s";

  monitor.signal(SIGINT);
  ASSERT_TRUE(monitor.wait_exit(10s));
  EXPECT_EQ(monitor.exit_code(), 0);
  // A pipe gets no escape codes.
  EXPECT_EQ(read_text(dir / "monitor.out").find('\x1b'), std::string::npos);
}

TEST_F(GroundProcesses, MonitorPlainTextFitsEightyByTwentyFour) {
  constexpr int kDomain = 63;
  const auto dir = scratch_dir("monitor_text");
  SyntheticFleet fleet(kDomain);
  const RunResult r =
      run(binary("odonav-ground"), ground_args("monitor", kDomain, {"--once", "--settle-s", "2"}), dir, "text");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::istringstream lines(r.out);
  std::string line;
  int n = 0;
  while (std::getline(lines, line)) {
    ++n;
    EXPECT_LE(line.size(), 80u) << line;
  }
  EXPECT_LE(n, 24);
  EXPECT_NE(r.out.find("veh-alpha"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("0.0125000"), std::string::npos) << r.out;  // veh-alpha's K
  EXPECT_EQ(r.out.find('\x1b'), std::string::npos);
}

// ---- command ----

namespace {

/// A fake component: acknowledges set-k with a positive value (and remembers it), rejects
/// everything else, in its Health, as ComponentRuntime does.
class FakeComponent {
 public:
  FakeComponent(int domain, std::string vehicle, std::string component)
      : participant_(participant_options(domain, "fake-component")),
        vehicle_(std::move(vehicle)),
        component_(std::move(component)),
        health_(participant_, vehicle_, component_, 100.0) {
    commands_ =
        std::make_unique<Reader<msg::Command>>(participant_, topics::kCommand.name, topics::kCommand.reader_profile,
                                               [this](const msg::Command& c) { on_command(c); });
    thread_ = std::thread([this] {
      while (!stop_) {
        publish();
        std::this_thread::sleep_for(500ms);
      }
    });
  }
  ~FakeComponent() {
    stop_ = true;
    thread_.join();
    commands_.reset();
  }
  std::optional<double> commanded_k() {
    std::lock_guard<std::mutex> lock(mutex_);
    return k_;
  }

 private:
  void publish() {
    std::lock_guard<std::mutex> lock(mutex_);
    health_.publish_now(odonav::dds::unix_now_s(), msg::HEALTH_STATE_RUNNING, msg::HEALTH_LEVEL_OK, "");
  }
  void on_command(const msg::Command& c) {
    if (c.vehicle_id() != vehicle_ || c.target_component() != component_) return;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (c.command() == msg::COMMAND_SET_K && c.value() > 0.0) {
        k_ = c.value();
        health_.acknowledge(c.command_id(), msg::COMMAND_RESULT_ACCEPTED, "K set");
      } else {
        health_.acknowledge(c.command_id(), msg::COMMAND_RESULT_REJECTED, "only set-k is supported here");
      }
    }
    publish();
  }

  Participant participant_;
  std::string vehicle_, component_;
  std::mutex mutex_;
  HealthPublisher health_;
  std::optional<double> k_;
  std::unique_ptr<Reader<msg::Command>> commands_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace

TEST_F(GroundProcesses, CommandIsAcknowledgedRejectedOrTimesOut) {
  constexpr int kDomain = 62;
  const auto dir = scratch_dir("command");
  FakeComponent fake(kDomain, "veh-cmd", "odonav-fake");
  FakeComponent other(kDomain, "veh-other", "odonav-fake");  // same component name, other vehicle
  // `odonav-ground command` to the fake component of veh-cmd, output under `name` in dir.
  const auto command = [&](const std::vector<std::string>& what, const std::string& name) {
    std::vector<std::string> args{"--vehicle", "veh-cmd", "--component"};
    args.insert(args.end(), what.begin(), what.end());
    return run(binary("odonav-ground"), ground_args("command", kDomain, args), dir, name);
  };

  const RunResult ok = command({"odonav-fake", "set-k", "0.0127125", "--timeout-s", "15"}, "set_k");
  EXPECT_EQ(ok.exit_code, 0) << ok.out << ok.err;
  EXPECT_NE(ok.out.find("ACCEPTED: K set"), std::string::npos) << ok.out;
  ASSERT_TRUE(fake.commanded_k().has_value());
  EXPECT_EQ(*fake.commanded_k(), 0.0127125);      // the value crossed the wire exactly
  EXPECT_FALSE(other.commanded_k().has_value());  // addressed to one vehicle only

  const RunResult rejected = command({"odonav-fake", "freeze", "--timeout-s", "15"}, "freeze");
  EXPECT_EQ(rejected.exit_code, 1) << rejected.out << rejected.err;
  EXPECT_NE(rejected.out.find("REJECTED: only set-k is supported here"), std::string::npos) << rejected.out;

  const RunResult timeout = command({"odonav-nobody", "reset", "--timeout-s", "2"}, "timeout");
  EXPECT_EQ(timeout.exit_code, 3) << timeout.out << timeout.err;
  EXPECT_NE(timeout.out.find("TIMEOUT"), std::string::npos) << timeout.out;
  EXPECT_NE(timeout.out.find("odonav-nobody"), std::string::npos) << timeout.out;

  const RunResult bad = command({"odonav-fake", "set-k", "fast"}, "bad");
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("'fast'"), std::string::npos) << bad.err;

  // The former name of wire value 0 is refused before anything is sent, naming the new ones.
  const RunResult old_name = command({"odonav-fake", "reset-calibration"}, "old_name");
  EXPECT_EQ(old_name.exit_code, 2) << old_name.out << old_name.err;
  EXPECT_NE(old_name.err.find("'reset-calibration' is no longer a command: use 'reset'"), std::string::npos)
      << old_name.err;
  EXPECT_NE(old_name.err.find("'release-k'"), std::string::npos) << old_name.err;

  // Subcommands take their own flags only: one before the subcommand's name (as a flat option list
  // took it) or of another subcommand is refused, naming the subcommand it belongs to.
  const RunResult before = run(binary("odonav-ground"), ground_args("--once", kDomain, {"monitor"}), dir, "before");
  EXPECT_EQ(before.exit_code, 2) << before.out << before.err;
  EXPECT_NE(before.err.find("--once is an option of 'odonav-ground monitor': write odonav-ground monitor ... --once"),
            std::string::npos)
      << before.err;
  const RunResult elsewhere =
      run(binary("odonav-ground"), ground_args("monitor", kDomain, {"--port", "80"}), dir, "elsewhere");
  EXPECT_EQ(elsewhere.exit_code, 2) << elsewhere.out << elsewhere.err;
  EXPECT_NE(elsewhere.err.find("--port is an option of 'odonav-ground serve', not of 'odonav-ground monitor'"),
            std::string::npos)
      << elsewhere.err;
  const RunResult none = run(binary("odonav-ground"), ground_args("--log-level=warn", kDomain), dir, "none");
  EXPECT_EQ(none.exit_code, 2) << none.out << none.err;
  EXPECT_NE(none.err.find("missing the subcommand: monitor, serve, record, command"), std::string::npos) << none.err;
}
