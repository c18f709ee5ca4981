// The dead reckoning's checkpoint and restart (dead_reckoning_checkpoint.hpp, restart_policy.hpp) in
// one process, on real files in a scratch state directory: a run killed at any point (during a GNSS
// outage, while an estimate is held, with estimates received but not applicable yet) and restarted
// from its last checkpoint, fed the producers' history like the node, publishes exactly the outputs
// of an uninterrupted run (pure DR and anchored position, bit for bit); corrupt and foreign
// checkpoints are moved aside and named.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>

#include "odonav/consumer_rules.hpp"
#include "odonav/dead_reckoning/dead_reckoning_lifecycle.hpp"
#include "checkpoint_test.hpp"
#include "synthetic_drive.hpp"

namespace {

using namespace odonav;
using namespace odonav::dead_reckoning;
using namespace odonav::synthetic;
using namespace odonav::test;
namespace fs = std::filesystem;

constexpr double kEstimateLag_s = 0.05;  // estimates arrive this long after their GNSS epoch
constexpr double kK = 0.0125;
const Misalignment kTrueMis = checkpoint_misalignment();
const Eigen::Vector3d kLeverArm_m = checkpoint_lever_arm_body_m();

DeadReckonerParams dr_params() {
  DeadReckonerParams p;
  p.nominal_k_m_per_pulse = 1.003 * kK;  // off, so the identified K and the anchored scale matter
  p.lever_arm_body_m = kLeverArm_m;
  return p;
}

/// 70 s on a 250 m circle at 10 m/s, 0.05 m/s velocity noise, antenna 1.4 m from the INS, a GNSS
/// outage t=25-33 s (no fixes, no estimates), an INS gap of 0.6 s at t=40.1 s, and the calibration
/// silent t=45-48 s (outputs on a held misalignment).
struct Drive {
  SyntheticData d;
  std::vector<std::pair<double, Misalignment>> misalignment;  // stamp = GNSS epoch
  std::vector<std::pair<double, double>> k;                   // stamp = GNSS epoch, K (m/pulse)
};
Drive drive() {
  SensorConfig c = checkpoint_sensors(70.0, 5);
  c.k_m_per_pulse = kK;
  Drive r{simulate(checkpoint_circle(), c), {}, {}};
  auto& g = r.d.gnss;
  g.erase(std::remove_if(g.begin(), g.end(), [](const GnssSample& s) { return s.t_s > 25.0 && s.t_s < 33.0; }),
          g.end());
  auto& ins = r.d.ins;
  ins.erase(std::remove_if(ins.begin(), ins.end(), [](const InsSample& s) { return s.t_s > 40.1 && s.t_s < 40.7; }),
            ins.end());
  for (std::size_t i = 0; i < g.size(); ++i) {
    const double t = g[i].t_s;
    // Estimates that converge over the drive.
    const double f = std::exp(-t / 20.0);
    if (!(t > 45.0 && t < 48.0))
      r.misalignment.emplace_back(t, Misalignment{kTrueMis.heading_rad * (1.0 - f), kTrueMis.pitch_rad * (1.0 - f)});
    r.k.emplace_back(t, kK * (1.0 + 0.003 * f));
  }
  return r;
}

enum class Kind { kOdometer, kGnss, kIns, kMisalignment, kScaleFactor };
struct Event {
  double arrival_s;  // when the node receives it (event time of the data it follows)
  double t_s;        // its stamp
  Kind kind;
  std::size_t index;
};
std::vector<Event> events_of(const Drive& r) {
  std::vector<Event> e;
  for (std::size_t i = 0; i < r.d.odometer.size(); ++i)
    e.push_back({r.d.odometer[i].t_s, r.d.odometer[i].t_s, Kind::kOdometer, i});
  for (std::size_t i = 0; i < r.d.gnss.size(); ++i) e.push_back({r.d.gnss[i].t_s, r.d.gnss[i].t_s, Kind::kGnss, i});
  for (std::size_t i = 0; i < r.d.ins.size(); ++i) e.push_back({r.d.ins[i].t_s, r.d.ins[i].t_s, Kind::kIns, i});
  for (std::size_t i = 0; i < r.misalignment.size(); ++i)
    e.push_back({r.misalignment[i].first + kEstimateLag_s, r.misalignment[i].first, Kind::kMisalignment, i});
  for (std::size_t i = 0; i < r.k.size(); ++i)
    e.push_back({r.k[i].first + kEstimateLag_s, r.k[i].first, Kind::kScaleFactor, i});
  std::stable_sort(e.begin(), e.end(), [](const Event& a, const Event& b) { return a.arrival_s < b.arrival_s; });
  return e;
}

struct Published {
  DeadReckoningOutput dr;
  AnchoredPosition anchored;
  Misalignment applied;
};

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }
bool same_bits(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return same_bits(a.x(), b.x()) && same_bits(a.y(), b.y()) && same_bits(a.z(), b.z());
}

