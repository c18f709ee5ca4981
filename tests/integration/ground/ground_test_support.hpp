#pragma once
// Helpers of the ground-station tests: the loopback participant, programs run to their end, the
// monitor's JSON lines, the MCAP reader of the npm packages Foxglove uses, and a simulated
// vehicle's real pipeline (gateway, calibration, identification, dead reckoning as processes).
// Child processes, file reading and scratch folders: tests/support/child_process.hpp.
#include <gtest/gtest.h>
#include <signal.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "odonav/dds/participant.hpp"
#include "odonav/dds/types.hpp"
#include "child_process.hpp"
#include "odonav/topics.hpp"

namespace odonav::test {

// The names the ground-station tests use unqualified (each has `using namespace odonav::test`).
using namespace std::chrono_literals;
namespace msg = odonav::msg;
namespace topics = odonav::topics;
namespace fs = std::filesystem;
using nlohmann::json;

inline std::string loopback_profile() { return std::string(ODONAV_SOURCE_DIR) + "/deploy/profiles/loopback.xml"; }

inline dds::ParticipantOptions participant_options(int domain, const std::string& name) {
  dds::ParticipantOptions p;
  p.profiles_file = loopback_profile();
  p.participant_profile = topics::kLoopbackParticipantProfile;
  p.domain_id = domain;
  p.participant_name = name;
  return p;
}

/// A fresh folder under the build tree for one test.
inline std::filesystem::path scratch_dir(const std::string& name) { return fresh_dir("tests/ground", name); }

/// Runs a program to its end (bounded by timeout, then killed): exit code, stdout, stderr.
struct RunResult {
  int exit_code = -1;
  std::string out, err;
};
inline RunResult run(const std::string& path, const std::vector<std::string>& args, const std::filesystem::path& dir,
                     const std::string& tag, std::chrono::milliseconds timeout = std::chrono::seconds(120)) {
  ChildProcess child(path, args, dir / (tag + ".out"), dir / (tag + ".err"));
  RunResult r;
  if (!child.started()) {
    ADD_FAILURE() << "cannot start " << path;
    return r;
  }
  if (!child.wait_exit(timeout)) {
    ADD_FAILURE() << path << " did not finish within " << timeout.count() << " ms";
    child.signal(SIGKILL);
    child.wait_exit(std::chrono::seconds(5));
  }
  r.exit_code = child.exit_code();
  r.out = child.out();
  r.err = child.err();
  return r;
}

/// The item of a JSON array whose `key` equals `value`, or nullptr.
inline const nlohmann::json* find_by(const nlohmann::json& array, const std::string& key, const std::string& value) {
  for (const auto& item : array)
    if (item.at(key) == value) return &item;
  return nullptr;
}

/// The last complete line of a file that a running `odonav-ground monitor --json` writes (one JSON
/// document per line), parsed; nullopt while there is none.
inline std::optional<nlohmann::json> last_json_line(const std::filesystem::path& file) {
  // Only the file's tail (a snapshot of a few vehicles is a few kB): polled often, the file grows.
  std::ifstream in(file, std::ios::binary);
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  if (size <= 0) return std::nullopt;
  const std::streamoff from = std::max<std::streamoff>(0, size - 256 * 1024);
  std::string text(static_cast<std::size_t>(size - from), '\0');
  in.seekg(from);
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  const auto end = text.rfind('\n');
  if (end == std::string::npos) return std::nullopt;
  const auto before = end == 0 ? std::string::npos : text.rfind('\n', end - 1);
  const std::size_t begin = before == std::string::npos ? 0 : before + 1;
  return nlohmann::json::parse(text.substr(begin, end - begin));
}

/// One component's entry of a monitor snapshot, or nullptr.
inline const nlohmann::json* snapshot_component(const nlohmann::json& snapshot, const std::string& vehicle,
                                                const std::string& component) {
  const nlohmann::json* v = find_by(snapshot.at("vehicles"), "vehicle_id", vehicle);
  return v ? find_by(v->at("components"), "component", component) : nullptr;
}

// ---- MCAP files read back with the npm packages Foxglove uses ----

/// Folder with node_modules holding @mcap/core, @foxglove/rosmsg and @foxglove/rosmsg2-serialization;
/// installs them the first time (under a lock, so parallel tests install once). Fails the test with
/// what to install when node/npm are missing.
inline std::optional<std::filesystem::path> npm_reader_modules() {
  if (std::system("command -v node >/dev/null 2>&1 && command -v npm >/dev/null 2>&1") != 0) {
    ADD_FAILURE() << "node and npm are needed to read MCAP files back: install nodejs and npm "
                     "(Debian 12: apt-get install nodejs npm)";
    return std::nullopt;
  }
  const std::filesystem::path dir = std::filesystem::path(ODONAV_BINARY_DIR) / "tests" / "ground-npm";
  std::filesystem::create_directories(dir);
  const std::string cmd = "cd '" + dir.string() +
                          "' && flock .lock sh -c 'test -d node_modules/@foxglove/rosmsg2-serialization -a -d "
                          "node_modules/@mcap/core -a -d node_modules/@foxglove/rosmsg || npm install --no-audit "
                          "--no-fund --silent @mcap/core @foxglove/rosmsg @foxglove/rosmsg2-serialization' "
                          ">npm-install.log 2>&1";
  if (std::system(cmd.c_str()) != 0) {
    ADD_FAILURE() << "npm install of @mcap/core @foxglove/rosmsg @foxglove/rosmsg2-serialization failed: "
                  << read_text(dir / "npm-install.log");
    return std::nullopt;
  }
  return dir / "node_modules";
}

/// What read_mcap.js printed for a file in `mode` ("indexed" or "stream"): exit code and JSON.
struct McapRead {
  int exit_code = -1;
  nlohmann::json doc;
  std::string err;
};
inline McapRead read_mcap(const std::filesystem::path& file, const std::string& mode) {
  McapRead r;
  const auto modules = npm_reader_modules();
  if (!modules) return r;
  const std::filesystem::path out = file.string() + "." + mode + ".json";
  const std::filesystem::path err = file.string() + "." + mode + ".err";
  const std::string cmd = "NODE_PATH='" + modules->string() + "' node '" + ODONAV_SOURCE_DIR +
                          "/tests/integration/ground/read_mcap.js' '" + file.string() + "' " + mode + " >'" +
                          out.string() + "' 2>'" + err.string() + "'";
  const int status = std::system(cmd.c_str());
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.err = read_text(err);
  if (r.exit_code == 0) r.doc = nlohmann::json::parse(read_text(out));
  return r;
}

// ---- a simulated vehicle's pipeline as real processes ----

/// How a VehiclePipeline runs.
struct PipelineOptions {
  std::string scenario = "terrain";  ///< odonav-simulator scenario of the gateway's sim: source
  std::string speed = "2";           ///< gateway --speed: 1 real time, N, or max
  int seed = 1;
  double duration_s = 240.0;  ///< sim length (s); terrain's first K step is at 250 s
  bool with_dead_reckoning = true;
  bool with_recorder = false;  ///< odonav-recorder --out <dir>/recorder
};

/// One vehicle of a fleet: odonav-calibration, -identification, -dead-reckoning (and optionally
/// -recorder) started by start_consumers(), odonav-gateway (sim source) by start_gateway(); each a
/// ChildProcess with its log in <dir>/<vehicle>-<component>.log, SIGKILLed by the destructor if
/// still running. All on the loopback profile, one domain, told apart by --vehicle-id.
class VehiclePipeline {
 public:
  VehiclePipeline(int domain, std::string vehicle_id, std::filesystem::path dir, PipelineOptions options = {})
      : domain_(domain), vehicle_(std::move(vehicle_id)), dir_(std::move(dir)), options_(std::move(options)) {}

