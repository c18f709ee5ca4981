// The pipeline across hosts, as on a vehicle (deploy/README.md): three ECUs and a ground station as
// Linux network namespaces
// joined by a bridge (virtual_network.hpp), each component a process on its host, DDS over the
// bridge with the vehicle profile (deploy/profiles/vehicle.xml with the host's address), SHM only
// within a host. Needs root (CI runs as root); domains 130-139.
//
//   ecu1 10.0.0.11  odonav-gateway (sim:terrain, real-time pace)
//   ecu2 10.0.0.12  odonav-calibration, odonav-identification
//   ecu3 10.0.0.13  odonav-dead-reckoning
//   gs   10.0.0.50  odonav-recorder (writes the outputs), odonav-ground monitor --json (live),
//                   odonav-multihost-rogue (listener / intruders)
//
// 1. Plain: accuracy as in tests/integration/pipeline (final K within 0.5 % of the truth, final
//    DR error below 0.5 % of the distance); ECU2's link cut for 5 s and restored: DR publishes an
//    output for every odometer sample throughout (no gap over 2 periods) on the last identified K,
//    identification's scale factor reaches DR again afterwards, and the health view shows the
//    outage (the ground sees the scale factor STALE, DR reports "no identification") and its end.
//    A passive listener on the ground host receives the vehicle's topics (control for 2.).
// 2. Secure (deploy/profiles/secure.xml, UDP only, + a PKI made by deploy/security/make-pki): the
//    same pipeline works across hosts and every pair of the six vehicle/ground participants
//    authenticated (each one's log; deploy/README.md "DDS Security and Fast DDS 2.9" for the race
//    that used to lose a pair about 1 run in 3); a participant without credentials and one with
//    a certificate from another CA, on the ground host, receive nothing and their fake scale
//    factor never reaches DR; a component whose permissions do not grant a topic cannot create
//    that writer.
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "../nodes/node_test_support.hpp"
#include "odonav/dataset.hpp"
#include "odonav/geodesy.hpp"
#include "odonav/results/output_files.hpp"
#include "virtual_network.hpp"

namespace {

using namespace std::chrono_literals;
using odonav::multihost::Host;
using odonav::multihost::VirtualNetwork;
using odonav::multihost::instantiate_profile;
using odonav::test::ChildProcess;
using odonav::test::read_text;
using odonav::test::tail_of;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

const fs::path kSource = ODONAV_SOURCE_DIR;
const fs::path kBin = fs::path(ODONAV_BINARY_DIR) / "bin";
constexpr const char* kVehicle = "test-vehicle";
constexpr int kSeed = 1;

/// The last line of a file that is a JSON document (Fast DDS may log to stdout before it).
nlohmann::json last_json_line(const fs::path& path) {
  std::istringstream in(read_text(path));
  nlohmann::json last = nlohmann::json::value_t::discarded;
  for (std::string l; std::getline(in, l);)
    if (!l.empty() && l[0] == '{') last = nlohmann::json::parse(l, nullptr, false);
  return last;
}

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

/// The live monitor's JSON lines (one snapshot per refresh), each stamped with the test's clock
/// when it was read (polled every 100 ms, so the stamp is at most ~0.1 s late).
struct Snapshot {
  double read_s = 0.0;     // seconds since the rig started
  nlohmann::json vehicle;  // the test vehicle's entry (null if absent)

  const nlohmann::json* component(const std::string& name) const {
    if (vehicle.is_null()) return nullptr;
    for (const auto& c : vehicle.at("components"))
      if (c.at("component") == name) return &c;
    return nullptr;
  }
  std::optional<double> dr_stamp_s() const {
    if (vehicle.is_null() || vehicle.at("dead_reckoning").is_null()) return std::nullopt;
    return vehicle.at("dead_reckoning").at("t").get<double>();
  }
  std::string dr_k_source() const {
    if (vehicle.is_null() || vehicle.at("dead_reckoning").is_null()) return "";
    return vehicle.at("dead_reckoning").at("k_source").get<std::string>();
  }
  bool scale_factor_stale() const {
    return !vehicle.is_null() && !vehicle.at("scale_factor").is_null() &&
           vehicle.at("scale_factor").at("stale").get<bool>();
  }
  std::string reason_of(const std::string& name) const {
    const auto* c = component(name);
    return c == nullptr ? "" : c->at("reason").get<std::string>();
  }
  double counter_of(const std::string& name, const std::string& counter) const {
    const auto* c = component(name);
    if (c == nullptr || !c->at("counters").contains(counter)) return std::nan("");
    return c->at("counters").at(counter).get<double>();
  }
};

/// The processes of one run on the virtual network, with their logs in dir/logs.
class Rig {
 public:
  Rig(const fs::path& dir, VirtualNetwork& net) : dir_(dir), net_(net), t0_(Clock::now()) {
    fs::create_directories(dir_ / "logs");
  }
  ~Rig() { stop_all(); }