void expect_identical(const Published& a, const Published& b, const std::string& where) {
  EXPECT_TRUE(same_bits(a.dr.t_s, b.dr.t_s)) << where;
  EXPECT_TRUE(same_bits(a.dr.position.lat_rad, b.dr.position.lat_rad)) << where;
  EXPECT_TRUE(same_bits(a.dr.position.lon_rad, b.dr.position.lon_rad)) << where;
  EXPECT_TRUE(same_bits(a.dr.position.height_m, b.dr.position.height_m)) << where;
  EXPECT_TRUE(same_bits(a.dr.enu_m, b.dr.enu_m)) << where;
  EXPECT_TRUE(same_bits(a.dr.heading_rad, b.dr.heading_rad)) << where;
  EXPECT_TRUE(same_bits(a.dr.distance_m, b.dr.distance_m)) << where;
  EXPECT_TRUE(same_bits(a.dr.k_m_per_pulse, b.dr.k_m_per_pulse)) << where;
  EXPECT_EQ(a.dr.k_source, b.dr.k_source) << where;
  EXPECT_EQ(a.dr.heading_held, b.dr.heading_held) << where;
  EXPECT_EQ(a.dr.gnss_reference, b.dr.gnss_reference) << where;
  EXPECT_TRUE(same_bits(a.dr.horizontal_error_m, b.dr.horizontal_error_m)) << where;
  EXPECT_TRUE(same_bits(a.dr.error_percent_distance, b.dr.error_percent_distance)) << where;
  EXPECT_TRUE(same_bits(a.dr.error_t_s, b.dr.error_t_s)) << where;
  EXPECT_EQ(a.dr.gnss_fixes.size(), b.dr.gnss_fixes.size()) << where;
  EXPECT_EQ(a.dr.k_held, b.dr.k_held) << where;
  EXPECT_EQ(a.dr.misalignment_held, b.dr.misalignment_held) << where;
  EXPECT_TRUE(same_bits(a.applied.heading_rad, b.applied.heading_rad)) << where;
  EXPECT_TRUE(same_bits(a.applied.pitch_rad, b.applied.pitch_rad)) << where;
  EXPECT_TRUE(same_bits(a.anchored.position.lat_rad, b.anchored.position.lat_rad)) << where;
  EXPECT_TRUE(same_bits(a.anchored.position.lon_rad, b.anchored.position.lon_rad)) << where;
  EXPECT_TRUE(same_bits(a.anchored.enu_m, b.anchored.enu_m)) << where;
  EXPECT_EQ(std::memcmp(a.anchored.covariance_enu_m2.data(), b.anchored.covariance_enu_m2.data(), 9 * sizeof(double)),
            0)
      << where;
  EXPECT_EQ(a.anchored.status, b.anchored.status) << where;
  EXPECT_TRUE(same_bits(a.anchored.last_fix_t_s, b.anchored.last_fix_t_s)) << where;
  EXPECT_TRUE(same_bits(a.anchored.scale_error, b.anchored.scale_error)) << where;
}