  /// The flags every component gets: domain, loopback profile, vehicle, log level info (logs are
  /// read on failure).
  std::vector<std::string> common_args() const {
    return {"--domain", std::to_string(domain_), "--profile", loopback_profile(), "--vehicle-id",
            vehicle_,   "--log-level",           "info"};
  }
  /// Starts the consumers (recorder, dead reckoning, identification, calibration), consumers first
  /// as deploy/launch does. Faster than real time their event-time queues may lag each other by
  /// more than the default 2 s without any input being absent, hence --max-wait-s 30 then.
  void start_consumers() {
    std::vector<std::string> node = common_args();
    node.push_back("--max-wait-s");
    node.push_back(options_.speed == "1" ? "2" : "30");
    if (options_.with_recorder) {
      auto rec = common_args();
      rec.push_back("--out");
      rec.push_back((dir_ / (vehicle_ + "-recorder")).string());
      start("odonav-recorder", rec);
    }
    if (options_.with_dead_reckoning) start("odonav-dead-reckoning", node);
    start("odonav-identification", node);
    start("odonav-calibration", node);
  }
  /// Starts the gateway: sim:<scenario> at options().speed, waiting (bounded) for this vehicle's
  /// GNSS readers to be matched.
  void start_gateway() {
    auto args = common_args();
    const int readers = (options_.with_dead_reckoning ? 1 : 0) + 2;
    for (const std::string& a :
         {std::string("--source"), "sim:" + options_.scenario, std::string("--speed"), options_.speed,
          std::string("--seed"), std::to_string(options_.seed), std::string("--duration-s"),
          std::to_string(options_.duration_s), std::string("--wait-for-readers"), std::to_string(readers)})
      args.push_back(a);
    start("odonav-gateway", args);
  }
  ChildProcess& process(const std::string& component) { return *processes_.at(component); }
  bool has(const std::string& component) const { return processes_.count(component) > 0; }
  std::string log(const std::string& component) const { return read_text(log_path(component)); }
  /// The tail of every component's log, for failure messages.
  std::string logs_tail(std::size_t chars = 1500) const {
    std::string all;
    for (const auto& [name, p] : processes_) {
      const std::string text = log(name);
      all += "--- " + vehicle_ + " " + name + ":\n" + (text.size() > chars ? text.substr(text.size() - chars) : text);
    }
    return all;
  }
  const std::string& vehicle() const { return vehicle_; }
  const PipelineOptions& options() const { return options_; }
  std::filesystem::path recorder_dir() const { return dir_ / (vehicle_ + "-recorder"); }

