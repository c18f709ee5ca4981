// Faults that must lose nothing, as processes on loopback DDS (domains 160-169):
//   1. restart loop: odonav-identification killed (SIGKILL) and restarted with its --state-dir 20
//      times in a row while the drive goes on; every restarted instance's K reaches dead reckoning
//      (DR outputs carry it) and a recording reader. With Fast DDS 2.9's shared-memory transport a
//      restarted instance was cut off for 17-95 s in some cycles (docs/DDS.md section 8).
//   2. stalls: SIGSTOP 5 s of the identification, of dead reckoning and of the gateway in one
//      deploy/launch run (3x real time, so the consumers wait for each other): every output row is
//      present afterwards and equal to odonav-offline's, and after the gateway's stall the data flows
//      again (rows counted, not timed). Then dead reckoning is killed (-9): the launcher starts it
//      again, it resumes from its checkpoint, and the rows are still all there and equal.
//   3. kill -9 + restart, 2 s later, of two components at different times of one drive: the
//      identification (t=30 s) and dead reckoning (t=75 s) on domain 195, the calibration (t=52.5 s)
//      and dead reckoning (t=95 s) on domain 196: each resumes from its checkpoint, processes the
//      producers' history of its downtime and publishes those outputs late (catch-up, in its
//      health); every recorded row (misalignment, K, dead reckoning, navigation position) is
//      present and equal to odonav-offline's, and the recorder's gaps.csv is empty.
//   4. the identification killed for good (domain 162): the recorder's gaps.csv names the GNSS epochs
//      left without a K (against the dataset), and dead reckoning's health the outputs on the K held.
//      In the same run the recorder is killed (-9) and restarted: it resumes its recording, and every
//      other row is there and equal to odonav-offline's.
// The restart loop (1) also runs on the vehicle profile, in a network namespace of its own (root).
// ODONAV_FAULTS_PROFILE=<participant profile file> runs both against other profiles (with the qos.xml
// beside it), e.g. the shared-memory ones of an earlier version, for the before/after figures;
// ODONAV_FAULTS_PROFILE_NAME names the participant profile in it (default loopback.xml's).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <mutex>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "shm_clean_test.hpp"
#include "child_process.hpp"
#include "multihost/virtual_network.hpp"
#include "odonav/simulator/simulator.hpp"
#include "odonav/dataset.hpp"
#include "odonav/dds/endpoints.hpp"
#include "odonav/dds/participant.hpp"
#include "odonav/dds/time.hpp"
#include "odonav/msg/DeadReckoning.h"
#include "odonav/msg/Health.h"
#include "odonav/msg/Misalignment.h"
#include "odonav/msg/ScaleFactor.h"
#include "odonav/results/output_files.hpp"
#include "odonav/topics.hpp"

namespace {

using namespace odonav;
using namespace odonav::test;
namespace fs = std::filesystem;
using std::chrono::milliseconds;
using std::chrono::seconds;

constexpr const char* kVehicle = "fault-vehicle";

std::string profile_file() {
  if (const char* p = std::getenv("ODONAV_FAULTS_PROFILE"); p && *p) return p;
  return std::string(ODONAV_SOURCE_DIR) + "/deploy/profiles/loopback.xml";
}
/// The participant profile's name in profile_file(): ODONAV_FAULTS_PROFILE_NAME, else loopback.xml's.
std::string profile_name() {
  if (const char* p = std::getenv("ODONAV_FAULTS_PROFILE_NAME"); p && *p) return p;
  return topics::kLoopbackParticipantProfile;
}

double steady_s() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }
double stamp_s(const msg::ScaleFactor& m) { return odonav::dds::to_seconds(m.header().stamp()); }
double stamp_s(const msg::DeadReckoning& m) { return odonav::dds::to_seconds(m.header().stamp()); }
double stamp_s(const msg::Misalignment& m) { return odonav::dds::to_seconds(m.header().stamp()); }

/// Every sample of a topic with the steady-clock time it arrived here.
template <class T>
class TimedCollector {
 public:
  struct Item {
    T sample;
    double received_s;
  };
  TimedCollector(const odonav::dds::Participant& p, const topics::TopicSpec& topic, const std::string& profile)
      : reader_(p, topic.name, profile, [this](const T& s) {
          std::lock_guard<std::mutex> lock(mutex_);
          items_.push_back({s, steady_s()});
        }) {}
  std::vector<Item> items() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return items_;
  }
  /// Waits until pred(items) holds or timeout; returns whether it held.
  template <class Pred>
  bool wait_until(Pred pred, milliseconds timeout) const {
    const auto end = std::chrono::steady_clock::now() + timeout;
    for (;;) {
      if (pred(items())) return true;
      if (std::chrono::steady_clock::now() >= end) return false;
      std::this_thread::sleep_for(milliseconds(10));
    }
  }

 private:
  mutable std::mutex mutex_;
  std::vector<Item> items_;
  odonav::dds::Reader<T> reader_;
};

odonav::dds::ParticipantOptions participant_options(int domain) {
  odonav::dds::ParticipantOptions p;
  p.profiles_file = profile_file();
  p.participant_profile = profile_name();
  p.domain_id = domain;
  p.participant_name = "odonav-faults-test";
  return p;
}

std::vector<std::string> common_args(int domain, std::vector<std::string> extra) {
  std::vector<std::string> a{"--domain",     std::to_string(domain), "--profile", profile_file(), "--profile-name",
                             profile_name(), "--vehicle-id",         kVehicle,    "--log-level",  "warn"};
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}

std::string lever_arm(const std::string& scenario) {
  const Eigen::Vector3d l = simulator::scenario_config(scenario).lever_arm_m;
  char buf[96];
  std::snprintf(buf, sizeof buf, "%.17g,%.17g,%.17g", l.x(), l.y(), l.z());
  return buf;
}

struct Percentiles {
  double p50 = 0, max = 0;
};
Percentiles percentiles(std::vector<double> v) {
  Percentiles p;
  if (v.empty()) return p;
  std::sort(v.begin(), v.end());
  p.p50 = v[v.size() / 2];
  p.max = v.back();
  return p;
}

/// One row of the recorder's gaps.csv.
struct GapsCsvRow {
  std::string topic, reason;
  double first_s = 0, last_s = 0;
  unsigned long long count = 0;
};

/// The restarted instances one listener heard, and how long after each restart (steady s).
struct Heard {
  int instances = 0;
  std::vector<double> after_restart_s;
};

/// Waits up to 20 s until first_new(items) gives the arrival time (steady s) of a sample that only
/// the instance restarted at restart_s can have sent; counts it in `heard`. Returns whether it came.
template <class T, class FirstNew>
bool wait_heard(const TimedCollector<T>& c, FirstNew first_new, double restart_s, Heard& heard) {
  double heard_at = -1.0;
  const bool ok = c.wait_until(
      [&](const auto& items) {
        const std::optional<double> at = first_new(items);
        if (at) heard_at = *at;
        return at.has_value();
      },
      seconds(20));
  if (ok) {
    ++heard.instances;
    heard.after_restart_s.push_back(heard_at - restart_s);
  }
  return ok;
}

class Faults : public odonav::test::ShmCleanTest {};

// ---- 1. restart loop ----------------------------------------------------------------------------