std::size_t index_at(const std::vector<Event>& ev, double t_s) {
  return static_cast<std::size_t>(
      std::lower_bound(ev.begin(), ev.end(), t_s, [](const Event& e, double t) { return e.arrival_s < t; }) -
      ev.begin());
}

class DeadReckoningCheckpointTest : public StateDirTest {
 protected:
  DeadReckoningCheckpointTest() : StateDirTest("dead-reckoning-vehicle-07.ckpt") {}

  /// The node's work over the events [from, to): each sample through the lifecycle, then into the
  /// cores as the node feeds them; processed up to what every input has reached; what the lifecycle
  /// keeps published (the anchored position stepped on it); checkpoints when due. `to` == all:
  /// finish. The events before `live_from` (the history) arrive at once at steady0_s.
  struct Run {
    DeadReckoner core{dr_params()};
    AnchoredPositionFilter anchor;
    DeadReckoningConsumerState consumer{dr_params().nominal_k_m_per_pulse};
    DeadReckoningLifecycle lifecycle;
    std::vector<Published> published;
    explicit Run(const CheckpointSettings& s) : lifecycle(s, kVehicle) {}
    DeadReckoningStateRefs state() { return {core, anchor, consumer}; }
    /// The node's start at wall clock kUnixTime_s, steady clock `steady_s` (restores a usable checkpoint).
    void start(double steady_s) { lifecycle.start(state(), kUnixTime_s, steady_s); }
    void publish(std::vector<DeadReckoningOutput> outputs, double steady_s) {
      for (DeadReckoningOutput& o : lifecycle.outputs_to_publish(std::move(outputs), steady_s)) {
        const Misalignment applied = consumer.applied_misalignment.at_or_before(o.t_s).value_or(Misalignment{});
        consumer.applied_misalignment.drop_before(o.t_s);
        const AnchoredPosition a = anchor.step(o);
        published.push_back({std::move(o), a, applied});
      }
      lifecycle.checkpoint_if_due(state());
    }
  };
  static void feed(Run& r, const Drive& dv, const std::vector<Event>& ev, std::size_t from, std::size_t to,
                   double steady0_s, std::size_t live_from = 0) {
    const double hold_off = dr_params().estimate_hold_off_s;
    for (std::size_t k = from; k < to; ++k) {
      const Event& e = ev[k];
      const double steady_s =
          k < live_from ? steady0_s : steady0_s + 0.01 + (e.arrival_s - ev[std::min(live_from, to - 1)].arrival_s);
      switch (e.kind) {
        case Kind::kOdometer:
          r.lifecycle.note_live_sample(e.t_s, steady_s);
          if (r.lifecycle.take_sample(DeadReckoningInput::kOdometer, e.t_s))
            r.core.add_odometer(dv.d.odometer[e.index]);
          break;
        case Kind::kGnss:
          if (r.lifecycle.take_sample(DeadReckoningInput::kGnss, e.t_s)) r.core.add_gnss(dv.d.gnss[e.index]);
          break;
        case Kind::kIns:
          if (r.lifecycle.take_sample(DeadReckoningInput::kIns, e.t_s)) r.core.add_ins(dv.d.ins[e.index]);
          break;
        case Kind::kMisalignment:
          if (r.lifecycle.take_sample(DeadReckoningInput::kMisalignment, e.t_s)) {
            r.core.add_estimate_received(HeldEstimate::kMisalignment, e.t_s);
            const double from_s = estimate_applies_from_s(e.t_s, hold_off);
            r.core.add_misalignment(from_s, dv.misalignment[e.index].second);
            r.consumer.applied_misalignment.add(from_s, dv.misalignment[e.index].second);
            ++r.consumer.misalignments_applied;
            r.consumer.held_misalignment_t_s = e.t_s;
          }
          break;
        case Kind::kScaleFactor:
          if (r.lifecycle.take_sample(DeadReckoningInput::kScaleFactor, e.t_s)) {
            r.core.add_estimate_received(HeldEstimate::kScaleFactor, e.t_s);
            const IdentifiedScaleFactor k{
                estimate_applies_from_s(e.t_s, hold_off), dv.k[e.index].second, true, "identification", 1e-6, 500};
            if (const auto u = r.consumer.k_selection.on_identified(k, steady_s))
              r.core.add_scale_factor(u->t_s, u->k_m_per_pulse, u->source);
          }
          break;
      }
      // Every input stamped up to here, and every estimate applicable up to here, has arrived.
      r.publish(r.core.process_until(e.arrival_s - kEstimateLag_s - 1e-6), steady_s);
    }
    if (to == ev.size()) {
      r.publish(r.core.finish(), steady0_s);
      r.lifecycle.checkpoint_at_finish(r.state());
    }
  }
  /// Starts `r` at steady clock 0 and feeds it the events up to event time `until_s`: a node killed
  /// there, its checkpoints left in the state directory.
  static void start_and_feed_until(Run& r, const Drive& dv, const std::vector<Event>& ev, double until_s) {
    r.start(0.0);
    feed(r, dv, ev, 0, index_at(ev, until_s), 0.0);
  }
};

}  // namespace