 private:
  std::filesystem::path log_path(const std::string& component) const {
    return dir_ / (vehicle_ + "-" + component + ".log");
  }
  void start(const std::string& component, const std::vector<std::string>& args) {
    // The components log to stderr; stdout (normally empty) beside it.
    auto p = std::make_unique<ChildProcess>(binary(component), args, log_path(component).string() + ".out",
                                            log_path(component));
    if (!p->started()) ADD_FAILURE() << "cannot start " << binary(component);
    processes_[component] = std::move(p);
  }

  int domain_;
  std::string vehicle_;
  std::filesystem::path dir_;
  PipelineOptions options_;
  std::map<std::string, std::unique_ptr<ChildProcess>> processes_;
};

// ---- a real vehicle's expectations ----

inline const std::vector<std::string> kVehicleComponents{"odonav-calibration", "odonav-dead-reckoning",
                                                         "odonav-gateway", "odonav-identification"};

inline double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// The simulator's truth for a scenario and seed (meta.json "truth" and "simulation"), from
/// odonav-simulator itself: initial K (m/pulse) and installation misalignment (deg).
struct ScenarioTruth {
  double k_m_per_pulse = 0.0;
  double heading_deg = 0.0, pitch_deg = 0.0;
};
inline ScenarioTruth scenario_truth(const std::string& scenario, int seed, const std::filesystem::path& dir) {
  const RunResult r = run(binary("odonav-simulator"),
                          {scenario, "--seed", std::to_string(seed), "--duration-s", "10", "--out", dir.string()},
                          dir.parent_path(), "sim-" + scenario);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json meta = nlohmann::json::parse(read_text(dir / "meta.json"));
  ScenarioTruth t;
  t.k_m_per_pulse = meta.at("simulation").at("k_true_initial_m_per_pulse").get<double>();
  t.heading_deg = meta.at("truth").at("misalignment_heading_deg").get<double>();
  t.pitch_deg = meta.at("truth").at("misalignment_pitch_deg").get<double>();
  return t;
}

/// Every component of the vehicle live, and its estimates there: K converged with a sigma, the
/// misalignment with sigmas, DR with an error against GNSS.
inline bool vehicle_ready(const nlohmann::json& snap, const std::string& vehicle) {
  const nlohmann::json* v = find_by(snap.at("vehicles"), "vehicle_id", vehicle);
  if (!v) return false;
  for (const auto& c : kVehicleComponents) {
    const nlohmann::json* jc = find_by(v->at("components"), "component", c);
    if (!jc || jc->at("stale").get<bool>() || jc->at("state") != "RUNNING") return false;
  }
  const nlohmann::json& k = v->at("scale_factor");
  const nlohmann::json& m = v->at("misalignment");
  const nlohmann::json& d = v->at("dead_reckoning");
  return !k.is_null() && k.at("converged").get<bool>() && !k.at("sigma_m_per_pulse").is_null() && !m.is_null() &&
         !m.at("heading_std_deg").is_null() && !d.is_null() && !d.at("horizontal_error_m").is_null() &&
         !d.at("error_percent").is_null() && !k.at("stale").get<bool>();
}

/// The common DDS flags of odonav-ground under test.
inline std::vector<std::string> ground_args(const std::string& action, int domain,
                                            std::vector<std::string> extra = {}) {
  std::vector<std::string> a{action,        "--domain", std::to_string(domain), "--profile", loopback_profile(),
                             "--log-level", "warn"};
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}

}  // namespace odonav::test