TEST_F(Faults, TwentyKillNineRestartsOfTheIdentificationAreEachHeardByDeadReckoningAndARecorder) {
  constexpr int kDomain = 160;
  constexpr int kCycles = 20;
  const std::string dir = fresh_dir("test-faults", "restart-loop").string();
  const std::string state = dir + "/state";
  const std::string arm = lever_arm("ring");

  odonav::dds::Participant participant(participant_options(kDomain));
  TimedCollector<msg::ScaleFactor> k(participant, topics::kScaleFactor, topics::kScaleFactorRecorderReaderProfile);
  TimedCollector<msg::DeadReckoning> dr(participant, topics::kDeadReckoning, topics::kDeadReckoningReaderProfile);

  auto dead_reckoning = start_logged("odonav-dead-reckoning",
                                     common_args(kDomain, {"--max-wait-s", "2", "--lever-arm", arm}), dir + "/dr.log");
  // The calibration too, as in the pipeline: a restarted identification gets its misalignment at
  // once instead of waiting --max-wait-s for it.
  auto calibration = start_logged("odonav-calibration", common_args(kDomain, {"--max-wait-s", "2", "--lever-arm", arm}),
                                  dir + "/calibration.log");
  const std::vector<std::string> id_args =
      common_args(kDomain, {"--max-wait-s", "2", "--lever-arm", arm, "--state-dir", state, "--checkpoint-every-s", "1",
                            "--log-level", "info"});
  int instance = 1;
  auto identification = start_logged("odonav-identification", id_args, dir + "/id-1.log");
  ASSERT_TRUE(dead_reckoning->started() && calibration->started() && identification->started());
  // Long enough for the loop at twice real time; stopped with SIGINT once the loop is done.
  auto gateway = start_logged("odonav-gateway",
                              common_args(kDomain, {"--source", "sim:ring", "--seed", "5", "--duration-s", "400",
                                                    "--speed", "2", "--wait-for-readers", "3",
                                                    "--wait-for-readers-timeout-s", "60", "--tolerate-lost-readers"}),
                              dir + "/gateway.log");
  ASSERT_TRUE(gateway->started());

  // K converged enough to move between epochs, and DR applying it.
  ASSERT_TRUE(k.wait_until([](const auto& s) { return !s.empty() && stamp_s(s.back().sample) >= 20.0; }, seconds(90)))
      << read_text(dir + "/id-1.log") << read_text(dir + "/gateway.log");

  Heard by_recorder, by_dr;
  for (int cycle = 0; cycle < kCycles; ++cycle) {
    SCOPED_TRACE("cycle " + std::to_string(cycle + 1));
    ASSERT_TRUE(gateway->running()) << "the gateway ended before the loop did: " << read_text(dir + "/gateway.log");
    identification->signal(SIGKILL);
    ASSERT_TRUE(identification->wait_exit(seconds(5)));
    const auto before = k.items();
    ASSERT_FALSE(before.empty());
    const double last_stamp = stamp_s(before.back().sample);
    const double restart_s = steady_s();
    ++instance;
    identification = start_logged("odonav-identification", id_args, dir + "/id-" + std::to_string(instance) + ".log");
    ASSERT_TRUE(identification->started());

    // The recorder: a K newer than any before the kill (only the new instance can publish it).
    std::set<double> new_k_values;
    const bool recorder_ok = wait_heard(
        k,
        [&](const auto& s) -> std::optional<double> {
          for (std::size_t i = before.size(); i < s.size(); ++i)
            if (stamp_s(s[i].sample) > last_stamp) return s[i].received_s;
          return std::nullopt;
        },
        restart_s, by_recorder);
    if (recorder_ok)
      std::cerr << "instance " << instance << ": first new K at the recorder " << by_recorder.after_restart_s.back()
                << " s after the restart\n";
    // Dead reckoning: an output received after the restart that applies one of the new instance's
    // K values (each epoch's K differs in its last digits at least, so this is the new instance's).
    const bool dr_ok = wait_heard(
        dr,
        [&](const auto& out) -> std::optional<double> {
          for (const auto& item : k.items())
            if (stamp_s(item.sample) > last_stamp && item.sample.k_m_per_pulse() > 0.0)
              new_k_values.insert(item.sample.k_m_per_pulse());
          for (auto it = out.rbegin(); it != out.rend() && it->received_s >= restart_s; ++it)
            if (new_k_values.count(it->sample.k_m_per_pulse())) return it->received_s;
          return std::nullopt;
        },
        restart_s, by_dr);
    if (!recorder_ok || !dr_ok) {
      if (!identification->running())
        ADD_FAILURE() << "restarted instance " << instance << " exited with status " << identification->exit_code();
      // What the unheard instance is doing: its threads' stacks, next to its log.
      const std::string stacks = dir + "/id-" + std::to_string(instance) + ".stacks";
      [[maybe_unused]] const int rc = std::system(
          ("gdb -p " + std::to_string(identification->pid()) + " -batch -ex 'thread apply all bt' >" + stacks + " 2>&1")
              .c_str());
    }
    EXPECT_TRUE(recorder_ok && dr_ok) << "restarted instance " << instance << " not heard (recorder " << recorder_ok
                                      << ", DR " << dr_ok << ")\n"
                                      << read_text(dir + "/id-" + std::to_string(instance) + ".log");
    std::this_thread::sleep_for(milliseconds(300));  // a few epochs of this instance before the next kill
  }
  const Percentiles rec = percentiles(by_recorder.after_restart_s), drp = percentiles(by_dr.after_restart_s);
  std::cerr << "restart loop (" << profile_file() << "): " << by_recorder.instances << "/" << kCycles
            << " restarted instances heard by the recorder (restart -> first new K: median " << rec.p50 << " s, max "
            << rec.max << " s), " << by_dr.instances << "/" << kCycles << " by DR (median " << drp.p50 << " s, max "
            << drp.max << " s)\n";
  EXPECT_EQ(by_recorder.instances, kCycles);
  EXPECT_EQ(by_dr.instances, kCycles);
  // Generous bound: the promise is 2 s, measured over runs of this loop in BENCHMARKS.md section
  // 11 (max 1.4 s), not asserted here on a shared machine; a cut-off instance took 17-95 s. The
  // one 11 s restart seen before came from the SQLite persistence the scale-factor writer no
  // longer has (docs/DDS.md section 8).
  EXPECT_LT(rec.max, 10.0);
  EXPECT_LT(drp.max, 10.0);

  gateway->signal(SIGINT);
  EXPECT_TRUE(gateway->wait_exit(seconds(30)));
  identification->signal(SIGINT);
  EXPECT_TRUE(identification->wait_exit(seconds(30)));
  EXPECT_EQ(identification->exit_code(), 0);
  calibration->signal(SIGINT);
  EXPECT_TRUE(calibration->wait_exit(seconds(30)));
  dead_reckoning->signal(SIGINT);
  EXPECT_TRUE(dead_reckoning->wait_exit(seconds(30)));
  EXPECT_EQ(dead_reckoning->exit_code(), 0);
}