TEST_F(DeadReckoningCheckpointTest,
       KilledAnywhereAndRestartedFromTheCheckpointItPublishesExactlyTheUninterruptedOutputs) {
  const Drive dv = drive();
  const std::vector<Event> ev = events_of(dv);
  Run reference(CheckpointSettings{});
  feed(reference, dv, ev, 0, ev.size(), 0.0);
  ASSERT_EQ(reference.published.size(), dv.d.odometer.size() - 1);  // every sample after the start fix
  // The drive exercised what the checkpoint carries: the outage (no error, anchored bridging), the
  // held misalignment, the identified K, fixes applied to the anchored filter.
  EXPECT_GT(reference.core.counters().outputs_on_held_misalignment, 100u);
  EXPECT_GT(reference.anchor.counters().fixes_applied, 500u);
  const auto in_outage = std::find_if(reference.published.begin(), reference.published.end(),
                                      [](const Published& p) { return p.dr.t_s > 30.0; });
  ASSERT_NE(in_outage, reference.published.end());
  EXPECT_FALSE(in_outage->dr.gnss_reference);
  EXPECT_EQ(in_outage->anchored.status, AnchorStatus::kDeadReckoning);
  EXPECT_EQ(reference.published.back().dr.k_source, ScaleFactorSource::kIdentified);

  // Kills early, in the GNSS outage, right after the INS gap, while the misalignment is held, late.
  for (const double kill_t_s : {6.43, 29.71, 40.52, 46.38, 66.05}) {
    SCOPED_TRACE("killed at t=" + std::to_string(kill_t_s) + " s");
    fs::remove_all(dir_);
    const std::size_t kill = index_at(ev, kill_t_s);
    Run first(settings(1.0));
    first.start(0.0);
    feed(first, dv, ev, 0, kill, 0.0);  // no finish: kill -9
    EXPECT_GE(first.lifecycle.restart().checkpoints_written(), 2u);

    Run second(settings(1.0));
    second.start(100.0);
    ASSERT_TRUE(second.lifecycle.restored_t_s());
    const double t_ckpt = *second.lifecycle.restored_t_s();
    EXPECT_LE(t_ckpt, first.published.back().dr.t_s);
    EXPECT_GT(t_ckpt, first.published.back().dr.t_s - 1.0 - 1e-9);
    // Restarted 2 s of data after the kill: the history reaches 30 s back from there.
    const std::size_t live = index_at(ev, ev[kill].arrival_s + 2.0);
    const std::size_t history = index_at(ev, ev[live].arrival_s - kHistory_s);
    feed(second, dv, ev, history, ev.size(), 100.0, live);

    std::vector<const Published*> expected;
    for (const auto& p : reference.published)
      if (p.dr.t_s > t_ckpt) expected.push_back(&p);
    ASSERT_EQ(second.published.size(), expected.size());
    for (std::size_t i = 0; i < expected.size(); ++i)
      expect_identical(second.published[i], *expected[i], "output " + std::to_string(i));
    const DeadReckonerCounters& a = reference.core.counters();
    const DeadReckonerCounters& b = second.core.counters();
    EXPECT_EQ(std::memcmp(&a, &b, sizeof a), 0) << "the counters go on across the restart";
    EXPECT_EQ(reference.anchor.counters().fixes_applied, second.anchor.counters().fixes_applied);
    EXPECT_EQ(reference.consumer.misalignments_applied, second.consumer.misalignments_applied);
    EXPECT_EQ(reference.consumer.k_selection.counters().k_applied, second.consumer.k_selection.counters().k_applied);
    const RestartPolicy& p = second.lifecycle.restart();
    expect_caught_up(p, expected.front()->dr.t_s);
    EXPECT_NE(p.health_notes().restore_note.find("restored the dead reckoning from checkpoint"), std::string::npos);
  }
}

