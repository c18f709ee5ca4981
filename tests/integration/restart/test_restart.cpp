// odonav-identification restart (it resumes its K instead of re-converging), as processes on loopback
// DDS (domains 102-105): the gateway drives a simulated ring course in accelerated real time,
// odonav-identification checkpoints into a state directory.
//   1. corrupt checkpoints (garbage, then a truncated real one) are moved aside, the node starts
//      from nominal and its health says so.
//   2. a re-sent stream after a restore is not counted twice.
//   3. late reader after a restart: the scale-factor writer is TRANSIENT_LOCAL and the restored K
//      is published at once; killed and restarted with no input at all, it serves a reader created
//      after the restart the K of its checkpoint, equal to what it had published for that epoch.
// A kill -9 mid-drive and its exact catch-up (every row equal to odonav-offline) is tested with the
// other faults in tests/integration/faults.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "shm_clean_test.hpp"
#include "../nodes/node_test_support.hpp"
#include "odonav/identification/checkpoint.hpp"
#include "odonav/msg/ScaleFactor.h"

namespace {

using namespace odonav;
using namespace odonav::test;
namespace fs = std::filesystem;
using std::chrono::milliseconds;
using std::chrono::seconds;

constexpr const char* kIdentification = "odonav-identification";

/// This suite's scratch folder for one test (as a string: the tests build paths with +).
std::string suite_dir(const std::string& name) { return fresh_dir("test-restart", name).string(); }

double stamp_s(const msg::ScaleFactor& m) { return odonav::dds::to_seconds(m.header().stamp()); }

/// The latest estimate with a value (k > 0) among `k[0..n)`.
std::optional<msg::ScaleFactor> last_valid(const std::vector<msg::ScaleFactor>& k, std::size_t n) {
  for (std::size_t i = std::min(n, k.size()); i-- > 0;)
    if (k[i].k_m_per_pulse() > 0.0) return k[i];
  return std::nullopt;
}

std::vector<msg::Health> health_of(const std::vector<msg::Health>& all, const std::string& component) {
  std::vector<msg::Health> out;
  for (const auto& h : all)
    if (h.component() == component) out.push_back(h);
  return out;
}

class IdentificationRestart : public odonav::test::ShmCleanTest {
 protected:
  /// The GNSS antenna lever arm of the simulated vehicle, as deploy/launch passes it from meta.json
  /// (without it K wobbles in every turn by more than the tolerances below).
  static std::string lever_arm() {
    const Eigen::Vector3d l = simulator::scenario_config("ring").lever_arm_m;
    char buf[96];
    std::snprintf(buf, sizeof buf, "%.17g,%.17g,%.17g", l.x(), l.y(), l.z());
    return buf;
  }
  std::vector<std::string> identification_args(int domain, const std::string& state_dir) const {
    return node_args(
        domain, 2.0,
        {"--state-dir", state_dir, "--checkpoint-every-s", "5", "--lever-arm", lever_arm(), "--log-level", "info"});
  }
  std::vector<std::string> gateway_args(int domain, double duration_s, const std::string& speed) const {
    return node_args(domain, 2.0,
                     {"--source", "sim:ring", "--seed", "3", "--duration-s", std::to_string(duration_s), "--speed",
                      speed, "--wait-for-readers", "2", "--wait-for-readers-timeout-s", "30",
                      // The identification is killed on purpose while the gateway publishes.
                      "--tolerate-lost-readers"});
  }
};

TEST_F(IdentificationRestart, CorruptCheckpointsAreMovedAsideAndTheNodeStartsFromNominal) {
  const std::string dir = suite_dir("corrupt");
  const std::string state = dir + "/state";
  fs::create_directories(state);
  const std::string ckpt = state + "/identification-" + std::string(kVehicle) + ".ckpt";
  const std::string reason = "checkpoint " + ckpt + " was corrupt: moved aside; starting from nominal K";

  // One short run of the identification over `garbage` as its checkpoint; returns its health and K.
  auto run_over = [&](int domain, const std::string& content, const std::string& log,
                      std::vector<msg::Health>& health_out, std::vector<msg::ScaleFactor>& k_out) {
    {
      std::ofstream f(ckpt, std::ios::binary | std::ios::trunc);
      f << content;
    }
    odonav::dds::Participant participant(test_participant(domain));
    Collector<msg::ScaleFactor> k(participant, topics::kScaleFactor);
    Collector<msg::Health> health(participant, topics::kHealth);
    auto identification = start_logged(kIdentification, identification_args(domain, state), log);
    ASSERT_TRUE(identification->started());
    std::this_thread::sleep_for(milliseconds(500));
    ASSERT_TRUE(identification->running()) << read_text(log);
    auto gw_args = gateway_args(domain, 40.0, "max");
    gw_args[std::find(gw_args.begin(), gw_args.end(), "--wait-for-readers") - gw_args.begin() + 1] = "1";
    auto gateway = start_logged("odonav-gateway", gw_args, log + ".gateway.log");
    ASSERT_TRUE(gateway->wait_exit(seconds(90))) << read_text(log + ".gateway.log");
    EXPECT_EQ(gateway->exit_code(), 0) << read_text(log + ".gateway.log");
    // The health note lasts 30 s: wait (bounded) until the running node has published it.
    health.wait_until(
        [&](const std::vector<msg::Health>& all) {
          for (const auto& h : all)
            if (h.component() == kIdentification && h.reason().find(reason) != std::string::npos) return true;
          return false;
        },
        seconds(10));
    identification->signal(SIGINT);
    EXPECT_TRUE(identification->wait_exit(seconds(30)));
    EXPECT_EQ(identification->exit_code(), 0) << "never a crash on a bad checkpoint\n" << read_text(log);
    std::this_thread::sleep_for(milliseconds(300));
    health_out = health_of(health.samples(), kIdentification);
    k_out = k.samples();
  };

  auto check = [&](const std::string& content, const std::string& log, const std::string& log_reason,
                   const std::vector<msg::Health>& health, const std::vector<msg::ScaleFactor>& k) {
    // Moved aside, content kept, under <name>.bad-<unix time>.
    std::vector<fs::path> bad;
    for (const auto& e : fs::directory_iterator(state))
      if (e.path().filename().string().rfind("identification-" + std::string(kVehicle) + ".ckpt.bad-", 0) == 0 &&
          read_text(e.path().string()) == content)
        bad.push_back(e.path());
    EXPECT_EQ(bad.size(), 1u) << "the bad file, moved aside unchanged";
    // The log names the file and why.
    const std::string text = read_text(log);
    EXPECT_NE(text.find("checkpoint " + ckpt + " was corrupt (" + log_reason), std::string::npos) << text;
    // Health says so, at WARN.
    bool said = false;
    for (const auto& h : health)
      if (h.reason().find(reason) != std::string::npos && h.level() == msg::HEALTH_LEVEL_WARN) said = true;
    EXPECT_TRUE(said) << "no WARN health '" << reason << "'";
    // Started from nominal: nothing restored was published; the first estimate is a fresh one,
    // made from the first accepted samples of this drive (few of them).
    ASSERT_FALSE(k.empty());
    const auto first_valid = std::find_if(k.begin(), k.end(), [](const auto& m) { return m.k_m_per_pulse() > 0.0; });
    ASSERT_NE(first_valid, k.end());
    EXPECT_LT(first_valid->samples_accepted(), 5u);
    EXPECT_LT(stamp_s(k.front()), 15.0) << "the first K is stamped in this drive's beginning";
    // At shutdown a good checkpoint was written over the bad one's name.
    EXPECT_TRUE(fs::exists(ckpt));
  };

  std::vector<msg::Health> health;
  std::vector<msg::ScaleFactor> k;
  // 1. Garbage (fixed seed).
  std::string garbage(3000, '\0');
  uint32_t x = 12345;
  for (char& c : garbage) c = static_cast<char>((x = x * 1664525u + 1013904223u) >> 24);
  run_over(102, garbage, dir + "/garbage.log", health, k);
  if (HasFatalFailure()) return;
  check(garbage, dir + "/garbage.log", "not an odonav checkpoint", health, k);
  if (HasFatalFailure()) return;

  // 2. The good checkpoint that run wrote at shutdown, truncated in its middle (a torn write).
  const std::string good = read_text(ckpt);
  ASSERT_NE(good.find("\"component\":\"identification\""), std::string::npos) << good.substr(0, 200);
  ASSERT_NE(good.find("\"format\":\"odonav-checkpoint\""), std::string::npos);
  ASSERT_NE(good.find("\"version\":" + std::to_string(identification::kIdentificationCheckpointVersion) + "}"),
            std::string::npos)
      << "the identification's version, last key";
  shm_clean();
  const std::string truncated = good.substr(0, good.size() / 2);
  run_over(103, truncated, dir + "/truncated.log", health, k);
  if (HasFatalFailure()) return;
  check(truncated, dir + "/truncated.log", "truncated", health, k);
}

}  // namespace