  /// Starts `binary` on `host` as `name` (logs/<name>.out, .log); `env` as VAR=value.
  ChildProcess& start(const std::string& name, const std::string& host, const std::string& binary,
                      const std::vector<std::string>& args, const std::vector<std::string>& env = {}) {
    std::vector<std::string> command{"/usr/bin/env"};
    command.insert(command.end(), env.begin(), env.end());
    command.push_back((kBin / binary).string());
    command.insert(command.end(), args.begin(), args.end());
    const auto argv = net_.exec_argv(host, out_file(name), log_file(name), command);
    auto child = std::make_unique<ChildProcess>(argv[0], std::vector<std::string>(argv.begin() + 1, argv.end()));
    if (!child->started()) throw std::runtime_error("cannot start " + name);
    order_.push_back(name);
    children_[name] = std::move(child);
    return *children_[name];
  }
  ChildProcess& child(const std::string& name) { return *children_.at(name); }
  /// A process that was meant to exit (already waited for): no longer watched.
  void forget(const std::string& name) {
    children_.erase(name);
    order_.erase(std::remove(order_.begin(), order_.end(), name), order_.end());
  }
  fs::path log_file(const std::string& name) const { return dir_ / "logs" / (name + ".log"); }
  fs::path out_file(const std::string& name) const { return dir_ / "logs" / (name + ".out"); }
  std::string log_tail(const std::string& name) const {
    return name + " (" + log_file(name).string() + "):\n" + tail_of(log_file(name), 25) + tail_of(out_file(name), 5);
  }
  double now_s() const { return seconds_since(t0_); }

  /// SIGINT and a bounded wait; returns the exit code, or -1 on timeout (then SIGKILL).
  int stop(const std::string& name, std::chrono::seconds timeout) {
    ChildProcess& c = child(name);
    c.signal(SIGINT);
    if (!c.wait_exit(timeout)) {
      c.signal(SIGKILL);
      c.wait_exit(5s);
      return -1;
    }
    return c.exit_code();
  }
  /// Every process still running: SIGTERM, then SIGKILL (reverse start order).
  void stop_all() {
    for (auto it = order_.rbegin(); it != order_.rend(); ++it) children_.at(*it)->signal(SIGTERM);
    for (auto it = order_.rbegin(); it != order_.rend(); ++it)
      if (!children_.at(*it)->wait_exit(5s)) children_.at(*it)->signal(SIGKILL);
    children_.clear();
    order_.clear();
  }

  /// Waits until `text` appears in the log of `name`; false on timeout or if any process died.
  bool wait_for_log(const std::string& name, const std::string& text, std::chrono::seconds timeout, std::string& why) {
    const auto end = Clock::now() + timeout;
    while (Clock::now() < end) {
      if (read_text(log_file(name)).find(text) != std::string::npos) return true;
      for (const auto& n : order_)
        if (!children_.at(n)->running()) {
          why = n + " exited early (status " + std::to_string(children_.at(n)->exit_code()) + ")\n" + log_tail(n);
          return false;
        }
      std::this_thread::sleep_for(200ms);
    }
    why = "'" + text + "' not in the log of " + name + " within " + std::to_string(timeout.count()) + " s\n" +
          log_tail(name);
    return false;
  }

  /// Reads the monitor's new JSON lines.
  void poll_monitor(const std::string& name) {
    std::ifstream in(out_file(name));
    in.seekg(static_cast<std::streamoff>(monitor_offset_));
    std::string line;
    while (std::getline(in, line)) {
      if (in.eof()) break;  // an incomplete last line: read it next time
      monitor_offset_ += line.size() + 1;
      if (line.empty() || line[0] != '{') continue;
      Snapshot s;
      s.read_s = now_s();
      const auto j = nlohmann::json::parse(line, nullptr, false);
      if (j.is_discarded()) continue;
      for (const auto& v : j.at("vehicles"))
        if (v.at("vehicle_id") == kVehicle) s.vehicle = v;
      snapshots_.push_back(std::move(s));
    }
  }
  const std::vector<Snapshot>& snapshots() const { return snapshots_; }
  /// Polls the monitor every 100 ms until pred(last snapshot) holds; false on timeout.
  bool wait_snapshot(const std::string& monitor, const std::function<bool(const Snapshot&)>& pred, double timeout_s) {
    const double end = now_s() + timeout_s;
    while (now_s() < end) {
      poll_monitor(monitor);
      if (!snapshots_.empty() && pred(snapshots_.back())) return true;
      std::this_thread::sleep_for(100ms);
    }
    return false;
  }
  void sleep_polling(const std::string& monitor, double seconds) {
    const double end = now_s() + seconds;
    while (now_s() < end) {
      poll_monitor(monitor);
      std::this_thread::sleep_for(100ms);
    }
  }