TEST_F(DeadReckoningCheckpointTest, StatesRoundTripExactly) {
  const Drive dv = drive();
  const std::vector<Event> ev = events_of(dv);
  Run r(CheckpointSettings{});
  feed(r, dv, ev, 0, index_at(ev, 29.0), 0.0);  // in the outage, inputs buffered ahead
  const StateJson core = r.core.save_state();
  const StateJson anchor = r.anchor.save_state();
  DeadReckoner c(dr_params());
  c.restore_state(core);
  EXPECT_EQ(c.save_state(), core);
  EXPECT_EQ(c.save_state().dump(), core.dump()) << "saved, restored and saved again: the same bytes";
  AnchoredPositionFilter a;
  a.restore_state(anchor);
  EXPECT_EQ(a.save_state(), anchor);
  EXPECT_EQ(a.save_state().dump(), anchor.dump());
  EXPECT_TRUE(c.started());
  EXPECT_EQ(c.origin()->lat_rad, r.core.origin()->lat_rad);
  // In the outage, with inputs buffered ahead: the state holds them.
  EXPECT_FALSE(core.at("odometer").at("entries").empty());
  EXPECT_FALSE(core.at("origin").is_null());
  EXPECT_EQ(anchor.at("p").size(), 64u) << "the 8x8 covariance";
}