namespace {

TEST_F(IdentificationRestart, ResentStreamIsNotCountedTwiceAfterARestore) {
  // Run 1: 40 s of the ring, as fast as the readers take it; the checkpoint is written at shutdown
  // (t = last GNSS epoch). Run 2: same state directory, the same 40 s sent again: every sample
  // predates the checkpoint, so nothing is processed twice: the only K published is the restored
  // one, equal to run 1's last K, with run 1's counters.
  const std::string dir = suite_dir("resent");
  const std::string state = dir + "/state";
  struct Run {
    std::vector<msg::ScaleFactor> k;
    std::vector<msg::Health> health;
  };
  auto run = [&](int domain, const std::string& log, Run& out) {
    odonav::dds::Participant participant(test_participant(domain));
    Collector<msg::ScaleFactor> k(participant, topics::kScaleFactor);
    Collector<msg::Health> health(participant, topics::kHealth);
    auto identification = start_logged(kIdentification, identification_args(domain, state), log);
    ASSERT_TRUE(identification->started());
    auto gw_args = gateway_args(domain, 40.0, "max");
    gw_args[std::find(gw_args.begin(), gw_args.end(), "--wait-for-readers") - gw_args.begin() + 1] = "1";
    auto gateway = start_logged("odonav-gateway", gw_args, log + ".gateway.log");
    ASSERT_TRUE(gateway->wait_exit(seconds(90))) << read_text(log + ".gateway.log");
    EXPECT_EQ(gateway->exit_code(), 0) << read_text(log + ".gateway.log");
    std::this_thread::sleep_for(seconds(3));  // more than the max wait: the node processes what it can
    identification->signal(SIGINT);
    EXPECT_TRUE(identification->wait_exit(seconds(30)));
    EXPECT_EQ(identification->exit_code(), 0) << read_text(log);
    std::this_thread::sleep_for(milliseconds(300));
    out.k = k.samples();
    out.health = health_of(health.samples(), kIdentification);
  };
  Run first, second;
  run(104, dir + "/first.log", first);
  if (HasFatalFailure()) return;
  const auto last = last_valid(first.k, first.k.size());
  ASSERT_TRUE(last.has_value());
  ASSERT_GT(stamp_s(*last), 39.0);
  ASSERT_GT(last->samples_accepted(), 100u);
  shm_clean();
  run(104, dir + "/second.log", second);
  if (HasFatalFailure()) return;

  ASSERT_FALSE(second.k.empty());
  // Nothing new: the restored estimate and its heartbeats, each equal to run 1's estimate of that
  // stamp, none after run 1's last.
  std::map<double, const msg::ScaleFactor*> run1;
  for (const auto& m : first.k) run1[stamp_s(m)] = &m;
  bool restored_seen = false;
  for (const auto& m : second.k) {
    ASSERT_LE(stamp_s(m), stamp_s(*last));
    const auto it = run1.find(stamp_s(m));
    ASSERT_NE(it, run1.end()) << "t=" << stamp_s(m) << " s was not published by run 1";
    EXPECT_EQ(m.k_m_per_pulse(), it->second->k_m_per_pulse());
    EXPECT_EQ(m.samples_accepted(), it->second->samples_accepted());
    EXPECT_EQ(m.samples_rejected(), it->second->samples_rejected());
    if (stamp_s(m) == stamp_s(*last)) restored_seen = true;
  }
  EXPECT_TRUE(restored_seen) << "the last K of run 1 is served after the restore";
  ASSERT_FALSE(second.health.empty());
  const msg::Health& h = second.health.back();
  EXPECT_EQ(counter(h, "checkpoint_restored"), 1.0);
  // 40 s of odometer (100 Hz), INS (100 Hz) and GNSS (10 Hz), less the last second kept for
  // interpolation: about 8000 samples skipped.
  EXPECT_GT(counter(h, "skipped_before_checkpoint"), 7500.0);
  EXPECT_LT(counter(h, "skipped_before_checkpoint"), 8500.0);
  std::cerr << "restored K " << last->k_m_per_pulse() << " at t=" << stamp_s(*last) << " s; "
            << counter(h, "skipped_before_checkpoint") << " re-sent samples skipped, " << second.k.size()
            << " ScaleFactor messages in the second run\n";
}

}  // namespace

