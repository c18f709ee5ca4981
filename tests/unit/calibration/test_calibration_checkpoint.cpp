// The calibration's checkpoint and restart (calibration_checkpoint.hpp, restart_policy.hpp) in one
// process, on real files in a scratch state directory: a run killed at any point and restarted from
// its last checkpoint, fed the producers' history like the node, publishes exactly the outputs of an
// uninterrupted run (bit for bit, every field); corrupt and foreign checkpoints are moved aside and
// named; a history that does not reach back to the checkpoint is named as lost.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>

#include "odonav/calibration/calibration_lifecycle.hpp"
#include "odonav/calibration/misalignment_calibrator.hpp"
#include "checkpoint_test.hpp"
#include "synthetic_drive.hpp"

namespace {

using namespace odonav;
using namespace odonav::calibration;
using namespace odonav::synthetic;
using namespace odonav::test;
namespace fs = std::filesystem;

const Misalignment kTrueMis = checkpoint_misalignment();

const Eigen::Vector3d kLeverArm_m = checkpoint_lever_arm_body_m();  // GNSS antenna in the body frame (forward-left-up)

/// The calibrator compensates the lever arm with the yaw-rate window's body rate: the outputs
/// depend on the INS before each epoch (the window), which a restart must feed again.
MisalignmentCalibratorParams test_params() {
  MisalignmentCalibratorParams p;
  p.lever_arm_body_m = kLeverArm_m;
  return p;
}

/// 90 s on a 250 m circle at 10 m/s (2.3 deg/s, inside the straight-line gate), 0.05 m/s velocity
/// noise, antenna 1.4 m from the INS, with the gates' state exercised: the first 25 epochs biased by
/// 10 deg to the left (then 50 innovation rejections in a row and the suspension), three sideways
/// outliers, and a 0.8 s INS gap (attitude interpolated across it).
SyntheticData gated_drive() {
  const Trajectory t = checkpoint_circle();
  SyntheticData d = simulate(t, checkpoint_sensors(90.0, 11));
  auto left = [&](std::size_t i) {
    const Eigen::Vector3d u = t.direction(d.gnss[i].t_s);
    return Eigen::Vector3d(-u.y(), u.x(), 0.0);
  };
  for (std::size_t i = 0; i < 25; ++i) d.gnss[i].vel_enu_mps += std::tan(deg_to_rad(10.0)) * 10.0 * left(i);
  for (std::size_t i : {300u, 420u, 610u}) d.gnss.at(i).vel_enu_mps += 3.0 * left(i);
  d.ins.erase(
      std::remove_if(d.ins.begin(), d.ins.end(), [](const InsSample& s) { return s.t_s > 40.1 && s.t_s < 40.9; }),
      d.ins.end());
  return d;
}

/// One input sample in arrival order (merged by time, as the gateway publishes them).
struct Event {
  double t_s;
  bool gnss;
  std::size_t index;
};
std::vector<Event> events_of(const SyntheticData& d) {
  std::vector<Event> e;
  for (std::size_t i = 0; i < d.gnss.size(); ++i) e.push_back({d.gnss[i].t_s, true, i});
  for (std::size_t i = 0; i < d.ins.size(); ++i) e.push_back({d.ins[i].t_s, false, i});
  std::stable_sort(e.begin(), e.end(), [](const Event& a, const Event& b) { return a.t_s < b.t_s; });
  return e;
}

void expect_identical(const MisalignmentOutput& a, const MisalignmentOutput& b, const std::string& where) {
  EXPECT_EQ(std::memcmp(&a.t_s, &b.t_s, sizeof(double)), 0) << where;
  EXPECT_EQ(a.state, b.state) << where;
  EXPECT_EQ(a.epoch_status, b.epoch_status) << where;
  EXPECT_EQ(std::memcmp(&a.misalignment.heading_rad, &b.misalignment.heading_rad, sizeof(double)), 0) << where;
  EXPECT_EQ(std::memcmp(&a.misalignment.pitch_rad, &b.misalignment.pitch_rad, sizeof(double)), 0) << where;
  EXPECT_EQ(std::memcmp(&a.sigma_heading_rad, &b.sigma_heading_rad, sizeof(double)), 0) << where;
  EXPECT_EQ(std::memcmp(&a.sigma_pitch_rad, &b.sigma_pitch_rad, sizeof(double)), 0) << where;
  EXPECT_EQ(a.samples_used, b.samples_used) << where;
  EXPECT_EQ(a.converged, b.converged) << where;
  EXPECT_EQ(a.reason, b.reason) << where;
}

/// Gives `c` every sample of `d` and processes up to `t_s` (event time).
void feed_all_until(MisalignmentCalibrator& c, const SyntheticData& d, double t_s) {
  for (const auto& s : d.ins) c.add_ins(s);
  for (const auto& s : d.gnss) c.add_gnss(s);
  c.process_until(t_s);
}

class CalibrationCheckpointTest : public StateDirTest {
 protected:
  CalibrationCheckpointTest() : StateDirTest("calibration-vehicle-07.ckpt") {}