TEST_F(DeadReckoningCheckpointTest, CorruptOrForeignCheckpointsAreMovedAsideNamedAndChangeNothing) {
  const Drive dv = drive();
  const std::vector<Event> ev = events_of(dv);
  Run r(settings(1.0));
  start_and_feed_until(r, dv, ev, 12.0);
  const std::string good = read_text(ckpt_);
  ASSERT_FALSE(good.empty());
  DeadReckoningCheckpoint c = parse_dead_reckoning_checkpoint(good);
  EXPECT_EQ(serialize_dead_reckoning_checkpoint(c), good);
  // A flipped bit in a digit after a decimal point: still valid JSON, only the checksum sees it.
  std::string flipped = good;
  flipped[good.find('.', good.find("\"position\"")) + 1] ^= 0x01;
  DeadReckoningCheckpoint other_vehicle = c;
  other_vehicle.vehicle_id = "vehicle-99";
  DeadReckoningCheckpoint bad_core = c;
  bad_core.dead_reckoner_state.at("position").erase("lat_rad");
  DeadReckoningCheckpoint bad_anchor = c;
  bad_anchor.anchor_state = StateJson{{"queued_fixes", StateJson::array()}};
  struct Case {
    std::string name, text, reason;
  };
  const std::vector<Case> cases{
      {"truncated", good.substr(0, good.size() / 2), "truncated"},
      {"flipped byte", flipped, "checksum mismatch: the file is corrupt"},
      {"other vehicle", serialize_dead_reckoning_checkpoint(other_vehicle), "made for vehicle 'vehicle-99'"},
      {"bad dead reckoner state", serialize_dead_reckoning_checkpoint(bad_core),
       "dead reckoner state refused: field 'dead_reckoner.position.lat_rad' is missing"},
      {"bad anchored state", serialize_dead_reckoning_checkpoint(bad_anchor),
       "anchored position state refused: field 'anchored_position.last_added_t_s' is missing"},
      {"calibration checkpoint",
       seal_checkpoint(CheckpointIdentity{"calibration", kDeadReckoningCheckpointVersion, kVehicle, kHash},
                       StateJson::parse(good).at("payload")),
       "made by odonav-calibration, this is odonav-dead-reckoning"},
      {"older version",
       seal_checkpoint(CheckpointIdentity{"dead-reckoning", kDeadReckoningCheckpointVersion - 1, kVehicle, kHash},
                       StateJson::parse(good).at("payload")),
       "checkpoint version 2, this build reads version 3"},
  };
  for (const Case& k : cases) {
    SCOPED_TRACE(k.name);
    write_checkpoint(k.text);
    Run fresh(settings(1.0));
    const StateJson fresh_core = fresh.core.save_state(), fresh_anchor = fresh.anchor.save_state();
    fresh.start(10.0);
    EXPECT_EQ(fresh.core.save_state(), fresh_core) << "untouched";
    EXPECT_EQ(fresh.anchor.save_state(), fresh_anchor) << "untouched";
    EXPECT_EQ(fresh.consumer.misalignments_applied, 0u);
    EXPECT_FALSE(fresh.lifecycle.restored_t_s());
    ASSERT_NO_FATAL_FAILURE(expect_moved_aside(fresh.lifecycle.restart(), k.text, "starting at the next GNSS fix"));
    const DeadReckoningCheckpointLoad again =
        load_dead_reckoning_checkpoint(aside().string(), kVehicle, kHash, fresh.state(), kUnixTime_s);
    EXPECT_NE(again.reason.find(k.reason), std::string::npos) << again.reason;
    EXPECT_TRUE(fresh.lifecycle.take_sample(DeadReckoningInput::kOdometer, 0.1)) << "a fresh start skips nothing";
  }
}

TEST_F(DeadReckoningCheckpointTest, AHistoryStartingAfterTheCheckpointIsNamedAsLost) {
  const Drive dv = drive();
  const std::vector<Event> ev = events_of(dv);
  Run first(settings(5.0));
  start_and_feed_until(first, dv, ev, 21.0);
  Run second(settings(5.0));
  second.start(100.0);
  ASSERT_TRUE(second.lifecycle.restored_t_s());
  const double t_ckpt = *second.lifecycle.restored_t_s();
  EXPECT_NEAR(t_ckpt, 20.0, 0.05);
  // Down 40 s: the history starts at t=36 s, 16 s after the checkpoint.
  const std::size_t live = index_at(ev, 61.0);
  feed(second, dv, ev, index_at(ev, 36.0), ev.size(), 100.0, live);
  const RestartPolicy& p = second.lifecycle.restart();
  EXPECT_NEAR(p.catch_up_lost_s(), 36.0 - t_ckpt, 0.05);
  std::string reason;
  bool warn = false;
  apply_restart_notes(p.health_notes(), 110.0, reason, warn);
  EXPECT_TRUE(warn);
  EXPECT_NE(reason.find("lost t=20.0-36.0 s after the checkpoint"), std::string::npos) << reason;
  // The odometer samples the checkpoint held (taken in up to the kill at 21 s) are processed; then
  // nothing until the history starts.
  ASSERT_FALSE(second.published.empty());
  EXPECT_GT(second.published.front().dr.t_s, t_ckpt);
  for (const Published& o : second.published) EXPECT_TRUE(o.dr.t_s <= 21.0 || o.dr.t_s >= 36.0) << o.dr.t_s;
  EXPECT_GE(second.published.back().dr.t_s, 69.9);
}