namespace {

TEST_F(IdentificationRestart, LateReaderAfterARestartWithNoInputGetsTheRestoredK) {
  constexpr int kDomain = 105;
  const std::string dir = suite_dir("late-reader");
  const std::string state = dir + "/state";
  std::vector<msg::ScaleFactor> before_kill;
  std::unique_ptr<ChildProcess> identification;
  {
    odonav::dds::Participant participant(test_participant(kDomain));
    Collector<msg::ScaleFactor> k(participant, topics::kScaleFactor);
    auto calibration = start_logged("odonav-calibration", node_args(kDomain, 2.0), dir + "/calibration.log");
    identification = start_logged(kIdentification, identification_args(kDomain, state), dir + "/id-1.log");
    ASSERT_TRUE(calibration->started() && identification->started());
    auto gw_args = gateway_args(kDomain, 40.0, "max");  // waits for 2 readers: calibration, identification
    auto gateway = start_logged("odonav-gateway", gw_args, dir + "/gateway.log");
    ASSERT_TRUE(gateway->wait_exit(seconds(90))) << read_text(dir + "/gateway.log");
    EXPECT_EQ(gateway->exit_code(), 0) << read_text(dir + "/gateway.log");
    // The identification has processed everything once its newest stamp stops moving (its
    // heartbeats repeat the last estimate): bounded wait.
    double newest = -1.0;
    for (int i = 0; i < 60; ++i) {
      std::this_thread::sleep_for(milliseconds(500));
      const auto v = k.samples();
      if (!v.empty() && stamp_s(v.back()) == newest && newest > 39.0) break;
      if (!v.empty()) newest = stamp_s(v.back());
    }
    before_kill = k.samples();
    ASSERT_GT(newest, 39.0) << "the drive was processed to its end";
    identification->signal(SIGKILL);
    ASSERT_TRUE(identification->wait_exit(seconds(5)));
    EXPECT_EQ(identification->exit_code(), 128 + SIGKILL);
    calibration->signal(SIGINT);
    EXPECT_TRUE(calibration->wait_exit(seconds(30)));
  }
  // The checkpoint the restart resumes from (every 5 s of event time: up to 5 s before the last K).
  const identification::IdentificationCheckpoint ckpt =
      identification::parse_checkpoint(read_text(state + "/identification-" + std::string(kVehicle) + ".ckpt"));
  const auto published = std::find_if(before_kill.begin(), before_kill.end(),
                                      [&](const msg::ScaleFactor& m) { return stamp_s(m) == ckpt.last_sample_t_s; });
  ASSERT_NE(published, before_kill.end()) << "the checkpoint's epoch t=" << ckpt.last_sample_t_s << " s was published";
  shm_clean();
  // Restart with no input at all: nothing new can be computed or published.
  identification = start_logged(kIdentification, identification_args(kDomain, state), dir + "/id-2.log");
  ASSERT_TRUE(identification->started());
  std::this_thread::sleep_for(seconds(1));
  ASSERT_TRUE(identification->running()) << read_text(dir + "/id-2.log");

  // A reader created after the restart (TRANSIENT_LOCAL, the consumers' profile).
  odonav::dds::Participant late(test_participant(kDomain));
  Collector<msg::ScaleFactor> k(late, topics::kScaleFactor);
  ASSERT_TRUE(k.wait_until([&](const std::vector<msg::ScaleFactor>& v) { return !v.empty(); }, seconds(20)))
      << "no ScaleFactor for a late reader after the restart\n"
      << read_text(dir + "/id-2.log");
  std::this_thread::sleep_for(milliseconds(500));
  const msg::ScaleFactor got = k.samples().back();
  std::cerr << "checkpoint t=" << ckpt.last_sample_t_s << " s, K published for it " << published->k_m_per_pulse()
            << "; late reader after the restart got " << got.k_m_per_pulse() << " at t=" << stamp_s(got)
            << " s (source '" << got.source() << "')\n";
  EXPECT_EQ(stamp_s(got), ckpt.last_sample_t_s);
  EXPECT_EQ(got.k_m_per_pulse(), published->k_m_per_pulse()) << "the checkpoint round-trips the estimator exactly";
  EXPECT_EQ(got.samples_accepted(), published->samples_accepted());
  EXPECT_EQ(got.source(), "identification");
  for (const auto& m : k.samples()) EXPECT_EQ(stamp_s(m), ckpt.last_sample_t_s) << "nothing older, nothing newer";
  const std::string log = read_text(dir + "/id-2.log");
  EXPECT_EQ(log.find("SQLite"), std::string::npos) << "no Fast DDS persistence any more\n" << log;
  identification->signal(SIGINT);
  EXPECT_TRUE(identification->wait_exit(seconds(30)));
  EXPECT_EQ(identification->exit_code(), 0) << read_text(dir + "/id-2.log");
}

}  // namespace