  /// A node's run over the events [from, to) (indices): feeds what the lifecycle does not skip,
  /// processes up to the minimum of the inputs' watermarks, publishes what the lifecycle keeps and
  /// checkpoints when due; at `to` == all events, finishes. The steady clock (s): the events before
  /// `live_from` (the producers' history) arrive at once at steady0_s, the later ones in real time.
  struct Run {
    MisalignmentCalibrator calibrator;
    CalibrationLifecycle lifecycle;
    std::vector<MisalignmentOutput> published;
    explicit Run(const CheckpointSettings& s)
        : calibrator(test_params()), lifecycle(s, kVehicle, calibrator.restore_margin_s()) {}
  };
  static void feed(Run& r, const SyntheticData& d, const std::vector<Event>& ev, std::size_t from, std::size_t to,
                   double steady0_s, std::size_t live_from = 0) {
    double wg = -std::numeric_limits<double>::infinity(), wi = wg;
    for (std::size_t k = from; k < to; ++k) {
      const Event& e = ev[k];
      const double steady_s =
          k < live_from ? steady0_s : steady0_s + 0.01 + (e.t_s - ev[std::min(live_from, to - 1)].t_s);
      if (e.gnss) {
        wg = e.t_s;
        if (!r.lifecycle.skip_sample(CalibrationInput::kGnss, e.t_s)) r.calibrator.add_gnss(d.gnss[e.index]);
      } else {
        wi = e.t_s;
        r.lifecycle.note_live_sample(e.t_s, steady_s);
        if (!r.lifecycle.skip_sample(CalibrationInput::kIns, e.t_s)) r.calibrator.add_ins(d.ins[e.index]);
      }
      for (auto& o : r.lifecycle.outputs_to_publish(r.calibrator.process_until(std::min(wg, wi)), steady_s))
        r.published.push_back(o);
      r.lifecycle.checkpoint_if_due(r.calibrator);
    }
    if (to == ev.size()) {
      for (auto& o : r.lifecycle.outputs_to_publish(r.calibrator.finish(), steady0_s)) r.published.push_back(o);
      r.lifecycle.checkpoint_at_finish(r.calibrator);
    }
  }
};

// ---- exact resume ----

TEST_F(CalibrationCheckpointTest,
       KilledAnywhereAndRestartedFromTheCheckpointItPublishesExactlyTheUninterruptedOutputs) {
  const SyntheticData d = gated_drive();
  const std::vector<Event> ev = events_of(d);
  Run reference(CheckpointSettings{});
  feed(reference, d, ev, 0, ev.size(), 0.0);
  ASSERT_EQ(reference.published.size(), d.gnss.size());
  // The drive did exercise the gates whose state the checkpoint carries: 50 rejections in a row
  // after the biased start (epochs 2.5-7.5 s, where two kills fall), then the suspension, and the
  // sideways outliers (52 rejected in all).
  EXPECT_GE(reference.calibrator.counters().outlier, 51u);
  EXPECT_GE(reference.calibrator.counters().innovation_suspended, 1u);

  // Kills during the biased start (rejections counting), right after the INS gap, and later.
  for (const double kill_t_s : {4.73, 7.05, 41.33, 43.02, 77.77}) {
    SCOPED_TRACE("killed at t=" + std::to_string(kill_t_s) + " s");
    fs::remove_all(dir_);
    const std::size_t kill = static_cast<std::size_t>(
        std::lower_bound(ev.begin(), ev.end(), kill_t_s, [](const Event& e, double t) { return e.t_s < t; }) -
        ev.begin());
    Run first(settings(1.0));
    first.lifecycle.start(first.calibrator, kUnixTime_s, 0.0);
    feed(first, d, ev, 0, kill, 0.0);  // no finish: kill -9
    EXPECT_GE(first.lifecycle.restart().checkpoints_written(), 2u);

    // The restart: the producers hand over their last 30 s, then the live data follows.
    Run second(settings(1.0));
    second.lifecycle.start(second.calibrator, kUnixTime_s, 100.0);
    ASSERT_TRUE(second.lifecycle.restored_t_s());
    const double t_ckpt = *second.lifecycle.restored_t_s();
    EXPECT_LE(t_ckpt, first.published.back().t_s);
    EXPECT_GT(t_ckpt, first.published.back().t_s - 1.0 - 1e-9);
    const auto restored = second.lifecycle.take_restored_output();
    ASSERT_TRUE(restored);
    EXPECT_FALSE(second.lifecycle.take_restored_output()) << "published once";
    const auto at_ckpt = std::find_if(reference.published.begin(), reference.published.end(),
                                      [&](const MisalignmentOutput& o) { return o.t_s == t_ckpt; });
    ASSERT_NE(at_ckpt, reference.published.end());
    MisalignmentOutput expected_restored = *at_ckpt;
    expected_restored.epoch_status = CalibrationEpochStatus::kUsed;  // not carried: the message has no field for it
    expect_identical(*restored, expected_restored, "restored output");
    // Restarted 2 s of data after the kill: its history reaches 30 s back from there.
    std::size_t live = kill, history = 0;
    while (live < ev.size() && ev[live].t_s < ev[kill].t_s + 2.0) ++live;
    while (history < ev.size() && ev[history].t_s < ev[live].t_s - kHistory_s) ++history;
    feed(second, d, ev, history, ev.size(), 100.0, live);

    // Every output after the checkpoint once, equal to the uninterrupted run's.
    std::vector<MisalignmentOutput> expected;
    for (const auto& o : reference.published)
      if (o.t_s > t_ckpt) expected.push_back(o);
    ASSERT_EQ(second.published.size(), expected.size());
    for (std::size_t i = 0; i < expected.size(); ++i)
      expect_identical(second.published[i], expected[i], "output " + std::to_string(i));
    const MisalignmentCounters& a = reference.calibrator.counters();
    const MisalignmentCounters& b = second.calibrator.counters();
    EXPECT_EQ(std::memcmp(&a, &b, sizeof a), 0) << "the counters go on across the restart";
    // The downtime's outputs were caught up: from the first after the checkpoint to the live edge.
    expect_caught_up(second.lifecycle.restart(), expected.front().t_s);
  }
}

TEST_F(CalibrationCheckpointTest, StateTextRoundTripsAndTheFileIsVersionedAndSelfDescribing) {
  const SyntheticData d = gated_drive();
  MisalignmentCalibrator a(test_params());
  feed_all_until(a, d, 50.0);
  const StateJson state = a.save_state();
  MisalignmentCalibrator b(test_params());
  b.restore_state(state);
  EXPECT_EQ(b.save_state(), state);
  EXPECT_EQ(b.save_state().dump(), state.dump()) << "saved, restored and saved again: the same bytes";
  const std::string text =
      serialize_calibration_checkpoint(CalibrationCheckpoint{kVehicle, kHash, a.current().t_s, state});
  // One JSON object in the shared envelope, one line.
  EXPECT_EQ(text.find('\n'), text.size() - 1) << text;
  const StateJson doc = StateJson::parse(text);
  EXPECT_EQ(doc.at("format"), "odonav-checkpoint");
  EXPECT_EQ(doc.at("component"), "calibration");
  EXPECT_EQ(doc.at("version"), kCalibrationCheckpointVersion);
  EXPECT_EQ(doc.at("vehicle"), "vehicle-07");
  EXPECT_EQ(doc.at("config_hash"), "0123456789abcdef");
  EXPECT_EQ(doc.at("checksum").get<std::string>().size(), 16u);
  EXPECT_EQ(doc.at("payload").at("calibrator"), state);
  EXPECT_TRUE(doc.at("payload").at("calibrator").at("heading").contains("sum_phi_y"));
  const CalibrationCheckpoint c = parse_calibration_checkpoint(text);
  EXPECT_EQ(c.last_sample_t_s, a.current().t_s);
  EXPECT_EQ(c.calibrator_state, state);
  // A GNSS epoch at or before the restored one is refused by the core itself.
  EXPECT_THROW(b.add_gnss(d.gnss[10]), StreamInputError);
}

// ---- corrupt and foreign checkpoints ----

TEST_F(CalibrationCheckpointTest, CorruptOrForeignCheckpointsAreMovedAsideNamedAndChangeNothing) {
  const SyntheticData d = gated_drive();
  MisalignmentCalibrator a(test_params());
  feed_all_until(a, d, 30.0);
  const std::string good =
      serialize_calibration_checkpoint(CalibrationCheckpoint{kVehicle, kHash, a.current().t_s, a.save_state()});
  // A flipped bit in a digit after a decimal point: the text stays valid JSON, only the checksum
  // sees it.
  std::string flipped = good;
  flipped[good.find('.', good.find("sum_phi_y")) + 1] ^= 0x01;
  StateJson bad_state = a.save_state();
  bad_state["frozen"] = 7;
  auto sealed = [&](const std::string& component, int version) {
    return seal_checkpoint(CheckpointIdentity{component, version, kVehicle, kHash},
                           StateJson::parse(good).at("payload"));
  };
  struct Case {
    std::string name, text, reason;
  };
  const std::vector<Case> cases{
      {"truncated", good.substr(0, good.size() / 2), "truncated"},
      {"flipped byte", flipped, "checksum mismatch: the file is corrupt"},
      {"garbage", "not a checkpoint\n", "not an odonav checkpoint"},
      {"older text checkpoint", "odonav-calibration-checkpoint 1\nvehicle vehicle-07\n",
       "an older text checkpoint ('odonav-calibration-checkpoint 1')"},
      {"other vehicle",
       serialize_calibration_checkpoint(CalibrationCheckpoint{"vehicle-99", kHash, 1.0, a.save_state()}),
       "made for vehicle 'vehicle-99', this is 'vehicle-07'"},
      {"other configuration",
       serialize_calibration_checkpoint(CalibrationCheckpoint{kVehicle, "fedcba9876543210", 1.0, a.save_state()}),
       "made with another configuration (hash fedcba9876543210, now 0123456789abcdef)"},
      {"bad state", serialize_calibration_checkpoint(CalibrationCheckpoint{kVehicle, kHash, 1.0, bad_state}),
       "calibrator state refused: field 'calibrator.frozen' is not true or false"},
      {"identification checkpoint", sealed("identification", kCalibrationCheckpointVersion),
       "made by odonav-identification, this is odonav-calibration"},
      {"future version", sealed("calibration", kCalibrationCheckpointVersion + 1),
       "checkpoint version " + std::to_string(kCalibrationCheckpointVersion + 1) + ", this build reads version " +
           std::to_string(kCalibrationCheckpointVersion)},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    write_checkpoint(c.text);
    MisalignmentCalibrator fresh(test_params());
    const StateJson fresh_state = fresh.save_state();
    CalibrationLifecycle l(settings(), kVehicle, fresh.restore_margin_s());
    l.start(fresh, kUnixTime_s, 10.0);
    EXPECT_EQ(fresh.save_state(), fresh_state) << "untouched";
    EXPECT_FALSE(l.restored_t_s());
    EXPECT_FALSE(l.take_restored_output());
    EXPECT_FALSE(fs::exists(ckpt_));
    // WARN in the health for 30 s, then gone.
    ASSERT_NO_FATAL_FAILURE(expect_moved_aside(l.restart(), c.text, "starting from nothing"));
    const CalibrationCheckpointLoad again =
        load_calibration_checkpoint(aside().string(), kVehicle, kHash, fresh, kUnixTime_s);
    EXPECT_NE(again.reason.find(c.reason), std::string::npos) << again.reason;
    std::string reason;
    bool warn = false;
    apply_restart_notes(l.restart().health_notes(), 40.1, reason, warn);
    EXPECT_FALSE(warn);
    EXPECT_EQ(reason, "");
    // Nothing is skipped: a fresh start.
    EXPECT_FALSE(l.skip_sample(CalibrationInput::kGnss, 0.1));
  }
}

// ---- a history that does not reach back ----

TEST_F(CalibrationCheckpointTest, AHistoryStartingAfterTheCheckpointIsNamedAsLost) {
  const SyntheticData d = gated_drive();
  const std::vector<Event> ev = events_of(d);
  Run first(settings(5.0));
  first.lifecycle.start(first.calibrator, kUnixTime_s, 0.0);
  std::size_t kill = 0;
  while (ev[kill].t_s < 21.0) ++kill;
  feed(first, d, ev, 0, kill, 0.0);  // checkpoints at the first epoch (t = 0) and every 5 s: the last at 20 s

  Run second(settings(5.0));
  second.lifecycle.start(second.calibrator, kUnixTime_s, 100.0);
  ASSERT_TRUE(second.lifecycle.restored_t_s());
  EXPECT_DOUBLE_EQ(*second.lifecycle.restored_t_s(), 20.0);
  std::size_t history = 0;
  while (ev[history].t_s < 24.0) ++history;  // the history starts 4 s after the checkpoint
  std::size_t live = history;
  while (ev[live].t_s < 26.0) ++live;
  feed(second, d, ev, history, ev.size(), 100.0, live);
  const RestartPolicy& p = second.lifecycle.restart();
  EXPECT_NEAR(p.catch_up_lost_s(), 4.0, 1e-9);
  // The GNSS epochs of 24.0 s on have attitude; the first published follows the first INS sample.
  ASSERT_FALSE(second.published.empty());
  EXPECT_GE(second.published.front().t_s, 24.0 - 1e-9);
  const RestartHealthNotes n = p.health_notes();
  EXPECT_TRUE(n.catch_up_warn);
  EXPECT_EQ(n.catch_up_note.rfind("lost t=20.0-24.0 s after the checkpoint (older than the producers' 30 s history): "
                                  "its estimates are missing; caught up after restart: ",
                                  0),
            0u)
      << n.catch_up_note;
}

}  // namespace
