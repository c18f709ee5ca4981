// Hot standby (a second identification takes over when the first dies), as processes on loopback DDS:
// gateway (simulated ring course at real-time pace, so the switch time means something),
// calibration, a primary identification (priority 20), a standby (priority 10, --instance
// identification/standby), dead reckoning and odonav-recorder. The scale-factor topic is SHARED:
// every reader gets both instances' estimates, and each consumer follows one through its
// SourceArbiter. The primary is SIGKILLed mid-run. Asserted (ordering and equality, no wall clock):
//   - the test's own reader (SHARED, deep) hears both instances: the topic is readable without
//     EXCLUSIVE ownership; the same arbiter over what it heard follows the primary while it lives
//     and the standby from a stamp at most 1 s of event time after the primary's last one;
//   - odonav-recorder's scale_factor.csv is exact: one row per epoch, no epoch skipped or repeated
//     around the switch, each row equal to the primary's estimate of that epoch up to its last one
//     and to the standby's after it (uninterrupted run: the primary's throughout);
//   - DR's health says its K source changed; DR never stops (contiguous in event time);
//   - the final DR error (%D) equals an uninterrupted run's within 0.1 %D.
// The switch time on the wall clock (kill to the arbiter's first standby estimate) is printed as a
// figure for BENCHMARKS.md, not asserted.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "shm_clean_test.hpp"
#include "../nodes/node_test_support.hpp"
#include "odonav/msg/DeadReckoning.h"
#include "odonav/msg/ScaleFactor.h"
#include "odonav/results/output_files.hpp"
#include "odonav/source_arbiter.hpp"

namespace {

using namespace odonav;
using namespace odonav::test;
using std::chrono::milliseconds;
using std::chrono::seconds;
using odonav::SourceArbiter;
using odonav::SourceSwitch;

// Every estimate of every instance, as a recorder reads them (SHARED, reliable, KEEP_LAST 1000).
constexpr const char* kRawScaleFactorProfile = odonav::topics::kScaleFactorRecorderReaderProfile;
constexpr const char* kPrimary = "identification";
constexpr const char* kStandby = "identification/standby";
constexpr double kDurationS = 40.0;     // event time = wall time (real-time pace)
constexpr double kKillAtEventS = 22.0;  // K converged by then; 18 s of data follow

/// This suite's scratch folder for one test (as a string: the tests build paths with +).
std::string suite_dir(const std::string& name) { return fresh_dir("test-standby", name).string(); }

double stamp_s(const msg::ScaleFactor& m) { return odonav::dds::to_seconds(m.header().stamp()); }
double stamp_s(const msg::DeadReckoning& m) { return odonav::dds::to_seconds(m.header().stamp()); }
double steady_s() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }

std::string lever_arm() {
  const Eigen::Vector3d l = simulator::scenario_config("ring").lever_arm_m;
  char buf[96];
  std::snprintf(buf, sizeof buf, "%.17g,%.17g,%.17g", l.x(), l.y(), l.z());
  return buf;
}