// The same loop on the vehicle profile (deploy/profiles/vehicle.xml: UDPv4 whitelisted to one
// interface, multicast discovery on 239.255.0.1), as components of one ECU run it. The loop above
// runs again, as a child of this test, inside a network namespace of its own whose one interface
// (10.0.0.11, a veth to an empty bridge, multicast routed to it: the multi-host test's
// VirtualNetwork) carries the multicast, so nothing leaves the machine. Every restart heard within
// the loop's bounds; the figures (median / max time to be heard) are printed for BENCHMARKS.md
// section 11. Needs root (ip netns), as the multi-host test.
TEST_F(Faults, TwentyKillNineRestartsOnTheVehicleProfileAreEachHeard) {
  if (std::getenv("ODONAV_FAULTS_PROFILE")) GTEST_SKIP() << "already given a profile (the loop's own run)";
  ASSERT_EQ(::geteuid(), 0u) << "this test creates a network namespace (ip netns): run it as root (CI does)";
  multihost::remove_stale_namespaces();
  const fs::path dir = fresh_dir("test-faults", "vehicle-profile");
  const std::string address = "10.0.0.11";
  multihost::VirtualNetwork net(dir / "net", {{"ecu1", address}});
  const fs::path profile = multihost::instantiate_profile(
      std::string(ODONAV_SOURCE_DIR) + "/deploy/profiles/vehicle.xml", dir / "profiles", address);

  const std::string self = fs::read_symlink("/proc/self/exe").string();
  const auto argv = net.exec_argv(
      "ecu1", dir / "loop.out", dir / "loop.err",
      {"/usr/bin/env", "ODONAV_FAULTS_PROFILE=" + profile.string(), "ODONAV_FAULTS_PROFILE_NAME=vehicle", self,
       "--gtest_filter=Faults.TwentyKillNineRestartsOfTheIdentificationAreEachHeardByDeadReckoningAndARecorder"});
  ChildProcess loop(argv[0], std::vector<std::string>(argv.begin() + 1, argv.end()));
  ASSERT_TRUE(loop.started());
  const bool ended = loop.wait_exit(seconds(330));
  const std::string out = read_text(dir / "loop.out"), err = read_text(dir / "loop.err");
  // The loop's figures line, for BENCHMARKS.md section 11.
  std::istringstream lines(err);
  for (std::string l; std::getline(lines, l);)
    if (l.rfind("restart loop (", 0) == 0 || l.find("first new K at the recorder") != std::string::npos)
      std::cerr << "vehicle profile: " << l << "\n";
  ASSERT_TRUE(ended) << "the loop did not end within 330 s\n" << out << err;
  EXPECT_EQ(loop.exit_code(), 0) << out << err;
  EXPECT_NE(out.find("[  PASSED  ] 1 test"), std::string::npos) << out << err;
}

// ---- 2. stalls ----------------------------------------------------------------------------------

