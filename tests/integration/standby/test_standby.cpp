// Hot standby (a second identification takes over when the first dies), as processes on loopback DDS:
// gateway (simulated ring course at
// real-time pace, so wall time means something), calibration, a primary identification (ownership
// strength 20), a standby (strength 10, --instance identification/standby) and dead reckoning.
// The primary is SIGKILLed mid-run. Asserted:
//   - before the kill, readers of the EXCLUSIVE scale-factor topic see the primary only;
//   - a reader with dead reckoning's profile (odonav_scale_factor_reader, 300 ms deadline) gets
//     the standby's estimates within 1 s of the kill; DR's health says its K source changed;
//   - DR never stops: its outputs are contiguous in event time (no step over 2 odometer periods);
//   - the final DR error (%D) equals an uninterrupted run's (same processes, no kill) within 0.1 %D.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "../nodes/node_test_support.hpp"
#include "odonav/msg/DeadReckoning.h"
#include "odonav/msg/ScaleFactor.h"

namespace {

using namespace odonav;
using namespace odonav::test;
namespace fs = std::filesystem;
using std::chrono::milliseconds;
using std::chrono::seconds;

// Dead reckoning's scale-factor reader profile (components/dead_reckoning/node: kScaleFactorReaderProfile).
constexpr const char* kDrScaleFactorProfile = odonav::topics::kScaleFactorReaderProfile;
constexpr const char* kPrimary = "identification";
constexpr const char* kStandby = "identification/standby";
constexpr double kDurationS = 40.0;    // event time = wall time (real-time pace)
constexpr double kKillAtEventS = 22.0;  // K converged by then; 18 s of data follow

/// This suite's scratch folder for one test (as a string: the tests build paths with +).
std::string suite_dir(const std::string& name) { return fresh_dir("test-standby", name).string(); }

double stamp_s(const msg::ScaleFactor& m) { return odonav::dds::to_seconds(m.header().stamp()); }
double stamp_s(const msg::DeadReckoning& m) { return odonav::dds::to_seconds(m.header().stamp()); }
double steady_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

std::string lever_arm() {
  const Eigen::Vector3d l = sim::scenario_config("ring").lever_arm_m;
  char buf[96];
  std::snprintf(buf, sizeof buf, "%.17g,%.17g,%.17g", l.x(), l.y(), l.z());
  return buf;
}

/// Every ScaleFactor received with dead reckoning's reader profile, with its arrival (steady s).
class ScaleFactorArrivals {
 public:
  struct Arrival {
    double wall_s;
    msg::ScaleFactor message;
  };
  ScaleFactorArrivals(const odonav::dds::Participant& p)
      : reader_(p, topics::kScaleFactor.name, kDrScaleFactorProfile, [this](const msg::ScaleFactor& m) {
          std::lock_guard<std::mutex> lock(mutex_);
          arrivals_.push_back({steady_s(), m});
        }) {}
  std::vector<Arrival> arrivals() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return arrivals_;
  }

 private:
  mutable std::mutex mutex_;
  std::vector<Arrival> arrivals_;
  odonav::dds::Reader<msg::ScaleFactor> reader_;
};

struct RunResult {
  std::vector<ScaleFactorArrivals::Arrival> k;
  std::vector<msg::DeadReckoning> dr;
  std::vector<msg::Health> health;
  double kill_wall_s = 0.0;
  double stop_wall_s = 0.0;  ///< when the shutdown began (the survivor takes over then: not a failover)
};

class HotStandby : public ::testing::Test {
 protected:
  void SetUp() override { shm_clean(); }
  void TearDown() override { shm_clean(); }

  static std::vector<std::string> identification_args(int domain, const char* instance, int strength) {
    return node_args(domain, 2.0,
                     {"--instance", instance, "--ownership-strength", std::to_string(strength), "--lever-arm",
                      lever_arm(), "--log-level", "info"});
  }