/// Every ScaleFactor received (both instances), with its arrival (steady s).
class ScaleFactorArrivals {
 public:
  struct Arrival {
    double wall_s;
    msg::ScaleFactor message;
  };
  ScaleFactorArrivals(const odonav::dds::Participant& p)
      : reader_(p, topics::kScaleFactor.name, kRawScaleFactorProfile, [this](const msg::ScaleFactor& m) {
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
  double stop_wall_s = 0.0;      ///< when the shutdown began (the survivor takes over then: not a failover)
  results::OutputRows recorded;  ///< odonav-recorder's files
};

class HotStandby : public odonav::test::ShmCleanTest {
 protected:
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
    auto primary =
        start_logged("odonav-identification", identification_args(domain, kPrimary, 20), dir + "/primary.log");
    auto standby =
        start_logged("odonav-identification", identification_args(domain, kStandby, 10), dir + "/standby.log");
    auto dead_reckoning = start_logged("odonav-dead-reckoning",
                                       node_args(domain, 2.0, {"--lever-arm", lever_arm(), "--log-level", "info"}),
                                       dir + "/dead-reckoning.log");
    auto recorder =
        start_logged("odonav-recorder", node_args(domain, 2.0, {"--out", dir + "/recorded", "--log-level", "info"}),
                     dir + "/recorder.log");
    ASSERT_TRUE(calibration->started() && primary->started() && standby->started() && dead_reckoning->started() &&
                recorder->started());
    // The recorder matched its producers before any estimate is published (its health says so).
    health.wait_until(
        [](const std::vector<msg::Health>& v) {
          for (const auto& h : v)
            if (h.component() == "odonav-recorder" && h.reason().empty()) return true;
          return false;
        },
        seconds(30));
    // Readers of GNSS: calibration, both identifications, dead reckoning.
    auto gateway =
        start_logged("odonav-gateway",
                     node_args(domain, 2.0,
                               {"--source", "sim:ring", "--seed", "3", "--duration-s", std::to_string(kDurationS),
                                "--speed", "1", "--wait-for-readers", "4", "--wait-for-readers-timeout-s", "30",
                                // the primary is killed while it publishes
                                "--tolerate-lost-readers"}),
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
    for (auto* p : {standby.get(), primary.get(), dead_reckoning.get(), calibration.get(), recorder.get()}) {
      if (!p->running()) continue;
      p->signal(SIGINT);
      EXPECT_TRUE(p->wait_exit(seconds(30)));
      EXPECT_EQ(p->exit_code(), 0);
    }
    std::this_thread::sleep_for(milliseconds(500));
    out.k = k.arrivals();
    out.dr = dr.samples();
    out.health = health.samples();
    out.recorded = results::read_output_rows(dir + "/recorded");
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

/// What the consumers' arbiter makes of the arrivals, each delivered estimate with the arrival (wall
/// clock) of the sample that released it.
struct Followed {
  std::vector<ScaleFactorArrivals::Arrival> delivered;
  std::vector<SourceSwitch> switches;
};
Followed follow(const std::vector<ScaleFactorArrivals::Arrival>& arrivals) {
  SourceArbiter<msg::ScaleFactor> arbiter;
  Followed f;
  for (const auto& a : arrivals)
    for (const auto& m : arbiter.offer(a.message.source(), a.message.source_priority(), stamp_s(a.message), a.message))
      f.delivered.push_back({a.wall_s, m});
  f.switches = arbiter.switches();
  return f;
}

/// The estimates of one instance by stamp (its first copy: heartbeats repeat it unchanged).
std::map<double, msg::ScaleFactor> by_stamp(const std::vector<ScaleFactorArrivals::Arrival>& arrivals,
                                            const std::string& source) {
  std::map<double, msg::ScaleFactor> out;
  for (const auto& a : arrivals)
    if (a.message.source() == source) out.emplace(stamp_s(a.message), a.message);
  return out;
}

/// odonav-recorder's scale_factor.csv from `from_s` on against what each instance published: one row per
/// epoch, in order, nothing skipped or repeated, the primary's estimate up to `primary_last_s`, the
/// standby's after it.
void expect_recording_exact(const RunResult& run, double from_s, double primary_last_s) {
  const auto primary = by_stamp(run.k, kPrimary);
  const auto standby = by_stamp(run.k, kStandby);
  std::vector<double> expected;
  for (const auto& [t, m] : primary)
    if (t >= from_s && t <= primary_last_s) expected.push_back(t);
  for (const auto& [t, m] : standby)
    if (t >= from_s && t > primary_last_s) expected.push_back(t);
  std::vector<const results::ScaleFactorRow*> rows;
  for (const auto& r : run.recorded.scale_factor)
    if (r.t_s >= from_s) rows.push_back(&r);
  ASSERT_FALSE(expected.empty());
  ASSERT_EQ(rows.size(), expected.size()) << "recorded rows from t=" << from_s << " s vs epochs published";
  std::size_t standby_rows = 0;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const double t = rows[i]->t_s;
    ASSERT_DOUBLE_EQ(t, expected[i]) << "row " << i << ": an epoch skipped or repeated";
    const bool from_standby = t > primary_last_s;
    standby_rows += from_standby;
    const msg::ScaleFactor& want = from_standby ? standby.at(t) : primary.at(t);
    if (want.k_m_per_pulse() > 0.0) {
      ASSERT_TRUE(rows[i]->k_m_per_pulse.has_value()) << "t=" << t;
      EXPECT_DOUBLE_EQ(*rows[i]->k_m_per_pulse, want.k_m_per_pulse())
          << "t=" << t << (from_standby ? " (standby)" : "");
    }
    EXPECT_EQ(rows[i]->samples_accepted, want.samples_accepted()) << "t=" << t;
  }
  std::cerr << "recorder: " << rows.size() << " rows from t=" << from_s << " s, " << standby_rows
            << " of them the standby's, every epoch once\n";
}

TEST_F(HotStandby, PrimaryKilledStandbyTakesOverWithinOneSecondExactlyForEveryReader) {
  // The uninterrupted run and the run whose primary is killed go side by side, each in its own
  // domain and folder: both are paced by the drive (real time) and nothing here reads the wall clock
  // but the printed switch time.
  RunResult reference, failover;
  const std::string dir = suite_dir("failover");
  std::thread uninterrupted([&] {
    SCOPED_TRACE("uninterrupted run");
    run(106, suite_dir("uninterrupted"), false, reference);
  });
  {
    SCOPED_TRACE("primary killed");
    run(107, dir, true, failover);
  }
  uninterrupted.join();
  if (HasFatalFailure()) return;
  // SHARED: the test's reader hears both instances all along.
  ASSERT_FALSE(by_stamp(reference.k, kPrimary).empty());
  ASSERT_FALSE(by_stamp(reference.k, kStandby).empty()) << "the standby's estimates never reached a SHARED reader";
  // Both alive: once the primary has been heard, the arbiter follows it only. (Before that, the
  // standby's first sample may come first.)
  {
    bool primary_heard = false;
    for (const auto& a : follow(reference.k).delivered) {
      primary_heard = primary_heard || a.message.source() == kPrimary;
      if (primary_heard && a.wall_s < reference.stop_wall_s) {
        ASSERT_EQ(a.message.source(), kPrimary);
      }
    }
  }
  constexpr double kCheckFromS = 5.0;  // every process matched long before (event time = wall time)
  {
    SCOPED_TRACE("uninterrupted recording");
    expect_recording_exact(reference, kCheckFromS, 1e9);
  }

  const auto primary = by_stamp(failover.k, kPrimary);
  ASSERT_FALSE(primary.empty());
  const double primary_last_s = primary.rbegin()->first;
  const Followed followed = follow(failover.k);
  std::optional<ScaleFactorArrivals::Arrival> last_primary, first_standby;
  bool primary_heard = false;
  for (const auto& a : followed.delivered) {
    primary_heard = primary_heard || a.message.source() == kPrimary;
    if (stamp_s(a.message) <= primary_last_s) {
      if (primary_heard) {
        EXPECT_EQ(a.message.source(), kPrimary) << "the standby was followed while the primary was alive";
      }
      if (a.message.k_m_per_pulse() > 0.0) last_primary = a;
    } else {
      EXPECT_EQ(a.message.source(), kStandby) << "the dead primary came back?";
      if (!first_standby) first_standby = a;
    }
  }
  ASSERT_TRUE(last_primary.has_value());
  ASSERT_TRUE(first_standby.has_value()) << "the standby's K was never followed";
  ASSERT_FALSE(followed.switches.empty());
  const SourceSwitch& sw = followed.switches.back();
  EXPECT_EQ(sw.to, kStandby);
  std::cerr << "switch (" << sw.reason << ") at the standby's t=" << sw.at_stamp_s << " s, "
            << sw.at_stamp_s - primary_last_s << " s of event time after the primary's last t=" << primary_last_s
            << " s; on the wall clock " << (first_standby->wall_s - failover.kill_wall_s) * 1000
            << " ms after the kill; first standby estimate t=" << stamp_s(first_standby->message) << " s, K "
            << first_standby->message.k_m_per_pulse() << " (last primary K " << last_primary->message.k_m_per_pulse()
            << ")\n";
  // Within 1 s, in event time; and the first standby estimate followed is the epoch right after the
  // primary's last (nothing skipped).
  EXPECT_LE(sw.at_stamp_s - primary_last_s, 1.0);
  EXPECT_NEAR(stamp_s(first_standby->message) - primary_last_s, 0.1, 1e-6);
  // The standby identified from the same data: the same K (within what 3 s of data can move it).
  EXPECT_NEAR(first_standby->message.k_m_per_pulse() / last_primary->message.k_m_per_pulse(), 1.0, 5e-4);
  {
    SCOPED_TRACE("recording across the failover");
    expect_recording_exact(failover, kCheckFromS, primary_last_s);
  }
  EXPECT_NE(read_text(dir + "/recorder.log").find("scale factor: recording 'identification/standby' from t="),
            std::string::npos)
      << read_text(dir + "/recorder.log");

  // DR said it: log and health (K source changed), counter k_source_changes.
  bool said = false;
  double changes = 0.0, late_k = 0.0;
  for (const auto& h : failover.health) {
    if (h.component() != "odonav-dead-reckoning") continue;
    if (h.reason().find("K source changed from 'identification' to 'identification/standby'") != std::string::npos)
      said = true;
    changes = std::max(changes, counter(h, "k_source_changes"));
    const double late = counter(h, "scale_factor_late");
    if (std::isfinite(late)) late_k = std::max(late_k, late);
  }
  EXPECT_TRUE(said) << "DR health never told the K source change";
  // DR took every estimate the arbiter handed on: none came after DR had processed past its epoch.
  EXPECT_EQ(late_k, 0.0) << "standby estimates reached DR too late to be applied";
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
  std::cerr << "final DR error: uninterrupted " << ref_end->error_percent_distance() << " %D at t=" << stamp_s(*ref_end)
            << " s, with failover " << end->error_percent_distance() << " %D at t=" << stamp_s(*end) << " s\n";
  EXPECT_NEAR(end->error_percent_distance(), ref_end->error_percent_distance(), 0.1);
  EXPECT_GT(end->distance_m(), 100.0);
}

}  // namespace