int run(const std::string& command) {
  const int status = std::system(command.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

pid_t read_pid(const std::string& file) {
  std::ifstream in(file);
  long pid = -1;
  in >> pid;
  return static_cast<pid_t>(pid);
}

/// Peak resident memory (VmHWM) of a live process, kB (-1 if it cannot be read).
long peak_rss_kb(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("VmHWM:", 0) == 0) return std::stol(line.substr(6));
  return -1;
}

/// Stamps of `ref` missing from `got` (both sorted by time), as "N rows t0-t1 s" runs.
template <class Row>
std::string missing_rows(const std::vector<Row>& got, const std::vector<Row>& ref, std::size_t& missing) {
  std::vector<double> have;
  for (const auto& r : got) have.push_back(r.t_s);
  std::sort(have.begin(), have.end());
  std::ostringstream out;
  missing = 0;
  std::size_t run_n = 0;
  double run_t0 = 0, run_t1 = 0;
  auto flush = [&] {
    if (run_n) out << " " << run_n << " rows t=" << run_t0 << "-" << run_t1 << " s;";
    run_n = 0;
  };
  for (const auto& r : ref) {
    const auto it = std::lower_bound(have.begin(), have.end(), r.t_s - 1e-9);
    const bool present = it != have.end() && std::abs(*it - r.t_s) <= 1e-9;
    if (present) {
      flush();
      continue;
    }
    ++missing;
    if (!run_n) run_t0 = r.t_s;
    run_t1 = r.t_s;
    ++run_n;
  }
  flush();
  return out.str();
}

/// pipe against ref: as many rows, then expect_same(pipe row, ref row, "<what> row <i>") on each
/// pair in turn, up to the first that fails fatally.
template <class Row, class ExpectSame>
void expect_each_row(const std::vector<Row>& pipe, const std::vector<Row>& ref, const char* what,
                     ExpectSame expect_same) {
  ASSERT_EQ(pipe.size(), ref.size());
  for (std::size_t i = 0; i < ref.size(); ++i)
    ASSERT_NO_FATAL_FAILURE(expect_same(pipe[i], ref[i], std::string(what) + " row " + std::to_string(i)));
}

/// The recorder's rows against odonav-offline's: every row present (the missing ones printed as
/// runs) and equal row by row (the pipeline test's 1e-9).
/// navigation: the navigation_position rows too (present, and equal to offline's).
void expect_rows_equal(const results::OutputRows& pipe, const results::OutputRows& ref, bool navigation = false) {
  std::size_t lost_mis = 0, lost_k = 0, lost_dr = 0;
  const std::string gaps_mis = missing_rows(pipe.misalignment, ref.misalignment, lost_mis);
  const std::string gaps_k = missing_rows(pipe.scale_factor, ref.scale_factor, lost_k);
  const std::string gaps_dr = missing_rows(pipe.dead_reckoning, ref.dead_reckoning, lost_dr);
  std::cerr << "rows missing against odonav-offline: misalignment " << lost_mis << "/" << ref.misalignment.size()
            << gaps_mis << " scale factor " << lost_k << "/" << ref.scale_factor.size() << gaps_k << " dead reckoning "
            << lost_dr << "/" << ref.dead_reckoning.size() << gaps_dr << "\n";
  EXPECT_EQ(lost_mis, 0u);
  EXPECT_EQ(lost_k, 0u);
  EXPECT_EQ(lost_dr, 0u);
  // How far the rows present are from offline's (matched by stamp), to say how large a difference is.
  auto differing = [](const auto& got, const auto& want, auto value, const char* what) {
    std::map<double, double> ref_of;
    for (const auto& r : want)
      if (const auto v = value(r)) ref_of[r.t_s] = *v;
    std::size_t n = 0;
    double max_rel = 0.0, first_t = 0.0, last_t = 0.0;
    for (const auto& r : got) {
      const auto v = value(r);
      const auto it = ref_of.find(r.t_s);
      if (!v || it == ref_of.end()) continue;
      const double rel = std::abs(*v - it->second) / std::max(std::abs(it->second), 1e-12);
      if (std::abs(*v - it->second) > 1e-9 * std::max(1.0, std::abs(it->second))) {
        if (!n) first_t = r.t_s;
        last_t = r.t_s;
        ++n;
        max_rel = std::max(max_rel, rel);
      }
    }
    std::cerr << what << " rows present but differing from offline: " << n;
    if (n) std::cerr << " (t=" << first_t << "-" << last_t << " s, max relative difference " << max_rel << ")";
    std::cerr << "\n";
  };
  differing(
      pipe.misalignment, ref.misalignment, [](const auto& r) { return std::optional<double>(r.heading_rad); },
      "misalignment heading");
  differing(
      pipe.scale_factor, ref.scale_factor, [](const auto& r) { return r.k_m_per_pulse; }, "scale factor");
  differing(
      pipe.dead_reckoning, ref.dead_reckoning, [](const auto& r) { return std::optional<double>(r.distance_m); },
      "dead-reckoning distance");
  if (navigation) {
    std::size_t lost_nav = 0;
    const std::string gaps_nav = missing_rows(pipe.navigation_position, ref.navigation_position, lost_nav);
    std::cerr << "navigation position rows missing against odonav-offline: " << lost_nav << "/"
              << ref.navigation_position.size() << gaps_nav << "\n";
    EXPECT_EQ(lost_nav, 0u);
    differing(
        pipe.navigation_position, ref.navigation_position,
        [](const auto& r) { return std::optional<double>(r.east_m); }, "navigation position east");
  }

  // Equal to the offline tool row by row (its tolerance: the pipeline test's 1e-9).
  constexpr double kTol = 1e-9;
  ASSERT_NO_FATAL_FAILURE(expect_each_row(pipe.misalignment, ref.misalignment, "misalignment",
                                          [&](const auto& a, const auto& b, const std::string& row) {
                                            ASSERT_NEAR(a.t_s, b.t_s, kTol) << row;
                                            ASSERT_NEAR(a.heading_rad, b.heading_rad, kTol) << row;
                                            ASSERT_NEAR(a.pitch_rad, b.pitch_rad, kTol) << row;
                                          }));
  ASSERT_NO_FATAL_FAILURE(expect_each_row(
      pipe.scale_factor, ref.scale_factor, "scale factor", [&](const auto& a, const auto& b, const std::string& row) {
        ASSERT_NEAR(a.t_s, b.t_s, kTol) << row;
        ASSERT_EQ(a.k_m_per_pulse.has_value(), b.k_m_per_pulse.has_value()) << row;
        if (b.k_m_per_pulse) {
          ASSERT_NEAR(*a.k_m_per_pulse, *b.k_m_per_pulse, kTol * *b.k_m_per_pulse) << row;
        }
        ASSERT_EQ(a.samples_accepted, b.samples_accepted) << row;
      }));
  ASSERT_NO_FATAL_FAILURE(expect_each_row(pipe.dead_reckoning, ref.dead_reckoning, "dead-reckoning",
                                          [&](const auto& a, const auto& b, const std::string& row) {
                                            ASSERT_NEAR(a.t_s, b.t_s, kTol) << row;
                                            ASSERT_NEAR(a.lat_rad, b.lat_rad, kTol) << row;
                                            ASSERT_NEAR(a.lon_rad, b.lon_rad, kTol) << row;
                                            ASSERT_NEAR(a.distance_m, b.distance_m, kTol) << row;
                                            ASSERT_NEAR(a.k_m_per_pulse, b.k_m_per_pulse, kTol * b.k_m_per_pulse)
                                                << row;
                                          }));
  if (!navigation) return;
  ASSERT_FALSE(ref.navigation_position.empty());
  expect_each_row(pipe.navigation_position, ref.navigation_position, "navigation position",
                  [&](const auto& a, const auto& b, const std::string& row) {
                    ASSERT_NEAR(a.t_s, b.t_s, kTol) << row;
                    ASSERT_NEAR(a.lat_rad, b.lat_rad, kTol) << row;
                    ASSERT_NEAR(a.lon_rad, b.lon_rad, kTol) << row;
                    ASSERT_NEAR(a.east_m, b.east_m, kTol) << row;
                    ASSERT_NEAR(a.north_m, b.north_m, kTol) << row;
                    ASSERT_EQ(a.status, b.status) << row;
                  });
}

/// The recorder's rows in `out` against odonav-offline's in `offline_dir` (expect_rows_equal).
void expect_rows_equal_offline(const std::string& out, const std::string& offline_dir, bool navigation = false) {
  expect_rows_equal(results::read_output_rows(out), results::read_output_rows(offline_dir), navigation);
}

TEST_F(Faults, FiveSecondStallsOfIdentificationDeadReckoningAndGatewayLoseNothing) {
  constexpr int kDomain = 161;
  const std::string out = fresh_dir("test-faults", "stalls").string();
  const std::string logs = out + "/logs";
  const std::string script = std::string(ODONAV_SOURCE_DIR) + "/deploy/launch";
  // 150 s of data at 3x: 50 s of wall time, the three stalls in the middle of it. At 3x a 5 s stall
  // is 15 s of data: within the 30 s histories, and the launcher's 30 s wait for inputs lets every
  // consumer wait for a stalled producer instead of going on without it.
  // For the figures of longer stalls (BENCHMARKS.md section 11) the same run takes, from the
  // environment: ODONAV_FAULTS_STALL_S (5), ODONAV_FAULTS_STALL_COMPONENTS (comma-separated, the
  // gateway last; default identification, dead reckoning, gateway), ODONAV_FAULTS_SPEED (3) and
  // ODONAV_FAULTS_DURATION_S (150).
  auto env_or = [](const char* name, const std::string& fallback) {
    const char* v = std::getenv(name);
    return std::string(v && *v ? v : fallback.c_str());
  };
  const int stall_s = std::stoi(env_or("ODONAV_FAULTS_STALL_S", "5"));
  const std::string speed = env_or("ODONAV_FAULTS_SPEED", "3");
  const std::string duration = env_or("ODONAV_FAULTS_DURATION_S", "150");
  ChildProcess launcher(
      "/bin/bash",
      {script, "--build-dir", ODONAV_BINARY_DIR, "--source", "sim:ring", "--duration-s", duration, "--seed", "4",
       "--speed", speed, "--domain", std::to_string(kDomain), "--profile", profile_file(), "--out", out},
      out + ".launch.log", out + ".launch.log");
  ASSERT_TRUE(launcher.started());

  odonav::dds::Participant participant(participant_options(kDomain));
  TimedCollector<msg::DeadReckoning> dr(participant, topics::kDeadReckoning, topics::kDeadReckoningReaderProfile);

  // The gateway's pid file appears when the launcher starts it (after every producer matched).
  const auto t0 = std::chrono::steady_clock::now();
  while (!fs::exists(logs + "/odonav-gateway.pid") && std::chrono::steady_clock::now() - t0 < seconds(90))
    std::this_thread::sleep_for(milliseconds(100));
  ASSERT_TRUE(fs::exists(logs + "/odonav-gateway.pid")) << read_text(out + ".launch.log");
  std::this_thread::sleep_for(seconds(4));

  struct Stall {
    std::string component;
    double cont_s = 0;
  };
  std::vector<Stall> stalls;
  {
    std::stringstream list(
        env_or("ODONAV_FAULTS_STALL_COMPONENTS", "odonav-identification,odonav-dead-reckoning,odonav-gateway"));
    for (std::string c; std::getline(list, c, ',');) stalls.push_back({c});
  }
  ASSERT_FALSE(stalls.empty());
  for (auto& s : stalls) {
    const pid_t pid = read_pid(logs + "/" + s.component + ".pid");
    ASSERT_GT(pid, 0) << s.component;
    std::cerr << "SIGSTOP " << s.component << " (pid " << pid << ") for " << stall_s << " s\n";
    ASSERT_EQ(::kill(pid, SIGSTOP), 0) << s.component;
    std::this_thread::sleep_for(seconds(stall_s));
    ASSERT_EQ(::kill(pid, SIGCONT), 0) << s.component;
    s.cont_s = steady_s();
    std::this_thread::sleep_for(seconds(4));
  }
  // The flow after the last stall (the gateway's): how long until dead reckoning, at the end of the
  // chain, produced again (printed, not asserted: wall clock).
  {
    const auto items = dr.items();
    for (const auto& i : items)
      if (i.received_s > stalls.back().cont_s) {
        std::cerr << "first DR output " << i.received_s - stalls.back().cont_s << " s after the SIGCONT of "
                  << stalls.back().component << "\n";
        break;
      }
  }
  // After the gateway's stall, dead reckoning (at the end of the chain) produced again.
  const auto dr_items = dr.items();
  const std::size_t after_gateway = static_cast<std::size_t>(std::count_if(
      dr_items.begin(), dr_items.end(), [&](const auto& i) { return i.received_s > stalls.back().cont_s; }));
  std::cerr << "DR outputs received in the 4 s after the SIGCONT of " << stalls.back().component << ": "
            << after_gateway << "\n";
  // 4 s at 3x real time is 1 200 outputs at 100 Hz: most of them, if the flow resumed at once.
  EXPECT_GT(after_gateway, 600u);

  std::map<std::string, long> rss;
  for (const char* c :
       {"odonav-gateway", "odonav-identification", "odonav-dead-reckoning", "odonav-calibration", "odonav-recorder"})
    rss[c] = peak_rss_kb(read_pid(logs + "/" + c + ".pid"));

  std::cerr << "peak RSS (kB, VmHWM before the end):";
  for (const auto& [c, kb] : rss) std::cerr << " " << c << " " << kb;
  std::cerr << "\n";

  // The launcher supervises like the systemd units: dead reckoning killed now is started again
  // (its checkpoint in out/state) and resumes; the gateway's lost reader is that dead instance's.
  const pid_t dr_pid = read_pid(logs + "/odonav-dead-reckoning.pid");
  ASSERT_GT(dr_pid, 0);
  ASSERT_EQ(::kill(dr_pid, SIGKILL), 0);
  std::cerr << "SIGKILL odonav-dead-reckoning (pid " << dr_pid << ")\n";

  ASSERT_TRUE(launcher.wait_exit(seconds(240 + static_cast<int>(std::stod(duration) / std::stod(speed)))))
      << read_text(out + ".launch.log");
  ASSERT_EQ(launcher.exit_code(), 0) << read_text(out + ".launch.log");
  const std::string launch_log = read_text(out + ".launch.log");
  EXPECT_NE(launch_log.find("odonav-dead-reckoning died while waiting for odonav-gateway (killed by signal 9); "
                            "started again (restart 1 of at most 5)"),
            std::string::npos)
      << launch_log;
  EXPECT_NE(launch_log.find("1 restart(s) during the run"), std::string::npos) << launch_log;
  EXPECT_NE(read_text(logs + "/odonav-dead-reckoning.log").find("restored"), std::string::npos)
      << read_text(logs + "/odonav-dead-reckoning.log");

  const std::string offline_dir = out + "/offline-check";
  ASSERT_EQ(run(binary("odonav-offline") + " " + out + "/dataset --out " + offline_dir + " >" + out +
                "/offline-check.log 2>&1"),
            0)
      << read_text(out + "/offline-check.log");
  expect_rows_equal_offline(out, offline_dir);
}

// ---- 3. kill -9 + restart: the downtime is caught up ----------------------------------------------

const char* health_level_name_of(const msg::Health& h) {
  return h.level() == 0 ? "OK" : h.level() == 1 ? "WARN" : "ERROR";
}

double health_counter(const msg::Health& h, const std::string& name) {
  for (const auto& c : h.counters())
    if (c.name() == name) return c.value();
  return std::nan("");
}

/// The ring drive the gateway replays (same seed and duration), as a dataset in dir/dataset.
void simulate_ring(const std::string& dir, const char* seed, const char* duration_s) {
  ASSERT_EQ(run(binary("odonav-simulator") + " ring --out " + dir + "/dataset --seed " + seed + " --duration-s " +
                duration_s + " >" + dir + "/sim.log 2>&1"),
            0)
      << read_text(dir + "/sim.log");
}

/// Waits (at most 60 s) until the recorder logging into recorder_log matched every producer.
void wait_for_producers(const std::string& recorder_log) {
  const auto t0 = std::chrono::steady_clock::now();
  while (read_text(recorder_log).find("every producer matched") == std::string::npos &&
         std::chrono::steady_clock::now() - t0 < seconds(60))
    std::this_thread::sleep_for(milliseconds(100));
}

/// The gateway replaying the simulated ring at 3x real time, once 4 GNSS readers matched: the
/// calibration, the identification, dead reckoning and the recorder.
std::unique_ptr<ChildProcess> start_ring_gateway(int domain, const char* seed, const char* duration_s,
                                                 const std::string& dir) {
  return start_logged(
      "odonav-gateway",
      common_args(domain, {"--source", "sim:ring", "--seed", seed, "--duration-s", duration_s, "--speed", "3",
                           "--wait-for-readers", "4", "--wait-for-readers-timeout-s", "60", "--tolerate-lost-readers"}),
      dir + "/gateway.log");
}

/// A kill -9 of one component once the K passes `at_t_s` (event time), restarted 2 s later.
struct Kill {
  std::string component;  ///< odonav-identification, odonav-calibration or odonav-dead-reckoning
  double at_t_s;
};

/// 120 s of the ring at 3x real time (40 s of wall time) with several components killed (SIGKILL)
/// at different times of the same drive, each between two of its checkpoints (every 5 s of event
/// time) and restarted 2 s later (6 s of data). With its --state-dir (`checkpointed`) each resumes
/// from its last checkpoint, the producers hand it their history, it processes again what it had
/// published since (the consumers skip those repeats) and publishes the outputs of its downtime
/// late. Faster than real time the consumers wait for it (--max-wait-s 30), so the recorder's rows,
/// misalignment, K, dead reckoning and navigation position alike, must all be there and equal
/// odonav-offline's. Without a checkpoint (the figures of docs/DESIGN_DECISIONS.md) a restarted
/// component starts again from nothing, and the comparison fails on the rows it lost or changed.
void kill_nine_and_restart_catches_up(int domain, const std::vector<Kill>& kills, bool checkpointed) {
  constexpr const char* kSeed = "6";
  constexpr const char* kDuration = "120";
  std::string name = "catch-up";
  for (const Kill& k : kills) name += "-" + k.component.substr(7);
  const std::string dir = fresh_dir("test-faults", name).string();
  const std::string out = dir + "/out";
  const std::string state = dir + "/state";
  const std::string arm = lever_arm("ring");
  char nominal[64];
  std::snprintf(nominal, sizeof nominal, "%.17g", simulator::scenario_config("ring").k_nominal_m_per_pulse);
  ASSERT_NO_FATAL_FAILURE(simulate_ring(dir, kSeed, kDuration));

  odonav::dds::Participant participant(participant_options(domain));
  TimedCollector<msg::ScaleFactor> k(participant, topics::kScaleFactor, topics::kScaleFactorRecorderReaderProfile);
  TimedCollector<msg::Health> health(participant, topics::kHealth, topics::kHealthReaderProfile);
  TimedCollector<msg::Misalignment> misalignment(participant, topics::kMisalignment, topics::kEstimateReaderProfile);
  TimedCollector<msg::DeadReckoning> dr(participant, topics::kDeadReckoning, topics::kDeadReckoningReaderProfile);

  const std::vector<std::string> node =
      common_args(domain, {"--max-wait-s", "30", "--lever-arm", arm, "--nominal-k", nominal});
  auto with = [&](std::vector<std::string> base, std::vector<std::string> extra) {
    base.insert(base.end(), extra.begin(), extra.end());
    return base;
  };
  // The identification always checkpoints (so a calibration's restart is seen through its K); the
  // killed components do when `checkpointed`.
  auto killed = [&](const std::string& c) {
    return std::any_of(kills.begin(), kills.end(), [&](const Kill& x) { return x.component == c; });
  };
  const std::vector<std::string> checkpoint = {"--state-dir", state,         "--checkpoint-every-s",
                                               "5",           "--log-level", "info"};
  auto checkpoint_if = [&](bool on) { return on ? checkpoint : std::vector<std::string>{}; };
  std::map<std::string, std::vector<std::string>> args;
  args["odonav-dead-reckoning"] = with(node, checkpoint_if(checkpointed && killed("odonav-dead-reckoning")));
  args["odonav-calibration"] = with(common_args(domain, {"--max-wait-s", "30", "--lever-arm", arm}),
                                    checkpoint_if(checkpointed && killed("odonav-calibration")));
  args["odonav-identification"] = with(node, checkpoint_if(checkpointed || !killed("odonav-identification")));
  std::map<std::string, int> starts;
  std::map<std::string, std::unique_ptr<ChildProcess>> proc;
  auto start = [&](const std::string& c) {
    proc[c] = start_logged(c, args[c], dir + "/" + c.substr(7) + "-" + std::to_string(++starts[c]) + ".log");
    return proc[c]->started();
  };
  auto logs = [&] {
    std::string all;
    for (const auto& [c, n] : starts)
      for (int i = 1; i <= n; ++i) all += read_text(dir + "/" + c.substr(7) + "-" + std::to_string(i) + ".log");
    return all;
  };
  auto recorder = start_logged("odonav-recorder", common_args(domain, {"--out", out, "--log-level", "info"}),
                               dir + "/recorder.log");
  ASSERT_TRUE(recorder->started() && start("odonav-dead-reckoning") && start("odonav-calibration") &&
              start("odonav-identification"));
  wait_for_producers(dir + "/recorder.log");
  for (const auto& [c, p] : proc) ASSERT_TRUE(p->running()) << logs();
  auto gateway = start_ring_gateway(domain, kSeed, kDuration, dir);
  ASSERT_TRUE(gateway->started());

  // ODONAV_FAULTS_DOWN_S (2): how long each stays down (wall clock); beyond 10 s at 3x real time the
  // downtime exceeds the producers' 30 s history, and the test then fails on the rows lost.
  const char* down_env = std::getenv("ODONAV_FAULTS_DOWN_S");
  const int down_s = down_env && *down_env ? std::stoi(down_env) : 2;
  std::map<std::string, double> last_published_before_kill_s;
  for (const Kill& kill : kills) {
    ASSERT_TRUE(
        k.wait_until([&](const auto& v) { return !v.empty() && stamp_s(v.back().sample) >= kill.at_t_s; }, seconds(90)))
        << logs() << read_text(dir + "/gateway.log");
    const std::string& c = kill.component;
    proc[c]->signal(SIGKILL);
    ASSERT_TRUE(proc[c]->wait_exit(seconds(5)));
    std::this_thread::sleep_for(seconds(down_s));
    // What the killed process published, read once its last datagrams have arrived (it may have
    // published, and checkpointed, a few more outputs between the wait above and the signal).
    if (c == "odonav-identification") {
      last_published_before_kill_s[c] = stamp_s(k.items().back().sample);
    } else if (c == "odonav-calibration") {
      const auto m = misalignment.items();
      last_published_before_kill_s[c] = m.empty() ? 0.0 : stamp_s(m.back().sample);
    } else {
      const auto d = dr.items();
      last_published_before_kill_s[c] = d.empty() ? 0.0 : stamp_s(d.back().sample);
    }
    ASSERT_TRUE(start(c));
    std::cerr << "killed " << c << " at K t=" << kill.at_t_s
              << " s (its last output t=" << last_published_before_kill_s[c] << " s), restarted " << down_s
              << " s later\n";
  }

  ASSERT_TRUE(gateway->wait_exit(seconds(150))) << read_text(dir + "/gateway.log");
  EXPECT_EQ(gateway->exit_code(), 0) << read_text(dir + "/gateway.log");
  // Data-flow order, each one's inputs complete when it is told to stop (as deploy/launch does).
  for (const char* c : {"odonav-calibration", "odonav-identification", "odonav-dead-reckoning"}) {
    proc[c]->signal(SIGINT);
    EXPECT_TRUE(proc[c]->wait_exit(seconds(60))) << c;
    EXPECT_EQ(proc[c]->exit_code(), 0) << c;
  }
  recorder->signal(SIGINT);
  EXPECT_TRUE(recorder->wait_exit(seconds(60)));
  EXPECT_EQ(recorder->exit_code(), 0);

  const std::string offline_dir = dir + "/offline";
  ASSERT_EQ(
      run(binary("odonav-offline") + " " + dir + "/dataset --out " + offline_dir + " >" + dir + "/offline.log 2>&1"), 0)
      << read_text(dir + "/offline.log");
  if (!checkpointed) {
    expect_rows_equal_offline(out, offline_dir, true);
    return;
  }
  // Each restarted instance says what it caught up, and that nothing was lost.
  const auto hs = health.items();
  for (const Kill& kill : kills) {
    const std::string& restarted = kill.component;
    const msg::Health* last = nullptr;
    for (const auto& h : hs)
      if (h.sample.component() == restarted && !std::isnan(health_counter(h.sample, "catch_up_outputs")))
        last = &h.sample;
    ASSERT_NE(last, nullptr) << "no health of the restarted " << restarted << " with catch-up counters";
    std::cerr << restarted << "'s last health: " << health_level_name_of(*last) << " \"" << last->reason() << "\"\n";
    std::cerr << "restarted " << restarted << ": " << health_counter(*last, "catch_up_outputs")
              << " outputs caught up, t=" << health_counter(*last, "catch_up_first_t_s") << "-"
              << health_counter(*last, "catch_up_last_t_s") << " s, lost " << health_counter(*last, "catch_up_lost_s")
              << " s, restored checkpoint t=" << health_counter(*last, "checkpoint_restored_t_s") << " s\n";
    EXPECT_EQ(health_counter(*last, "catch_up_lost_s"), 0.0) << restarted;
    // Which outputs count as catch-up is a label decided on the steady clock (printed above, not
    // asserted: on a loaded machine the history takes longer than the settling second to arrive);
    // what is asserted: it resumed from a checkpoint not newer than what it had published (older
    // as a rule: the kills fall between two checkpoints of the estimators; dead reckoning's follow
    // its output batches), and every row after it is there and equal to offline's (below).
    EXPECT_GT(health_counter(*last, "checkpoint_restored_t_s"), 0.0) << restarted;
    EXPECT_LE(health_counter(*last, "checkpoint_restored_t_s"), last_published_before_kill_s[restarted]) << restarted;
  }
  expect_rows_equal_offline(out, offline_dir, true);
  // Nothing lost, and the recording says so: gaps.csv is there with its header only.
  EXPECT_EQ(read_text(out + "/gaps.csv"), "topic,first_missing_t_s,last_missing_t_s,count,reason\n");
}

/// ODONAV_FAULTS_RESTART=<component> runs instead one kill of that component (at the time it has in
/// these runs) without its --state-dir: the "before" figures of docs/DESIGN_DECISIONS.md.
bool before_figure_instead(int domain) {
  const char* restart_env = std::getenv("ODONAV_FAULTS_RESTART");
  if (!restart_env || !*restart_env) return false;
  const std::string c = restart_env;
  const double at_t_s = c == "odonav-identification" ? 32.5 : c == "odonav-calibration" ? 52.5 : 75.0;
  kill_nine_and_restart_catches_up(domain, {{c, at_t_s}}, false);
  return true;
}

TEST_F(Faults, KillNineAndRestartOfTheIdentificationAndDeadReckoningCatchesUpEveryRowEqualToOffline) {
  if (before_figure_instead(195)) return;
  kill_nine_and_restart_catches_up(195, {{"odonav-identification", 32.5}, {"odonav-dead-reckoning", 75.0}}, true);
}

TEST_F(Faults, KillNineAndRestartOfTheCalibrationAndDeadReckoningCatchesUpEveryRowEqualToOffline) {
  if (std::getenv("ODONAV_FAULTS_RESTART") && *std::getenv("ODONAV_FAULTS_RESTART"))
    GTEST_SKIP() << "before figures: the other run";
  kill_nine_and_restart_catches_up(196, {{"odonav-calibration", 52.5}, {"odonav-dead-reckoning", 95.0}}, true);
}

// ---- 4. a loss named: the identification killed for good ----------------------------------------

/// gaps.csv rows (the header checked).
std::vector<GapsCsvRow> read_gaps(const std::string& path) {
  std::istringstream in(read_text(path));
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "topic,first_missing_t_s,last_missing_t_s,count,reason") << path;
  std::vector<GapsCsvRow> rows;
  while (std::getline(in, line)) {
    std::istringstream f(line);
    GapsCsvRow g;
    std::string first, last, count;
    std::getline(f, g.topic, ',');
    std::getline(f, first, ',');
    std::getline(f, last, ',');
    std::getline(f, count, ',');
    std::getline(f, g.reason);
    g.first_s = std::stod(first);
    g.last_s = std::stod(last);
    g.count = std::stoull(count);
    rows.push_back(g);
  }
  return rows;
}