  void run(int domain, const std::string& dir, bool kill, RunResult& out) {
    odonav::dds::Participant participant(test_participant(domain));
    ScaleFactorArrivals k(participant);
    Collector<msg::DeadReckoning> dr(participant, topics::kDeadReckoning);
    Collector<msg::Health> health(participant, topics::kHealth);

    auto calibration = start_logged("odonav-calibration", node_args(domain, 2.0, {"--lever-arm", lever_arm()}),
                                    dir + "/calibration.log");
    auto primary = start_logged("odonav-identification", identification_args(domain, kPrimary, 20), dir + "/primary.log");
    auto standby = start_logged("odonav-identification", identification_args(domain, kStandby, 10), dir + "/standby.log");
    auto dead_reckoning = start_logged("odonav-dead-reckoning",
                                       node_args(domain, 2.0, {"--lever-arm", lever_arm(), "--log-level", "info"}),
                                       dir + "/dead-reckoning.log");
    ASSERT_TRUE(calibration->started() && primary->started() && standby->started() && dead_reckoning->started());
    // Readers of GNSS: calibration, both identifications, dead reckoning.
    auto gateway = start_logged("odonav-gateway",
                                node_args(domain, 2.0,
                                          {"--source", "sim:ring", "--seed", "3", "--duration-s",
                                           std::to_string(kDurationS), "--speed", "1", "--wait-for-readers", "4",
                                           "--wait-for-readers-timeout-s", "30"}),
                                dir + "/gateway.log");
    ASSERT_TRUE(gateway->started());

    if (kill) {
      const auto deadline = steady_s() + 90.0;
      bool reached = false;
      while (steady_s() < deadline && !reached) {
        const auto v = k.arrivals();
        reached = !v.empty() && stamp_s(v.back().message) >= kKillAtEventS;
        if (!reached) std::this_thread::sleep_for(milliseconds(10));
      }
      ASSERT_TRUE(reached) << "no K reached t=" << kKillAtEventS << " s\n" << read_text(dir + "/primary.log");
      out.kill_wall_s = steady_s();
      primary->signal(SIGKILL);
      ASSERT_TRUE(primary->wait_exit(seconds(5)));
      EXPECT_EQ(primary->exit_code(), 128 + SIGKILL);
    }

    ASSERT_TRUE(gateway->wait_exit(seconds(120))) << read_text(dir + "/gateway.log");
    EXPECT_EQ(gateway->exit_code(), 0) << read_text(dir + "/gateway.log");
    dr.wait_until(
        [](const std::vector<msg::DeadReckoning>& s) { return !s.empty() && stamp_s(s.back()) >= kDurationS - 3.0; },
        seconds(30));
    out.stop_wall_s = steady_s();
    for (auto* p : {standby.get(), primary.get(), dead_reckoning.get(), calibration.get()}) {
      if (!p->running()) continue;
      p->signal(SIGINT);
      EXPECT_TRUE(p->wait_exit(seconds(30)));
      EXPECT_EQ(p->exit_code(), 0);
    }
    std::this_thread::sleep_for(milliseconds(500));
    out.k = k.arrivals();
    out.dr = dr.samples();
    out.health = health.samples();
  }
};

/// The last DR output with a GNSS reference (its error in % of distance travelled).
std::optional<msg::DeadReckoning> last_with_error(const std::vector<msg::DeadReckoning>& dr) {
  for (std::size_t i = dr.size(); i-- > 0;)
    if (dr[i].error_percent_distance() >= 0.0) return dr[i];
  return std::nullopt;
}

double max_event_gap_s(const std::vector<msg::DeadReckoning>& dr, double& first_s, double& last_s) {
  std::vector<double> t;
  for (const auto& m : dr) t.push_back(stamp_s(m));
  std::sort(t.begin(), t.end());
  t.erase(std::unique(t.begin(), t.end()), t.end());
  if (t.empty()) return 1e9;
  first_s = t.front();
  last_s = t.back();
  double gap = 0.0;
  for (std::size_t i = 1; i < t.size(); ++i) gap = std::max(gap, t[i] - t[i - 1]);
  return gap;
}