 private:
  fs::path dir_;
  VirtualNetwork& net_;
  Clock::time_point t0_;
  std::vector<std::string> order_;
  std::map<std::string, std::unique_ptr<ChildProcess>> children_;
  std::size_t monitor_offset_ = 0;
  std::vector<Snapshot> snapshots_;
};

/// The recorder on the ground host writing to `out`; `common`: its domain, profile and vehicle flags.
void start_recorder(Rig& rig, std::vector<std::string> common, const fs::path& out) {
  common.insert(common.end(), {"--out", out.string()});
  rig.start("odonav-recorder", "gs", "odonav-recorder", common);
}

/// The gateway on ECU1: the simulated terrain drive (kSeed, `duration_s`) at real time, once the
/// four consumers matched; `common`: its domain, profile and vehicle flags.
void start_gateway(Rig& rig, std::vector<std::string> common, double duration_s) {
  common.insert(common.end(), {"--source", "sim:terrain", "--seed", std::to_string(kSeed), "--duration-s",
                               std::to_string(duration_s), "--speed", "1", "--wait-for-readers", "4"});
  rig.start("odonav-gateway", "ecu1", "odonav-gateway", common);
}

/// The simulated drive the gateway publishes (same scenario, seed and duration), for the truth and
/// the installation values the components take as flags (as deploy/launch does).
struct Drive {
  odonav::Dataset data;
  double k_true_m_per_pulse = 0.0;
  std::vector<std::string> install_flags;  // --lever-arm, --nominal-k
};

Drive simulate_drive(const fs::path& dir, double duration_s) {
  const fs::path out = dir / "dataset";
  const std::string cmd = (kBin / "odonav-simulator").string() + " terrain --seed " + std::to_string(kSeed) +
                          " --duration-s " + std::to_string(duration_s) + " --out " + out.string() + " >" +
                          (dir / "sim.log").string() + " 2>&1";
  if (std::system(cmd.c_str()) != 0) throw std::runtime_error("odonav-simulator failed: " + read_text(dir / "sim.log"));
  Drive d;
  d.data = odonav::read_dataset(out.string(), odonav::BadRowPolicy::kFail);
  const auto meta = nlohmann::json::parse(d.data.meta.raw_json);
  d.k_true_m_per_pulse = meta.at("simulation").at("k_true_initial_m_per_pulse").get<double>();
  for (const auto& step : meta.at("simulation").at("k_steps"))
    if (step.at("t_s").get<double>() <= d.data.odometer.back().t_s)
      throw std::runtime_error("a K step inside the drive: the final-K check assumes a constant K");
  if (d.data.meta.gnss_lever_arm_m) {
    std::ostringstream arm;
    arm.precision(17);
    const auto& a = *d.data.meta.gnss_lever_arm_m;
    arm << a.x() << "," << a.y() << "," << a.z();
    d.install_flags = {"--lever-arm", arm.str()};
  }
  if (d.data.meta.k_nominal_m_per_pulse) {
    std::ostringstream k;
    k.precision(17);
    k << *d.data.meta.k_nominal_m_per_pulse;
    d.install_flags.insert(d.install_flags.end(), {"--nominal-k", k.str()});
  }
  return d;
}

const odonav::TruthSample& truth_at(const odonav::Dataset& d, double t_s) {
  auto it = std::lower_bound(d.truth.begin(), d.truth.end(), t_s,
                             [](const odonav::TruthSample& s, double t) { return s.t_s < t; });
  if (it == d.truth.end()) return d.truth.back();
  if (it != d.truth.begin() && std::abs((it - 1)->t_s - t_s) < std::abs(it->t_s - t_s)) --it;
  return *it;
}

/// Final accuracy as in tests/integration/pipeline: last K within 0.5 % of the truth, last DR
/// position within 0.5 % of the distance travelled. Returns {K error %, DR %D}.
std::pair<double, double> check_final_accuracy(const Drive& drive, const odonav::results::OutputRows& rows) {
  EXPECT_FALSE(rows.scale_factor.empty());
  EXPECT_FALSE(rows.dead_reckoning.empty());
  if (rows.scale_factor.empty() || rows.dead_reckoning.empty()) return {NAN, NAN};
  const auto& k_last = rows.scale_factor.back();
  EXPECT_TRUE(k_last.converged);
  EXPECT_TRUE(k_last.k_m_per_pulse.has_value());
  const double k_error = 100.0 * std::abs(k_last.k_m_per_pulse.value_or(0.0) / drive.k_true_m_per_pulse - 1.0);
  EXPECT_LT(k_error, 0.5) << "final K " << k_last.k_m_per_pulse.value_or(0.0) << " vs true "
                          << drive.k_true_m_per_pulse;
  const auto& first = rows.dead_reckoning.front();
  const auto& last = rows.dead_reckoning.back();
  EXPECT_EQ(last.k_source, "identified");
  const odonav::TruthSample& t_last = truth_at(drive.data, last.t_s);
  EXPECT_NEAR(t_last.t_s, last.t_s, 1e-6);
  const double travelled = t_last.distance_m - truth_at(drive.data, first.t_s).distance_m;
  EXPECT_GT(travelled, 300.0);
  const double error_m =
      odonav::horizontal_distance_m(odonav::Geodetic{last.lat_rad, last.lon_rad, last.height_m}, t_last.position);
  const double percent = 100.0 * error_m / travelled;
  EXPECT_LT(percent, 0.5) << error_m << " m over " << travelled << " m";
  std::cerr << "final K error " << k_error << " %, DR final error " << error_m << " m over " << travelled
            << " m = " << percent << " %D\n";
  return {k_error, percent};
}

/// The largest step between consecutive DR output stamps, and the odometer period (median step).
std::pair<double, double> dr_largest_gap(const std::vector<odonav::results::DeadReckoningRow>& dr,
                                         const odonav::Dataset& data) {
  std::vector<double> steps;
  for (std::size_t i = 1; i < data.odometer.size(); ++i)
    steps.push_back(data.odometer[i].t_s - data.odometer[i - 1].t_s);
  std::nth_element(steps.begin(), steps.begin() + steps.size() / 2, steps.end());
  const double period = steps[steps.size() / 2];
  double gap = 0.0;
  for (std::size_t i = 1; i < dr.size(); ++i) gap = std::max(gap, dr[i].t_s - dr[i - 1].t_s);
  return {gap, period};
}

class MultiHost : public ::testing::Test {
 protected:
  void SetUp() override {
    // CI runs as root; a silent skip would hide that this test never ran.
    ASSERT_EQ(::geteuid(), 0u) << "the multi-host test needs root (it creates network namespaces with ip netns); "
                                  "run it as root (CI does)";
    ASSERT_EQ(std::system("ip netns list >/dev/null 2>&1"), 0) << "'ip netns' is not available (iproute2)";
    odonav::multihost::remove_stale_namespaces();
    odonav::test::shm_clean();
  }
  void TearDown() override { odonav::test::shm_clean(); }