TEST_F(Faults, AnIdentificationKilledForGoodIsNamedInGapsCsvAndInDeadReckoningHealth) {
  // 60 s of the ring at 3x real time; the identification is killed (SIGKILL) once its K passes
  // t = 25 s and never comes back. The recorder is killed too (SIGKILL) at t = 40 s and restarted
  // 2 s later (6 s of data) with the same command: it resumes its recording, and the producers'
  // history gives it the rows of its downtime, so the recording still lacks only the K. Dead reckoning (--max-wait-s 2) goes on on the last K: every
  // output from the first GNSS epoch without a K (+ the 0.2 s hold-off) on is on a held K, and its
  // health says which (counters and reason). The recording names the loss in gaps.csv: the GNSS
  // epochs after the last scale-factor row, to the end, counted against the dataset's gnss.csv
  // (the same simulation), and nothing else.
  constexpr int kDomain = 162;
  constexpr const char* kSeed = "7";
  constexpr const char* kDuration = "60";
  const std::string dir = fresh_dir("test-faults", "killed-for-good").string();
  const std::string out = dir + "/out";
  const std::string arm = lever_arm("ring");
  ASSERT_NO_FATAL_FAILURE(simulate_ring(dir, kSeed, kDuration));

  odonav::dds::Participant participant(participant_options(kDomain));
  TimedCollector<msg::ScaleFactor> k(participant, topics::kScaleFactor, topics::kScaleFactorRecorderReaderProfile);
  TimedCollector<msg::Health> health(participant, topics::kHealth, topics::kHealthReaderProfile);
  TimedCollector<msg::Misalignment> misalignment(participant, topics::kMisalignment, topics::kEstimateReaderProfile);
  const std::vector<std::string> node = common_args(kDomain, {"--max-wait-s", "2", "--lever-arm", arm});
  const std::vector<std::string> recorder_args = common_args(kDomain, {"--out", out, "--log-level", "info"});
  auto recorder = start_logged("odonav-recorder", recorder_args, dir + "/recorder.log");
  auto dead_reckoning = start_logged("odonav-dead-reckoning", node, dir + "/dr.log");
  auto calibration = start_logged("odonav-calibration", node, dir + "/calibration.log");
  auto identification = start_logged("odonav-identification", node, dir + "/id.log");
  ASSERT_TRUE(recorder->started() && dead_reckoning->started() && calibration->started() && identification->started());
  wait_for_producers(dir + "/recorder.log");
  auto gateway = start_ring_gateway(kDomain, kSeed, kDuration, dir);
  ASSERT_TRUE(gateway->started());
  ASSERT_TRUE(k.wait_until([](const auto& v) { return !v.empty() && stamp_s(v.back().sample) >= 25.0; }, seconds(90)))
      << read_text(dir + "/id.log") << read_text(dir + "/gateway.log");
  identification->signal(SIGKILL);
  ASSERT_TRUE(identification->wait_exit(seconds(5)));
  ASSERT_TRUE(misalignment.wait_until([](const auto& v) { return !v.empty() && stamp_s(v.back().sample) >= 40.0; },
                                      seconds(90)))
      << read_text(dir + "/calibration.log");
  recorder->signal(SIGKILL);
  ASSERT_TRUE(recorder->wait_exit(seconds(5)));
  const double recorder_killed_s = stamp_s(misalignment.items().back().sample);
  std::this_thread::sleep_for(seconds(2));
  recorder = start_logged("odonav-recorder", recorder_args, dir + "/recorder-2.log");
  ASSERT_TRUE(recorder->started());

  ASSERT_TRUE(gateway->wait_exit(seconds(120))) << read_text(dir + "/gateway.log");
  for (auto* c : {&calibration, &dead_reckoning, &recorder}) {
    (*c)->signal(SIGINT);
    EXPECT_TRUE((*c)->wait_exit(seconds(60)));
    EXPECT_EQ((*c)->exit_code(), 0);
  }

  const results::OutputRows rows = results::read_output_rows(out);
  ASSERT_FALSE(rows.scale_factor.empty());
  ASSERT_FALSE(rows.dead_reckoning.empty());
  const double last_k_s = rows.scale_factor.back().t_s;
  const Dataset data = read_dataset(dir + "/dataset", BadRowPolicy::kFail);
  std::vector<double> lost;
  for (const auto& g : data.gnss)
    if (g.t_s > last_k_s + 1e-6) lost.push_back(g.t_s);
  ASSERT_GT(lost.size(), 100u) << "killed at t=" << last_k_s << " s of " << kDuration << " s";
  std::cerr << "last K row t=" << last_k_s << " s; GNSS epochs after it: " << lost.size() << " (t=" << lost.front()
            << "-" << lost.back() << " s)\n";

  const auto gaps = read_gaps(out + "/gaps.csv");
  for (const auto& g : gaps)
    std::cerr << "gaps.csv: " << g.topic << " t=" << g.first_s << "-" << g.last_s << " s, " << g.count << ": "
              << g.reason << "\n";
  ASSERT_EQ(gaps.size(), 1u) << read_text(out + "/gaps.csv");
  EXPECT_EQ(gaps[0].topic, topics::kScaleFactor.name);
  EXPECT_NEAR(gaps[0].first_s, lost.front(), 1e-6);
  EXPECT_NEAR(gaps[0].last_s, lost.back(), 1e-6);
  EXPECT_EQ(gaps[0].count, lost.size());
  const std::string restarted_log = read_text(dir + "/recorder-2.log");
  EXPECT_NE(restarted_log.find("gaps.csv: 1 spans missing: rt/odonav/scale_factor " + std::to_string(lost.size())),
            std::string::npos)
      << restarted_log;

  // The restarted recorder adopted the killed one's rows (its log says which), removed its
  // temporaries, and every row but the K after the identification's death is there and equal to
  // odonav-offline's: misalignment, K, dead reckoning and navigation position up to the first
  // output on the held K (offline goes on identifying K, so the positions differ from there on),
  // and present after it.
  std::cerr << "recorder killed at t=" << recorder_killed_s << " s and restarted 2 s later\n";
  for (const char* file : {"misalignment.csv", "scale_factor.csv", "dead_reckoning.csv", "navigation_position.csv"})
    EXPECT_NE(restarted_log.find(std::string("rows of ") + file + " from " + out + "/" + file + ".tmp-"),
              std::string::npos)
        << file << " not adopted:\n"
        << restarted_log;
  for (const auto& entry : fs::directory_iterator(out))
    EXPECT_EQ(entry.path().filename().string().find(".tmp-"), std::string::npos) << entry.path() << " left over";
  EXPECT_FALSE(fs::exists(out + "/.odonav-recording")) << "the finished recording still has its marker";
  const std::string offline_dir = dir + "/offline";
  ASSERT_EQ(
      run(binary("odonav-offline") + " " + dir + "/dataset --out " + offline_dir + " >" + dir + "/offline.log 2>&1"), 0)
      << read_text(dir + "/offline.log");
  results::OutputRows ref = results::read_output_rows(offline_dir);
  results::OutputRows got = rows;
  std::cerr << "recording: " << got.misalignment.size() << " misalignment, " << got.scale_factor.size() << " K, "
            << got.dead_reckoning.size() << " DR, " << got.navigation_position.size()
            << " navigation rows; odonav-offline: " << ref.misalignment.size() << ", " << ref.scale_factor.size()
            << ", " << ref.dead_reckoning.size() << ", " << ref.navigation_position.size() << "\n";
  ref.scale_factor.erase(std::remove_if(ref.scale_factor.begin(), ref.scale_factor.end(),
                                        [&](const auto& r) { return r.t_s > last_k_s + 1e-6; }),
                         ref.scale_factor.end());
  const double held_from_s = lost.front() + 0.2 - 1e-6;  // the first output on the held K
  std::size_t dr_after = 0, nav_after = 0;
  std::set<double> got_dr_after, got_nav_after;
  for (const auto& r : got.dead_reckoning)
    if (r.t_s >= held_from_s) got_dr_after.insert(r.t_s);
  for (const auto& r : got.navigation_position)
    if (r.t_s >= held_from_s) got_nav_after.insert(r.t_s);
  for (const auto& r : ref.dead_reckoning)
    if (r.t_s >= held_from_s) dr_after += got_dr_after.count(r.t_s) == 0 ? 1 : 0;
  for (const auto& r : ref.navigation_position)
    if (r.t_s >= held_from_s) nav_after += got_nav_after.count(r.t_s) == 0 ? 1 : 0;
  EXPECT_EQ(dr_after, 0u) << "dead-reckoning rows missing after the K held";
  EXPECT_EQ(nav_after, 0u) << "navigation-position rows missing after the K held";
  EXPECT_EQ(got_dr_after.size(),
            got.dead_reckoning.size() - std::count_if(got.dead_reckoning.begin(), got.dead_reckoning.end(),
                                                      [&](const auto& r) { return r.t_s < held_from_s; }))
      << "dead-reckoning rows not in time order or repeated";
  auto before_held = [&](auto& v) {
    v.erase(std::remove_if(v.begin(), v.end(), [&](const auto& r) { return r.t_s >= held_from_s; }), v.end());
  };
  before_held(ref.dead_reckoning);
  before_held(got.dead_reckoning);
  before_held(ref.navigation_position);
  before_held(got.navigation_position);
  ASSERT_NO_FATAL_FAILURE(expect_rows_equal(got, ref));
  ASSERT_EQ(got.navigation_position.size(), ref.navigation_position.size());
  for (std::size_t i = 0; i < ref.navigation_position.size(); ++i) {
    ASSERT_NEAR(got.navigation_position[i].t_s, ref.navigation_position[i].t_s, 1e-9) << "navigation row " << i;
    ASSERT_NEAR(got.navigation_position[i].lat_rad, ref.navigation_position[i].lat_rad, 1e-9) << "navigation row " << i;
    ASSERT_NEAR(got.navigation_position[i].lon_rad, ref.navigation_position[i].lon_rad, 1e-9) << "navigation row " << i;
    ASSERT_EQ(got.navigation_position[i].status, ref.navigation_position[i].status) << "navigation row " << i;
  }

  // Dead reckoning: its last health with the held-K counters names the span and the K held.
  const msg::Health* last = nullptr;
  const auto hs = health.items();
  for (const auto& h : hs)
    if (h.sample.component() == "odonav-dead-reckoning" && !std::isnan(health_counter(h.sample, "held_k_first_t_s")))
      last = &h.sample;
  ASSERT_NE(last, nullptr) << "no dead-reckoning health with a held K";
  const double first_s = health_counter(*last, "held_k_first_t_s"), last_s = health_counter(*last, "held_k_last_t_s");
  std::cerr << "dead reckoning: " << health_counter(*last, "outputs_on_held_k")
            << " outputs on the K of t=" << health_counter(*last, "held_k_epoch_t_s") << " s held, t=" << first_s << "-"
            << last_s << " s; \"" << last->reason() << "\"\n";
  EXPECT_NEAR(health_counter(*last, "held_k_epoch_t_s"), last_k_s, 1e-6);
  // The first output at or after the first epoch without K + the hold-off (0.2 s - 1 us).
  const double applies_s = lost.front() + 0.2 - 1e-6;
  const auto first_held = std::lower_bound(rows.dead_reckoning.begin(), rows.dead_reckoning.end(), applies_s,
                                           [](const auto& r, double t) { return r.t_s < t; });
  ASSERT_NE(first_held, rows.dead_reckoning.end());
  EXPECT_NEAR(first_s, first_held->t_s, 1e-6);
  // Every output of the span counted, none twice.
  const auto in_span = std::count_if(rows.dead_reckoning.begin(), rows.dead_reckoning.end(),
                                     [&](const auto& r) { return r.t_s >= first_s - 1e-6 && r.t_s <= last_s + 1e-6; });
  EXPECT_EQ(health_counter(*last, "outputs_on_held_k"), static_cast<double>(in_span));
  // While it ran (before "stopping"), its health reason named the K held.
  char held_text[96];
  std::snprintf(held_text, sizeof held_text, "use the K of t=%.1f s held: identification silent", last_k_s);
  std::string reasons;
  bool told = false;
  for (const auto& h : hs)
    if (h.sample.component() == "odonav-dead-reckoning" && h.sample.reason().find(held_text) != std::string::npos) {
      told = true;
      reasons = h.sample.reason();
    }
  EXPECT_TRUE(told) << "no dead-reckoning health saying '" << held_text << "'";
  std::cerr << "its health while it went on: \"" << reasons << "\"\n";
}

}  // namespace