TEST_F(HotStandby, PrimaryKilledStandbyTakesOverWithinOneSecondAndAccuracyHolds) {
  RunResult reference;
  {
    SCOPED_TRACE("uninterrupted run");
    run(106, suite_dir("uninterrupted"), false, reference);
  }
  if (HasFatalFailure()) return;
  // Both instances alive all along: once the primary has been heard, the strongest is the only one
  // readers see. (Before that, the standby's first sample may win the race at start: ownership goes
  // to whoever speaks first until a stronger writer does.)
  ASSERT_FALSE(reference.k.empty());
  bool primary_heard = false;
  for (const auto& a : reference.k) {
    primary_heard = primary_heard || a.message.source() == kPrimary;
    if (primary_heard && a.wall_s < reference.stop_wall_s) {
      ASSERT_EQ(a.message.source(), kPrimary);
    }
  }
  shm_clean();

  RunResult failover;
  const std::string dir = suite_dir("failover");
  {
    SCOPED_TRACE("primary killed");
    run(107, dir, true, failover);
  }
  if (HasFatalFailure()) return;

  // Before the kill: the primary only. After: the standby, first within 1 s.
  std::optional<ScaleFactorArrivals::Arrival> last_primary, first_standby;
  primary_heard = false;
  for (const auto& a : failover.k) {
    primary_heard = primary_heard || a.message.source() == kPrimary;
    if (a.wall_s < failover.kill_wall_s) {
      if (primary_heard) {
        EXPECT_EQ(a.message.source(), kPrimary) << "the standby was seen while the primary was alive";
      }
      if (a.message.k_m_per_pulse() > 0.0) last_primary = a;
    } else if (a.message.source() == kStandby && !first_standby) {
      first_standby = a;
    }
  }
  ASSERT_TRUE(last_primary.has_value());
  ASSERT_TRUE(first_standby.has_value()) << "the standby's K never reached the reader";
  const double switch_s = first_standby->wall_s - failover.kill_wall_s;
  std::cerr << "switch " << switch_s * 1000 << " ms after the kill; last primary K "
            << last_primary->message.k_m_per_pulse() << " at t=" << stamp_s(last_primary->message)
            << " s, first standby K " << first_standby->message.k_m_per_pulse() << " at t="
            << stamp_s(first_standby->message) << " s\n";
  EXPECT_LE(switch_s, 1.0);
  // The standby identified from the same data: the same K (within what 3 s of data can move it).
  EXPECT_NEAR(first_standby->message.k_m_per_pulse() / last_primary->message.k_m_per_pulse(), 1.0, 5e-4);
  for (const auto& a : failover.k)
    if (a.wall_s > first_standby->wall_s && a.wall_s < failover.stop_wall_s) {
      EXPECT_EQ(a.message.source(), kStandby) << "the dead primary came back?";
    }

  // DR said it: log and health (K source changed), counter k_source_changes.
  bool said = false;
  double changes = 0.0;
  for (const auto& h : failover.health) {
    if (h.component() != "odonav-dead-reckoning") continue;
    if (h.reason().find("K source changed from 'identification' to 'identification/standby'") != std::string::npos)
      said = true;
    changes = std::max(changes, counter(h, "k_source_changes"));
  }
  EXPECT_TRUE(said) << "DR health never told the K source change";
  // One change at the kill, plus one at start if the standby spoke first there.
  EXPECT_GE(changes, 1.0);
  EXPECT_LE(changes, 2.0);
  EXPECT_NE(read_text(dir + "/dead-reckoning.log").find("K source changed"), std::string::npos);

  // DR never stopped: contiguous in event time from start to end of data.
  double first = 0.0, last = 0.0;
  const double gap = max_event_gap_s(failover.dr, first, last);
  std::cerr << "DR: " << failover.dr.size() << " outputs, t=" << first << ".." << last << " s, largest step " << gap
            << " s\n";
  EXPECT_LE(gap, 2 * 0.01 + 1e-6);
  EXPECT_LT(first, 1.0);
  EXPECT_GT(last, kDurationS - 1.0);

  // Final accuracy equals the uninterrupted run's within 0.1 %D.
  const auto ref_end = last_with_error(reference.dr);
  const auto end = last_with_error(failover.dr);
  ASSERT_TRUE(ref_end && end);
  std::cerr << "final DR error: uninterrupted " << ref_end->error_percent_distance() << " %D at t="
            << stamp_s(*ref_end) << " s, with failover " << end->error_percent_distance() << " %D at t=" << stamp_s(*end)
            << " s\n";
  EXPECT_NEAR(end->error_percent_distance(), ref_end->error_percent_distance(), 0.1);
  EXPECT_GT(end->distance_m(), 100.0);
}

}  // namespace