  static fs::path fresh_dir(const std::string& name) {
    const fs::path dir = fs::path(ODONAV_BINARY_DIR) / "test-multihost" / name;
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir;
  }

  static std::vector<Host> hosts() {
    return {{"ecu1", "10.0.0.11"}, {"ecu2", "10.0.0.12"}, {"ecu3", "10.0.0.13"}, {"gs", "10.0.0.50"}};
  }
};

// ---- 1. plain: accuracy, link cut, health ---------------------------------------------------------

TEST_F(MultiHost, PipelineAcrossHostsSurvivesAFiveSecondLinkCutOfEcu2) {
  constexpr int kDomain = 130;
  constexpr double kDuration_s = 80.0;  // terrain: standstill, the long straight, into the turn
  constexpr double kCutAfter_s = 30.0;  // data time of the cut: K converged well before
  constexpr double kCut_s = 5.0;
  const fs::path dir = fresh_dir("plain");
  const Drive drive = simulate_drive(dir, kDuration_s);
  const double t_first = drive.data.odometer.front().t_s;

  VirtualNetwork net(dir / "net", hosts());
  std::map<std::string, fs::path> profile;
  for (const auto& h : hosts())
    profile[h.name] =
        instantiate_profile(kSource / "deploy/profiles/vehicle.xml", dir / "profiles" / h.name, h.address);
  const auto common = [&](const std::string& host) {
    return std::vector<std::string>{
        "--domain", std::to_string(kDomain), "--profile", profile[host].string(), "--profile-name",
        "vehicle",  "--vehicle-id",          kVehicle};
  };
  const auto node = [&](const std::string& host) {
    auto a = common(host);
    a.insert(a.end(), {"--max-wait-s", "2"});  // real-time pace: 2 s of silence is an absent input
    a.insert(a.end(), drive.install_flags.begin(), drive.install_flags.end());
    return a;
  };

  Rig rig(dir, net);
  start_recorder(rig, common("gs"), dir / "out");
  rig.start("monitor", "gs", "odonav-ground",
            {"monitor", "--json", "--refresh-s", "0.5", "--domain", std::to_string(kDomain), "--profile",
             profile["gs"].string(), "--profile-name", "vehicle", "--vehicle", kVehicle});
  rig.start("listener", "gs", "odonav-multihost-rogue",
            {"--domain", std::to_string(kDomain), "--profile", profile["gs"].string(), "--profile-name", "vehicle",
             "--listen-only", "--duration-s", "600"});
  rig.start("odonav-dead-reckoning", "ecu3", "odonav-dead-reckoning", node("ecu3"));
  rig.start("odonav-identification", "ecu2", "odonav-identification", node("ecu2"));
  rig.start("odonav-calibration", "ecu2", "odonav-calibration", [&] {
    auto a = node("ecu2");
    // calibration takes the lever arm but not the nominal K
    for (auto it = a.begin(); it != a.end(); ++it)
      if (*it == "--nominal-k") {
        a.erase(it, it + 2);
        break;
      }
    return a;
  }());
  std::string why;
  ASSERT_TRUE(rig.wait_for_log("odonav-recorder", "every producer matched", 60s, why)) << why;
  start_gateway(rig, common("ecu1"), kDuration_s);

  // Run until DR navigates on an identified K, well into the drive.
  ASSERT_TRUE(rig.wait_snapshot(
      "monitor",
      [&](const Snapshot& s) {
        return s.dr_k_source() == "identified" && s.dr_stamp_s().value_or(0.0) >= t_first + kCutAfter_s;
      },
      kCutAfter_s + 60.0))
      << "DR never used an identified K by t=" << kCutAfter_s << " s\n"
      << rig.log_tail("odonav-dead-reckoning") << rig.log_tail("odonav-identification") << rig.log_tail("monitor");
  // UDP only, also between the two components on one ECU: Fast DDS 2.9's shared-memory transport
  // cuts a restarted process off (docs/DDS.md §3), so the vehicle profile leaves it out and ECU2's
  // private /dev/shm holds no Fast DDS segment.
  bool ecu2_uses_shm = false;
  for (const auto& e : fs::directory_iterator(net.shm_dir("ecu2")))
    if (e.path().filename().string().rfind("fastrtps_", 0) == 0) ecu2_uses_shm = true;
  EXPECT_FALSE(ecu2_uses_shm) << "a Fast DDS shared-memory segment in ECU2's private /dev/shm";

  // ---- the cut ----
  const double dr_stamp_at_cut = rig.snapshots().back().dr_stamp_s().value();
  const double cut_s = rig.now_s();
  net.set_link("ecu2", false);
  rig.sleep_polling("monitor", kCut_s);
  const double restore_s = rig.now_s();
  net.set_link("ecu2", true);
  const double dr_stamp_at_restore = rig.snapshots().back().dr_stamp_s().value();
  const double k_applied_at_restore = rig.snapshots().back().counter_of("odonav-dead-reckoning", "k_applied");

  // During the cut, as the ground sees it: the scale factor is stale, DR says it lost
  // identification, and DR itself keeps publishing (its stamp advances).
  bool ground_sees_k_stale = false, dr_reports_no_identification = false;
  double dr_stamp_min = 1e300, dr_stamp_max = -1e300;
  for (const Snapshot& s : rig.snapshots()) {
    if (s.read_s < cut_s + 0.2 || s.read_s > restore_s + 0.2) continue;
    ground_sees_k_stale |= s.scale_factor_stale();
    const std::string reason = s.reason_of("odonav-dead-reckoning");
    dr_reports_no_identification |= reason.find("no identification") != std::string::npos;
    if (auto t = s.dr_stamp_s()) {
      dr_stamp_min = std::min(dr_stamp_min, *t);
      dr_stamp_max = std::max(dr_stamp_max, *t);
    }
  }
  EXPECT_TRUE(ground_sees_k_stale) << "the ground never showed the scale factor STALE during the cut";
  EXPECT_TRUE(dr_reports_no_identification) << "DR's health never reported the missing identification";
  EXPECT_GT(dr_stamp_max - dr_stamp_min, 1.0) << "DR did not publish during the cut";

  // After the restore: identification heard again, its K applied by DR again, DR's health clear.
  const bool recovered = rig.wait_snapshot(
      "monitor",
      [&](const Snapshot& s) {
        return !s.scale_factor_stale() && s.counter_of("odonav-dead-reckoning", "k_applied") > k_applied_at_restore &&
               s.reason_of("odonav-dead-reckoning").find("no identification") == std::string::npos &&
               s.component("odonav-identification") != nullptr &&
               !s.component("odonav-identification")->at("stale").get<bool>();
      },
      30.0);
  const double recovery_s = rig.now_s() - restore_s;
  EXPECT_TRUE(recovered) << "no recovery within 30 s of the restore\n"
                         << rig.log_tail("odonav-dead-reckoning") << rig.log_tail("odonav-identification");
  std::cerr << "link restored: ground/DR recovered after " << recovery_s << " s\n";

  // ---- the end of the data, then stop in data-flow order (each drains) ----
  ChildProcess& gateway = rig.child("odonav-gateway");
  ASSERT_TRUE(gateway.wait_exit(std::chrono::seconds(static_cast<int>(kDuration_s * 1.5 + 60))))
      << "the gateway did not reach the end of the data\n"
      << rig.log_tail("odonav-gateway");
  EXPECT_EQ(gateway.exit_code(), 0) << rig.log_tail("odonav-gateway");
  for (const char* c : {"odonav-calibration", "odonav-identification", "odonav-dead-reckoning", "odonav-recorder"})
    EXPECT_EQ(rig.stop(c, 60s), 0) << rig.log_tail(c);
  EXPECT_EQ(rig.stop("monitor", 20s), 0) << rig.log_tail("monitor");
  EXPECT_EQ(rig.stop("listener", 20s), 0) << rig.log_tail("listener");

  // The passive listener on the ground host heard the vehicle (control for the secure test).
  const auto heard = last_json_line(rig.out_file("listener"));
  EXPECT_GT(heard.at("received").at("dead_reckoning").get<int>(), 100) << heard.dump();
  EXPECT_GT(heard.at("received").at("scale_factor_not_fake").get<int>(), 0) << heard.dump();

  // ---- what DR published, from the recorder's files ----
  const auto rows = odonav::results::read_output_rows((dir / "out").string());
  check_final_accuracy(drive, rows);
  const auto [gap, period] = dr_largest_gap(rows.dead_reckoning, drive.data);
  EXPECT_LE(gap, 2.0 * period + 1e-9) << "DR output gap " << gap << " s (odometer period " << period << " s)";
  std::cerr << "DR largest output gap " << gap << " s, odometer period " << period << " s\n";

  // During the cut DR used the last identified K, the one in force before the cut.
  std::optional<double> k_cut;
  std::size_t rows_in_cut = 0;
  for (const auto& r : rows.dead_reckoning) {
    if (r.t_s < dr_stamp_at_cut + 0.5 || r.t_s > dr_stamp_at_restore) continue;
    ++rows_in_cut;
    EXPECT_EQ(r.k_source, "identified") << "t=" << r.t_s;
    if (!k_cut) k_cut = r.k_m_per_pulse;
    EXPECT_EQ(r.k_m_per_pulse, *k_cut) << "K changed during the cut at t=" << r.t_s;
  }
  ASSERT_TRUE(k_cut.has_value());
  EXPECT_GT(rows_in_cut, static_cast<std::size_t>(2.0 / period)) << "too few DR outputs inside the cut";
  // It is a K identification published before the cut (not the nominal K DR falls back to when
  // it never had one). Which one exactly depends on which estimate was in flight at the cut: the
  // recorder may get estimates written just before the cut later, by retransmission, DR drops them.
  const bool published_before_cut = std::any_of(rows.scale_factor.begin(), rows.scale_factor.end(), [&](const auto& k) {
    return k.t_s <= dr_stamp_at_cut + 0.5 && k.k_m_per_pulse && *k.k_m_per_pulse == *k_cut;
  });
  EXPECT_TRUE(published_before_cut) << "DR's K during the cut " << *k_cut << " was not identified before the cut";
  EXPECT_NE(*k_cut, drive.data.meta.k_nominal_m_per_pulse.value_or(0.0125));
  // After the restore, identification's new estimates reach DR (a K identified after the restore
  // is applied).
  std::optional<double> first_new_k_t;
  for (const auto& r : rows.dead_reckoning) {
    if (r.t_s <= dr_stamp_at_restore || r.k_m_per_pulse == *k_cut) continue;
    const bool identified_after = std::any_of(rows.scale_factor.begin(), rows.scale_factor.end(), [&](const auto& k) {
      return k.t_s > dr_stamp_at_restore && k.k_m_per_pulse && *k.k_m_per_pulse == r.k_m_per_pulse;
    });
    if (identified_after) {
      first_new_k_t = r.t_s;
      break;
    }
  }
  ASSERT_TRUE(first_new_k_t.has_value()) << "no scale factor identified after the restore reached DR";
  std::cerr << "cut at data t=" << dr_stamp_at_cut - t_first << " s, restored at t=" << dr_stamp_at_restore - t_first
            << " s; DR K during the cut " << *k_cut << " m/pulse over " << rows_in_cut
            << " outputs; first post-restore K applied at data t=" << *first_new_k_t - t_first << " s ("
            << *first_new_k_t - dr_stamp_at_restore << " s after the restore)\n";
}

// ---- 2. secure -------------------------------------------------------------------------------------

TEST_F(MultiHost, SecurePipelineAcrossHostsKeepsIntrudersOut) {
  constexpr int kDomain = 131;
  constexpr double kDuration_s = 45.0;
  constexpr double kFakeNoCredentials = 9.99;
  constexpr double kFakeForeignCa = 7.77;
  const fs::path dir = fresh_dir("secure");
  const Drive drive = simulate_drive(dir, kDuration_s);
  const double t_first = drive.data.odometer.front().t_s;
  for (const char* pki : {"pki", "pki_foreign"}) {
    const std::string cmd = (kSource / "deploy/security/make-pki").string() + " --out " + (dir / pki).string() +
                            " --org odonav-test >" + (dir / (std::string(pki) + ".log")).string() + " 2>&1";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd << "\n" << read_text(dir / (std::string(pki) + ".log"));
  }

  VirtualNetwork net(dir / "net", hosts());
  std::map<std::string, fs::path> secure, plain;
  for (const auto& h : hosts()) {
    secure[h.name] = instantiate_profile(kSource / "deploy/profiles/secure.xml", dir / "profiles" / h.name, h.address);
    plain[h.name] = instantiate_profile(kSource / "deploy/profiles/vehicle.xml", dir / "profiles" / h.name, h.address);
  }
  const std::string pki = (dir / "pki").string();
  const auto common = [&](const std::string& host) {
    return std::vector<std::string>{
        "--domain",       std::to_string(kDomain), "--profile", secure[host].string(), "--profile-name",
        "vehicle_secure", "--vehicle-id",          kVehicle,    "--security-dir",      pki};
  };
  const auto node = [&](const std::string& host, bool nominal_k) {
    auto a = common(host);
    a.insert(a.end(), {"--max-wait-s", "2"});
    for (std::size_t i = 0; i + 1 < drive.install_flags.size(); i += 2)
      if (nominal_k || drive.install_flags[i] != "--nominal-k")
        a.insert(a.end(), {drive.install_flags[i], drive.install_flags[i + 1]});
    return a;
  };

  Rig rig(dir, net);
  // A component whose permissions do not grant a topic cannot create that writer: calibration's
  // identity on ECU2 trying to publish the scale factor (tests/integration/deploy checks the
  // reader side and the ground station's grants in-process).
  rig.start("denied", "ecu2", "odonav-multihost-rogue",
            {"--domain", std::to_string(kDomain), "--profile", secure["ecu2"].string(), "--profile-name",
             "vehicle_secure", "--name", "odonav-calibration", "--security-dir", pki, "--duration-s", "1"});
  ASSERT_TRUE(rig.child("denied").wait_exit(30s));
  EXPECT_EQ(rig.child("denied").exit_code(), 3) << rig.log_tail("denied");
  const std::string denied = read_text(rig.log_file("denied"));
  EXPECT_NE(denied.find("permissions of identity 'odonav-calibration'"), std::string::npos) << denied;
  EXPECT_NE(denied.find("do not allow publishing"), std::string::npos) << denied;
  EXPECT_NE(denied.find("rt/odonav/scale_factor"), std::string::npos) << denied;
  rig.forget("denied");

  start_recorder(rig, common("gs"), dir / "out");
  // The ground station takes its material from the environment (ODONAV_SECURITY_DIR).
  rig.start("monitor", "gs", "odonav-ground",
            {"monitor", "--json", "--refresh-s", "0.5", "--domain", std::to_string(kDomain), "--profile",
             secure["gs"].string(), "--profile-name", "vehicle_secure", "--vehicle", kVehicle},
            {"ODONAV_SECURITY_DIR=" + pki});
  rig.start("odonav-dead-reckoning", "ecu3", "odonav-dead-reckoning", node("ecu3", true));
  rig.start("odonav-identification", "ecu2", "odonav-identification", node("ecu2", true));
  rig.start("odonav-calibration", "ecu2", "odonav-calibration", node("ecu2", false));
  std::string why;
  ASSERT_TRUE(rig.wait_for_log("odonav-recorder", "every producer matched", 90s, why)) << why;
  start_gateway(rig, common("ecu1"), kDuration_s);
  // The intruders on the ground host, for the whole drive, their fake stamps following the data's
  // event time (the gateway paces the data at real time from now).
  const std::string intrude_s = std::to_string(kDuration_s + 5.0);
  std::ostringstream stamp;
  stamp.precision(17);
  stamp << t_first;
  rig.start("no-credentials", "gs", "odonav-multihost-rogue",
            {"--domain", std::to_string(kDomain), "--profile", plain["gs"].string(), "--profile-name", "vehicle",
             "--vehicle-id", kVehicle, "--fake-k", std::to_string(kFakeNoCredentials), "--stamp-start-s", stamp.str(),
             "--duration-s", intrude_s});
  // Valid-looking material of another PKI with a legitimate identity name: it may publish the
  // scale factor by its (foreign) permissions, but the vehicle's CA does not authenticate it.
  rig.start(
      "foreign-ca", "gs", "odonav-multihost-rogue",
      {"--domain", std::to_string(kDomain), "--profile", secure["gs"].string(), "--profile-name", "vehicle_secure",
       "--name", "odonav-identification", "--security-dir", (dir / "pki_foreign").string(), "--vehicle-id", kVehicle,
       "--fake-k", std::to_string(kFakeForeignCa), "--stamp-start-s", stamp.str(), "--duration-s", intrude_s});

  ChildProcess& gateway = rig.child("odonav-gateway");
  const auto gateway_end = Clock::now() + std::chrono::seconds(static_cast<int>(kDuration_s * 1.5 + 60));
  while (!gateway.wait_exit(100ms) && Clock::now() < gateway_end) rig.poll_monitor("monitor");
  ASSERT_FALSE(gateway.running()) << "the gateway did not reach the end of the data\n"
                                  << rig.log_tail("odonav-gateway");
  EXPECT_EQ(gateway.exit_code(), 0) << rig.log_tail("odonav-gateway");
  for (const char* c : {"odonav-calibration", "odonav-identification", "odonav-dead-reckoning", "odonav-recorder"})
    EXPECT_EQ(rig.stop(c, 60s), 0) << rig.log_tail(c);
  rig.poll_monitor("monitor");
  EXPECT_EQ(rig.stop("monitor", 20s), 0) << rig.log_tail("monitor");
  for (const char* r : {"no-credentials", "foreign-ca"}) {
    ASSERT_TRUE(rig.child(r).wait_exit(30s)) << rig.log_tail(r);
    EXPECT_EQ(rig.child(r).exit_code(), 0) << rig.log_tail(r);
  }

  // The pipeline worked across hosts, secured: accuracy as in the plain run.
  const auto rows = odonav::results::read_output_rows((dir / "out").string());
  check_final_accuracy(drive, rows);
  // The secured ground station saw the vehicle's DR output.
  bool ground_saw_dr = false;
  for (const auto& s : rig.snapshots()) ground_saw_dr |= s.dr_stamp_s().has_value();
  EXPECT_TRUE(ground_saw_dr) << "the secure ground monitor never received dead reckoning\n" << rig.log_tail("monitor");
  // The health view shows the intruders (ComponentRuntime::publish_health: "DDS Security refused
  // '<name>'" or "... handshake with '<name>' incomplete"), and only them: no legitimate pair
  // stalled. They take the names odonav-rogue (no credentials) and odonav-identification
  // (foreign CA); at most those two are counted.
  std::size_t snapshots_with_components = 0, snapshots_showing_intruders = 0;
  const std::regex stranger_re("DDS Security (refused '([^']+)'|handshake with '([^']+)' incomplete)");
  for (const auto& s : rig.snapshots()) {
    if (s.vehicle.is_null()) continue;
    ++snapshots_with_components;
    bool shows = false;
    for (const auto& c : s.vehicle.at("components")) {
      const std::string reason = c.at("reason").get<std::string>();
      std::smatch m;
      if (!std::regex_search(reason, m, stranger_re)) continue;
      shows = true;
      const std::string who = m[2].matched ? m[2].str() : m[3].str();
      EXPECT_TRUE(who == "odonav-rogue" || who == "odonav-identification") << c.at("component") << ": " << reason;
      EXPECT_LE(c.at("counters").at("dds_unauthenticated_participants").get<double>(), 2.0) << reason;
    }
    snapshots_showing_intruders += shows ? 1 : 0;
  }
  EXPECT_GT(snapshots_with_components, 50u);
  EXPECT_GT(snapshots_showing_intruders, 0u) << "no component's health ever showed the intruders";

  // The intruders received nothing of the vehicle, only (the control) their own fake samples.
  for (const auto& [name, fake_k] :
       {std::pair<std::string, double>{"no-credentials", kFakeNoCredentials}, {"foreign-ca", kFakeForeignCa}}) {
    const auto r = last_json_line(rig.out_file(name));
    ASSERT_FALSE(r.is_discarded()) << rig.log_tail(name);
    std::cerr << name << ": " << r.dump() << "\n";
    EXPECT_GT(r.at("written").get<int>(), 100) << name;
    const auto& got = r.at("received");
    // null: a reader its own (foreign) permissions refuse; otherwise it must have received nothing.
    const auto nothing = [&](const char* topic) { return got.at(topic).is_null() || got.at(topic).get<int>() == 0; };
    if (!got.at("scale_factor").is_null()) {
      EXPECT_GT(got.at("scale_factor").get<int>(), 0) << name << ": control: it hears its own writer";
    }
    EXPECT_TRUE(nothing("scale_factor_not_fake")) << name << " received a vehicle estimate";
    EXPECT_TRUE(nothing("dead_reckoning")) << name << " received dead reckoning";
    EXPECT_TRUE(nothing("odometer")) << name << " received odometer data";
    EXPECT_LE(r.at("fake_matched_readers_max").get<int>(), 1) << name << ": its fake writer matched a vehicle reader";
    // Its fake K never reached DR nor the recorder.
    for (const auto& d : rows.dead_reckoning) {
      EXPECT_NE(d.k_m_per_pulse, fake_k) << "DR applied " << name << "'s fake K at t=" << d.t_s;
      if (d.k_m_per_pulse == fake_k) break;
    }
    for (const auto& k : rows.scale_factor)
      EXPECT_NE(k.k_m_per_pulse.value_or(0.0), fake_k) << "the recorder received " << name << "'s fake K";
  }
  // Every legitimate participant authenticated each of the five others, and nobody else: from
  // the DDS layer's log lines "<me> discovered participant '<name>' (<guid>)" and "<me>
  // authenticated participant <guid>". (The foreign-CA intruder is also named
  // odonav-identification: a name counts as authenticated if one of its GUIDs is.)
  const std::vector<std::pair<std::string, std::string>> legit = {{"odonav-gateway", "odonav-gateway"},
                                                                  {"odonav-calibration", "odonav-calibration"},
                                                                  {"odonav-identification", "odonav-identification"},
                                                                  {"odonav-dead-reckoning", "odonav-dead-reckoning"},
                                                                  {"odonav-recorder", "odonav-recorder"},
                                                                  {"monitor", "odonav-ground"}};
  const std::regex discovered_re("discovered participant '([^']+)' \\(([0-9a-f.]+)\\)");
  const std::regex authenticated_re("authenticated participant ([0-9a-f.]+)");
  for (const auto& [log_name, own_name] : legit) {
    const std::string log = read_text(rig.log_file(log_name));
    std::multimap<std::string, std::string> guids_by_name;
    for (std::sregex_iterator it(log.begin(), log.end(), discovered_re), end; it != end; ++it)
      guids_by_name.emplace((*it)[1].str(), (*it)[2].str());
    std::set<std::string> authenticated;
    for (std::sregex_iterator it(log.begin(), log.end(), authenticated_re), end; it != end; ++it)
      authenticated.insert((*it)[1].str());
    EXPECT_EQ(authenticated.size(), legit.size() - 1) << own_name << " authenticated " << authenticated.size()
                                                      << " participants, not the " << legit.size() - 1 << " others";
    for (const auto& [other_log, other_name] : legit) {
      if (other_name == own_name) continue;
      const auto [first, last] = guids_by_name.equal_range(other_name);
      const bool ok = std::any_of(first, last, [&](const auto& g) { return authenticated.count(g.second) > 0; });
      EXPECT_TRUE(ok) << own_name << " never authenticated " << other_name << "\n" << rig.log_tail(log_name);
    }
  }

  // DR's K was always the nominal one or one identification published.
  std::size_t identified_rows = 0;
  for (const auto& d : rows.dead_reckoning) {
    if (d.k_source != "identified") continue;
    ++identified_rows;
    const bool published = std::any_of(rows.scale_factor.begin(), rows.scale_factor.end(), [&](const auto& k) {
      return k.k_m_per_pulse && *k.k_m_per_pulse == d.k_m_per_pulse;
    });
    EXPECT_TRUE(published) << "DR used K=" << d.k_m_per_pulse << " at t=" << d.t_s << ", never identified";
    if (!published) break;
  }
  EXPECT_GT(identified_rows, 1000u);
}

}  // namespace
