// IdentificationLifecycle: the restart policy of odonav-identification in one process, on real
// files in a scratch state directory: restore (none, restored, corrupt, other configuration), the
// catch-up of the downtime's data and what was lost, which samples and outputs a restored run skips, the counters
// carried over, when checkpoints are written (and retried after a failure), the set_k stamp, and
// the health decision with its exact texts.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <random>

#include "odonav/config.hpp"
#include "odonav/estimators.hpp"
#include "odonav/identification/checkpoint.hpp"
#include "odonav/identification/identification_lifecycle.hpp"
#include "checkpoint_test.hpp"
#include "fed_core.hpp"

namespace {

using namespace odonav;
using namespace odonav::identification;
using namespace odonav::test;
namespace fs = std::filesystem;

constexpr double kTrueK = 0.0125;  // m/pulse

using State = ComponentHealth::State;
using Level = ComponentHealth::Level;

/// An identification core (vff_lm_rls) fed a straight 10 m/s drive of n GNSS epochs at 10 Hz
/// (velocity noise 2 cm/s, seed 7), everything processed.
std::unique_ptr<IdentificationCore> fed_core(std::size_t n) { return odonav::test::fed_core(n, "vff_lm_rls", 7); }
std::unique_ptr<IdentificationCore> fresh_core() {
  return std::make_unique<IdentificationCore>(IdentificationParams{});
}

/// An output at t_s (s) with these counters and, when given, the core's estimate.
IdentificationOutput output_at(double t_s, uint64_t accepted, uint64_t rejected,
                               const IdentificationCore* core = nullptr) {
  IdentificationOutput o;
  o.t_s = t_s;
  o.epoch_status = EpochStatus::kAccepted;
  if (core) o.main = core->main_estimator().estimate();
  o.samples_accepted = accepted;
  o.samples_rejected = rejected;
  return o;
}

class IdentificationLifecycleTest : public StateDirTest {
 protected:
  IdentificationLifecycleTest() : StateDirTest("identification-vehicle-07.ckpt") {}
  void SetUp() override {
    StateDirTest::SetUp();
    db_ = dir_ / "vehicle-07-identification.db";
  }

  /// A previous run: 300 epochs, its last published output at t = 30.1 s (300 accepted, 17
  /// rejected), having taken in odometer up to 30.3 s, GNSS up to 30.1 s, INS up to 30.25 s and a
  /// misalignment of 29.9 s; checkpointed. Returns the core it checkpointed.
  std::unique_ptr<IdentificationCore> previous_run(const std::string& hash = kHash) {
    auto e = fed_core(300);
    IdentificationLifecycle run(settings(5.0, hash), kVehicle);
    run.start(*e, kUnixTime_s, 0.0);
    for (const auto& [input, t] : {std::pair{IdentificationInput::kOdometer, 30.3},
                                   {IdentificationInput::kGnss, 30.1},
                                   {IdentificationInput::kIns, 30.25},
                                   {IdentificationInput::kMisalignment, 29.9}})
      EXPECT_FALSE(run.skip_sample(input, t));
    run.outputs_to_publish({output_at(30.1, 300, 17, e.get())});
    run.checkpoint_if_due(*e);
    EXPECT_EQ(run.checkpoints_written(), 1u);
    return e;
  }

  std::vector<fs::path> files_starting_with(const std::string& prefix) const {
    std::vector<fs::path> out;
    for (const auto& entry : fs::directory_iterator(dir_))
      if (entry.path().filename().string().rfind(prefix, 0) == 0) out.push_back(entry.path());
    return out;
  }

  fs::path db_;
};

// ---- restore ----

TEST_F(IdentificationLifecycleTest, WithoutStateDirectoryNothingIsReadSkippedOrWritten) {
  auto e = fed_core(50);
  IdentificationLifecycle l(CheckpointSettings{}, kVehicle);
  l.start(*e, kUnixTime_s, 0.0);
  EXPECT_FALSE(l.checkpointing());
  EXPECT_FALSE(fs::exists(dir_));
  EXPECT_FALSE(l.skip_sample(IdentificationInput::kGnss, -1e9));
  l.outputs_to_publish({output_at(100.0, 5, 1)});
  EXPECT_FALSE(l.checkpoint_due());
  l.checkpoint_if_due(*e);
  l.checkpoint_at_finish(*e);
  EXPECT_EQ(l.checkpoints_written(), 0u);
  EXPECT_EQ(l.checkpoint_errors(), 0u);
}

TEST_F(IdentificationLifecycleTest, NoCheckpointIsAFreshStartWithNothingSkipped) {
  auto e = fresh_core();
  IdentificationLifecycle l(settings(), kVehicle);
  l.start(*e, kUnixTime_s, 0.0);
  EXPECT_TRUE(fs::is_directory(dir_)) << "the state directory is created";
  EXPECT_EQ(l.checkpoint_file(), ckpt_.string());
  EXPECT_FALSE(l.restored_t_s());
  EXPECT_FALSE(l.checkpoint_moved_aside());
  EXPECT_FALSE(l.take_restored_output());
  EXPECT_FALSE(l.last_output());
  EXPECT_FALSE(l.skip_sample(IdentificationInput::kOdometer, -1e9));
  EXPECT_EQ(l.skipped_before_checkpoint(), 0u);
  const auto out = l.outputs_to_publish({output_at(0.1, 0, 0), output_at(0.2, 1, 0)});
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(out[1].samples_accepted, 1u) << "nothing restored: counters unchanged";
  EXPECT_EQ(l.health_facts(1.0).restore_note, "") << "a fresh start has nothing to say";
}

TEST_F(IdentificationLifecycleTest, RestoredCheckpointCarriesStateTimeAndCountersOver) {
  const auto before = previous_run();
  auto e = fresh_core();
  IdentificationLifecycle l(settings(), kVehicle);
  l.start(*e, kUnixTime_s, 1000.0);
  ASSERT_TRUE(l.restored_t_s());
  EXPECT_EQ(*l.restored_t_s(), 30.1);
  EXPECT_EQ(e->main_estimator().estimate().k_m_per_pulse, before->main_estimator().estimate().k_m_per_pulse)
      << "bit-identical K";
  EXPECT_EQ(e->save_state(), before->save_state()) << "the whole core: builder, estimator, counters";
  EXPECT_EQ(e->builder_counters().epochs, before->builder_counters().epochs);

  const auto restored = l.take_restored_output();
  ASSERT_TRUE(restored) << "the restored K is published at once";
  EXPECT_EQ(restored->t_s, 30.1);
  EXPECT_EQ(restored->samples_accepted, 300u) << "the restored counters, not added twice";
  EXPECT_EQ(restored->samples_rejected, 17u);
  EXPECT_EQ(restored->main.k_m_per_pulse, before->main_estimator().estimate().k_m_per_pulse);
  EXPECT_FALSE(l.take_restored_output()) << "published once";

  // The note: the describe() line, OK level, for 30 s of steady time.
  char expected[160];
  std::snprintf(expected, sizeof expected, "restored K=%.9g m/pulse from checkpoint (t=30.100 s)",
                before->main_estimator().estimate().k_m_per_pulse);
  IdentificationHealthFacts f = l.health_facts(1029.9);
  f.misalignment_heard = true;
  f.misalignments_applied = 3;
  EXPECT_EQ(f.restore_note, expected);
  EXPECT_FALSE(f.restore_warn);
  const ComponentHealth h = identification_health(f);
  EXPECT_EQ(h.reason, expected) << "the restored estimate is converged: the note alone";
  EXPECT_EQ(h.level, Level::kOk);
  f.now_s = 1030.0;
  EXPECT_EQ(identification_health(f).reason, "") << "the note expires 30 s after the start";
}

TEST_F(IdentificationLifecycleTest, CorruptCheckpointIsMovedAsideWithAWarnNote) {
  fs::create_directories(dir_);
  write_text(ckpt_, "odonav-identification-checkpoint 1\nvehicle vehicle-07\ngarbage");
  auto e = fresh_core();
  IdentificationLifecycle l(settings(), kVehicle);
  l.start(*e, kUnixTime_s, 500.0);
  EXPECT_TRUE(l.checkpoint_moved_aside());
  EXPECT_FALSE(l.restored_t_s());
  EXPECT_FALSE(l.take_restored_output());
  EXPECT_FALSE(e->main_estimator().estimate().valid) << "starts from nominal";
  EXPECT_FALSE(fs::exists(ckpt_));
  EXPECT_EQ(read_text(ckpt_.string() + ".bad-1700000000"),
            "odonav-identification-checkpoint 1\nvehicle vehicle-07\ngarbage")
      << "moved aside unchanged";

  IdentificationHealthFacts f = l.health_facts(529.0);
  f.misalignment_heard = true;
  f.misalignments_applied = 1;
  const std::string note = "checkpoint " + ckpt_.string() + " was corrupt: moved aside; starting from nominal K";
  ComponentHealth h = identification_health(f);
  EXPECT_EQ(h.state, State::kStarting);
  EXPECT_EQ(h.level, Level::kWarn);
  EXPECT_EQ(h.reason, note + "; waiting for the first GNSS epoch to process");
  f.now_s = 530.0;
  h = identification_health(f);
  EXPECT_EQ(h.level, Level::kOk) << "the WARN lasts as long as the note";
  EXPECT_EQ(h.reason, "waiting for the first GNSS epoch to process");
}

TEST_F(IdentificationLifecycleTest, CheckpointOfAnotherConfigurationIsMovedAsideAndNotRestored) {
  previous_run("fedcba9876543210");
  auto e = fresh_core();
  IdentificationLifecycle l(settings(), kVehicle);
  l.start(*e, kUnixTime_s, 0.0);
  EXPECT_TRUE(l.checkpoint_moved_aside());
  EXPECT_FALSE(l.restored_t_s());
  EXPECT_FALSE(e->main_estimator().estimate().valid) << "the other configuration's state must not be loaded";
  EXPECT_EQ(files_starting_with("identification-vehicle-07.ckpt.bad-").size(), 1u);
  EXPECT_TRUE(l.health_facts(0.0).restore_warn);
  // The next checkpoint goes under the normal name again, with this configuration's hash.
  auto fed = fed_core(20);
  l.outputs_to_publish({output_at(2.0, 20, 0, fed.get())});
  l.checkpoint_if_due(*fed);
  EXPECT_EQ(parse_checkpoint(read_text(ckpt_)).config_hash, kHash);
}

// ---- catch-up after a restore ----

TEST_F(IdentificationLifecycleTest, AnOldPersistenceDatabaseIsLeftAloneAndTheRestoredKIsPublished) {
  // A state directory of an earlier version (its writer kept a SQLite history there).
  previous_run();
  write_text(db_, "SQLite format 3");
  auto e = fresh_core();
  IdentificationLifecycle l(settings(), kVehicle);
  l.start(*e, kUnixTime_s, 0.0);
  EXPECT_EQ(read_text(db_), "SQLite format 3") << "not read, not moved, never deleted";
  const auto restored = l.take_restored_output();
  ASSERT_TRUE(restored) << "the TRANSIENT_LOCAL writer serves the restored K to late readers";
  EXPECT_EQ(restored->t_s, 30.1);
}

TEST_F(IdentificationLifecycleTest, OutputsUpToTheLiveEdgeAfterARestoreAreCatchUpUntilTheFirstLiveOne) {
  previous_run();  // checkpoint at t = 30.1 s
  auto e = fresh_core();
  IdentificationLifecycle l(settings(), kVehicle);
  l.start(*e, kUnixTime_s, 100.0);
  EXPECT_TRUE(l.catching_up());
  // The producers' history starts 20 s before the checkpoint: it reaches back, nothing is lost.
  EXPECT_TRUE(l.skip_sample(IdentificationInput::kOdometer, 10.1));
  EXPECT_TRUE(l.skip_sample(IdentificationInput::kGnss, 10.1));
  EXPECT_TRUE(l.skip_sample(IdentificationInput::kIns, 10.1));
  // The history arrives within the settling time (up to t = 45 s), the live data after it.
  l.note_odometer_received(10.1, 100.0);
  l.note_odometer_received(45.0, 100.4);
  // Processed before the edge is fixed: catch-up.
  auto out = l.outputs_to_publish({output_at(30.1, 0, 0), output_at(30.2, 1, 0), output_at(43.9, 130, 7)}, 100.5);
  ASSERT_EQ(out.size(), 2u) << "the epoch of the checkpoint was published already";
  EXPECT_EQ(l.catch_up_outputs(), 2u);
  EXPECT_TRUE(l.catching_up());
  EXPECT_EQ(l.health_facts(100.5).catch_up_note,
            "catching up from the checkpoint: 2 estimates t=30.2-43.9 s published late");
  EXPECT_FALSE(l.health_facts(100.5).catch_up_warn);
  l.note_odometer_received(45.01, 101.2);  // live, after the settling time: the edge is t = 45 s
  l.note_odometer_received(47.0, 103.0);
  l.outputs_to_publish({output_at(45.0, 137, 7), output_at(45.1, 138, 7), output_at(45.2, 139, 7)}, 103.0);
  EXPECT_FALSE(l.catching_up()) << "45.1 s is past the edge";
  EXPECT_EQ(l.catch_up_outputs(), 3u);
  EXPECT_EQ(*l.catch_up_first_t_s(), 30.2);
  EXPECT_EQ(*l.catch_up_last_t_s(), 45.0);
  EXPECT_DOUBLE_EQ(l.catch_up_lost_s(), 0.0);
  l.outputs_to_publish({output_at(45.3, 140, 7)}, 103.1);
  EXPECT_EQ(l.catch_up_outputs(), 3u) << "never catch-up again";
  const auto f = l.health_facts(110.0);
  EXPECT_EQ(f.catch_up_note, "caught up after restart: 3 estimates t=30.2-45.0 s published late");
  EXPECT_EQ(f.catch_up_note_until_s, 103.0 + kRestoreNoteDuration_s);
  EXPECT_EQ(identification_health(l.health_facts(103.0 + kRestoreNoteDuration_s + 1.0)).reason.find("caught up"),
            std::string::npos)
      << "the note goes after 30 s";
}

TEST_F(IdentificationLifecycleTest, AHistoryStartingAfterTheCheckpointIsALossNamedInTheHealth) {
  previous_run();  // checkpoint at t = 30.1 s
  auto e = fresh_core();
  IdentificationLifecycle l(settings(), kVehicle);
  l.start(*e, kUnixTime_s, 100.0);
  // Down for longer than the odometer's 30 s history: its first sample is t = 42.5 s.
  EXPECT_TRUE(l.skip_sample(IdentificationInput::kGnss, 30.1)) << "taken in before the restart";
  EXPECT_FALSE(l.skip_sample(IdentificationInput::kOdometer, 42.5));
  EXPECT_FALSE(l.skip_sample(IdentificationInput::kOdometer, 42.6)) << "only the first sample tells";
  EXPECT_TRUE(l.first_sample_seen(IdentificationInput::kOdometer));
  EXPECT_FALSE(l.first_sample_seen(IdentificationInput::kIns));
  // GNSS epochs of the lost span are skipped (no data to process them with), later ones are fed.
  EXPECT_TRUE(l.skip_sample(IdentificationInput::kGnss, 30.2));
  EXPECT_TRUE(l.skip_sample(IdentificationInput::kGnss, 42.4));
  EXPECT_FALSE(l.skip_sample(IdentificationInput::kGnss, 42.5));
  EXPECT_EQ(l.catch_up_lost_epochs(), 2u);
  ASSERT_TRUE(l.lost_until_t_s());
  EXPECT_EQ(*l.lost_until_t_s(), 42.5);
  EXPECT_NEAR(l.catch_up_lost_s(), 12.4, 1e-12);
  const auto f = l.health_facts(100.0);
  EXPECT_TRUE(f.catch_up_warn);
  EXPECT_EQ(f.catch_up_note,
            "lost t=30.1-42.5 s after the checkpoint (older than the producers' 30 s history): its estimates are "
            "missing");
  const auto h = identification_health(f);
  EXPECT_EQ(h.level, Level::kWarn);
  EXPECT_EQ(h.reason.rfind("lost t=30.1-42.5 s after the checkpoint", 0), 0u) << h.reason;
}

TEST_F(IdentificationLifecycleTest, AFreshStartHasNoCatchUp) {
  auto e = fresh_core();
  IdentificationLifecycle l(settings(), kVehicle);
  l.start(*e, kUnixTime_s, 0.0);
  EXPECT_FALSE(l.catching_up());
  EXPECT_FALSE(l.skip_sample(IdentificationInput::kOdometer, 50.0));
  l.note_odometer_received(50.0, 1.0);
  l.outputs_to_publish({output_at(1.0, 0, 0)}, 1.0);
  EXPECT_EQ(l.catch_up_outputs(), 0u);
  EXPECT_FALSE(l.lost_until_t_s());
  EXPECT_EQ(l.health_facts(1.0).catch_up_note, "");
}

TEST_F(IdentificationLifecycleTest, UnusableStateDirectoryIsAConfigErrorNamingIt) {
  fs::create_directories(dir_.parent_path());
  write_text(dir_, "a file, not a folder");
  auto e = fresh_core();
  IdentificationLifecycle l(settings(), kVehicle);
  try {
    l.start(*e, kUnixTime_s, 0.0);
    FAIL() << "expected ConfigError";
  } catch (const ConfigError& err) {
    EXPECT_EQ(std::string(err.what()).rfind("--state-dir '" + dir_.string() + "': ", 0), 0u) << err.what();
  }
  fs::remove(dir_);
}

// ---- after a restore: skipped samples, published outputs ----

TEST_F(IdentificationLifecycleTest, SamplesTakenInBeforeTheCheckpointAreSkippedPerInput) {
  previous_run();  // checkpoint at t = 30.1 s; odometer to 30.3, GNSS to 30.1, INS to 30.25, misalignment 29.9
  auto e = fresh_core();
  IdentificationLifecycle l(settings(), kVehicle);
  l.start(*e, kUnixTime_s, 0.0);
  // Each input up to the last stamp the restored core had taken in, whatever the checkpoint time:
  // the builder holds odometer and INS past its last epoch.
  EXPECT_TRUE(l.skip_sample(IdentificationInput::kGnss, 30.0));
  EXPECT_TRUE(l.skip_sample(IdentificationInput::kGnss, 30.1)) << "the epoch of the checkpoint was processed";
  EXPECT_FALSE(l.skip_sample(IdentificationInput::kGnss, 30.2));
  EXPECT_TRUE(l.skip_sample(IdentificationInput::kOdometer, 30.3));
  EXPECT_FALSE(l.skip_sample(IdentificationInput::kOdometer, 30.32));
  EXPECT_TRUE(l.skip_sample(IdentificationInput::kIns, 30.25));
  EXPECT_FALSE(l.skip_sample(IdentificationInput::kIns, 30.26));
  EXPECT_TRUE(l.skip_sample(IdentificationInput::kMisalignment, 29.9));
  EXPECT_FALSE(l.skip_sample(IdentificationInput::kMisalignment, 30.0));
  EXPECT_EQ(l.skipped_before_checkpoint(), 5u);
  // What is taken in now is the next checkpoint's.
  l.outputs_to_publish({output_at(30.2, 301, 17, e.get())});
  const IdentificationCheckpoint c = l.make_checkpoint(*e, 30.2);
  EXPECT_EQ(*c.fed_until_s[0], 30.32);
  EXPECT_EQ(*c.fed_until_s[1], 30.2);
  EXPECT_EQ(*c.fed_until_s[2], 30.26);
  EXPECT_EQ(*c.fed_until_s[3], 30.0);
}

TEST_F(IdentificationLifecycleTest, OutputsUpToTheCheckpointAreDroppedAndTheRestKeepTheCoreCounters) {
  previous_run();  // 300 accepted, 17 rejected at t = 30.1 s
  auto e = fresh_core();
  IdentificationLifecycle l(settings(), kVehicle);
  l.start(*e, kUnixTime_s, 0.0);
  const auto out = l.outputs_to_publish(
      {output_at(30.0, 299, 17), output_at(30.1, 300, 17), output_at(30.2, 301, 17), output_at(30.3, 302, 18)});
  ASSERT_EQ(out.size(), 2u) << "30.0 and 30.1 were published by the previous run";
  EXPECT_EQ(out[0].t_s, 30.2);
  EXPECT_EQ(out[0].samples_accepted, 301u) << "the restored core counts on: nothing is added";
  EXPECT_EQ(out[0].samples_rejected, 17u);
  EXPECT_EQ(out[1].t_s, 30.3);
  EXPECT_EQ(out[1].samples_accepted, 302u);
  EXPECT_EQ(out[1].samples_rejected, 18u);
  ASSERT_TRUE(l.last_output());
  EXPECT_EQ(l.last_output()->samples_accepted, 302u);
  EXPECT_EQ(*l.last_processed_t_s(), 30.3);
}

// ---- checkpoints ----

TEST_F(IdentificationLifecycleTest, CheckpointIsDueEveryPeriodOfProcessedEventTime) {
  auto e = fed_core(100);
  IdentificationLifecycle l(settings(5.0), kVehicle);
  l.start(*e, kUnixTime_s, 0.0);
  EXPECT_FALSE(l.checkpoint_due()) << "nothing processed yet";
  l.outputs_to_publish({output_at(10.0, 100, 2, e.get())});
  EXPECT_TRUE(l.checkpoint_due()) << "the first processed epoch is checkpointed at once";
  l.checkpoint_if_due(*e);
  EXPECT_EQ(l.checkpoints_written(), 1u);
  EXPECT_EQ(parse_checkpoint(read_text(ckpt_)).last_sample_t_s, 10.0);

  l.outputs_to_publish({output_at(14.9, 149, 2, e.get())});
  EXPECT_FALSE(l.checkpoint_due()) << "4.9 s after the last one";
  l.checkpoint_if_due(*e);
  EXPECT_EQ(l.checkpoints_written(), 1u);
  l.outputs_to_publish({output_at(15.0, 150, 3, e.get())});
  EXPECT_TRUE(l.checkpoint_due()) << "5 s after the last one";
  l.checkpoint_if_due(*e);
  EXPECT_EQ(l.checkpoints_written(), 2u);

  const IdentificationCheckpoint c = parse_checkpoint(read_text(ckpt_));
  EXPECT_EQ(c.vehicle_id, kVehicle);
  EXPECT_EQ(c.config_hash, kHash);
  EXPECT_EQ(c.estimator_name, "vff_lm_rls");
  EXPECT_EQ(c.last_sample_t_s, 15.0);
  EXPECT_EQ(c.samples_accepted, 150u);
  EXPECT_EQ(c.samples_rejected, 3u);
  EXPECT_EQ(c.core_state, e->save_state());
}

TEST_F(IdentificationLifecycleTest, RestoredCheckpointCountsAsTheLastOne) {
  previous_run();  // at t = 30.1 s
  auto e = fresh_core();
  IdentificationLifecycle l(settings(5.0), kVehicle);
  l.start(*e, kUnixTime_s, 0.0);
  EXPECT_FALSE(l.checkpoint_due()) << "the restored state is on disk already";
  l.outputs_to_publish({output_at(35.0, 340, 18)});
  EXPECT_FALSE(l.checkpoint_due());
  l.outputs_to_publish({output_at(35.2, 341, 18)});
  EXPECT_TRUE(l.checkpoint_due());
  EXPECT_EQ(l.make_checkpoint(*e, 35.2).samples_accepted, 341u);
}

TEST_F(IdentificationLifecycleTest, FailedCheckpointWriteIsCountedWarnedAndRetriedAtTheNextPeriod) {
  auto e = fed_core(100);
  IdentificationLifecycle l(settings(5.0), kVehicle);
  l.start(*e, kUnixTime_s, 0.0);
  ASSERT_TRUE(e->main_estimator().estimate().valid && e->main_estimator().estimate().converged);
  fs::remove_all(dir_);  // the state directory is gone: the write cannot create its temporary file

  l.outputs_to_publish({output_at(10.0, 100, 0, e.get())});
  l.checkpoint_if_due(*e);
  EXPECT_EQ(l.checkpoint_errors(), 1u);
  EXPECT_EQ(l.checkpoints_written(), 0u);
  IdentificationHealthFacts f = l.health_facts(0.0);
  f.misalignment_heard = true;
  f.misalignments_applied = 1;
  ComponentHealth h = identification_health(f);
  EXPECT_EQ(h.level, Level::kWarn);
  EXPECT_EQ(h.reason, "1 checkpoint writes failed") << "the estimate of 100 samples is converged";

  fs::create_directories(dir_);
  l.outputs_to_publish({output_at(12.0, 120, 0, e.get())});
  EXPECT_FALSE(l.checkpoint_due()) << "not retried at the next epoch: a full disk is not hammered";
  l.checkpoint_if_due(*e);
  EXPECT_EQ(l.checkpoint_errors(), 1u);
  l.outputs_to_publish({output_at(15.0, 150, 0, e.get())});
  l.checkpoint_if_due(*e);
  EXPECT_EQ(l.checkpoints_written(), 1u) << "retried one period after the failure";
  EXPECT_EQ(parse_checkpoint(read_text(ckpt_)).last_sample_t_s, 15.0);
  EXPECT_EQ(l.checkpoint_errors(), 1u) << "the count stays: the health keeps telling";
}

TEST_F(IdentificationLifecycleTest, FinishCheckpointsTheLastProcessedEpochOnce) {
  auto e = fed_core(100);
  IdentificationLifecycle l(settings(5.0), kVehicle);
  l.start(*e, kUnixTime_s, 0.0);
  l.outputs_to_publish({output_at(10.0, 100, 0, e.get())});
  l.checkpoint_if_due(*e);
  l.outputs_to_publish({output_at(12.5, 125, 0, e.get())});
  l.checkpoint_if_due(*e);
  EXPECT_EQ(l.checkpoints_written(), 1u);
  l.checkpoint_at_finish(*e);
  EXPECT_EQ(l.checkpoints_written(), 2u);
  EXPECT_EQ(parse_checkpoint(read_text(ckpt_)).last_sample_t_s, 12.5);
  l.checkpoint_at_finish(*e);
  EXPECT_EQ(l.checkpoints_written(), 2u) << "already the last one";
}

// ---- set_k ----

TEST_F(IdentificationLifecycleTest, SetKStampIsTheLastProcessedEpochElseTheAlignerElseZero) {
  IdentificationLifecycle fresh(CheckpointSettings{}, kVehicle);
  EXPECT_EQ(fresh.set_k_stamp_s(-std::numeric_limits<double>::infinity()), 0.0) << "nothing processed anywhere";
  EXPECT_EQ(fresh.set_k_stamp_s(std::nan("")), 0.0);
  EXPECT_EQ(fresh.set_k_stamp_s(42.5), 42.5) << "what the aligner released";
  fresh.outputs_to_publish({output_at(50.0, 10, 0)});
  EXPECT_EQ(fresh.set_k_stamp_s(60.0), 50.0) << "the output it replaces";

  previous_run();
  auto e = fresh_core();
  IdentificationLifecycle restored(settings(), kVehicle);
  restored.start(*e, kUnixTime_s, 0.0);
  EXPECT_EQ(restored.set_k_stamp_s(-std::numeric_limits<double>::infinity()), 30.1) << "the restored epoch";
  const IdentificationOutput o = restored.commanded_output(output_at(30.1, 300, 17));
  EXPECT_EQ(o.samples_accepted, 300u);
  EXPECT_EQ(o.samples_rejected, 17u);
  EXPECT_EQ(restored.last_output()->samples_accepted, 300u);
  EXPECT_EQ(*restored.last_processed_t_s(), 30.1) << "a command adds no epoch";
}

// ---- health ----

IdentificationHealthFacts running_facts(bool converged) {
  IdentificationHealthFacts f;
  f.last_output = IdentificationOutput{};
  f.last_output->main.valid = true;
  f.last_output->main.converged = converged;
  f.last_output->main.k_m_per_pulse = kTrueK;
  f.last_output->latency_decided = true;
  f.misalignment_heard = true;
  f.misalignments_applied = 4;
  f.now_s = 100.0;
  return f;
}

TEST(IdentificationHealthDecision, ConvergedWithMisalignmentIsRunningOkWithoutReason) {
  const ComponentHealth h = identification_health(running_facts(true));
  EXPECT_EQ(h.state, State::kRunning);
  EXPECT_EQ(h.level, Level::kOk);
  EXPECT_EQ(h.reason, "");
}

TEST(IdentificationHealthDecision, AKWaitingForTheLatencySearchSaysWhatIsMissing) {
  IdentificationHealthFacts f = running_facts(false);
  f.last_output->latency_decided = false;
  f.last_output->latency.estimate_s = 0.023;
  f.last_output->latency.sigma_s = 0.008;
  f.last_output->latency.samples = 120;
  ComponentHealth h = identification_health(f);
  EXPECT_EQ(h.state, State::kRunning);
  EXPECT_EQ(h.level, Level::kOk);
  EXPECT_EQ(
      h.reason,
      "K not converged yet: GNSS latency not decided (estimate 23.0 +- 8.0 ms from 120 samples, 0.0 ms in force)");
  f.last_output->latency = GnssLatencyEstimate{};
  f.last_output->latency.reason = "12 s of samples, 20 s needed";
  EXPECT_EQ(identification_health(f).reason,
            "K not converged yet: GNSS latency not decided (no estimate yet: 12 s of samples, 20 s needed)");
  f.last_output->main.valid = false;
  EXPECT_EQ(identification_health(f).reason, "K not converged yet") << "no K: the latency is not the reason";
}

TEST(IdentificationHealthDecision, WaitingFrozenAndNotConverged) {
  IdentificationHealthFacts f = running_facts(true);
  f.last_output.reset();
  ComponentHealth h = identification_health(f);
  EXPECT_EQ(h.state, State::kStarting);
  EXPECT_EQ(h.reason, "waiting for the first GNSS epoch to process");

  f = running_facts(false);
  h = identification_health(f);
  EXPECT_EQ(h.state, State::kRunning);
  EXPECT_EQ(h.level, Level::kOk);
  EXPECT_EQ(h.reason, "K not converged yet");
  f.last_output->main.valid = false;
  f.last_output->main.converged = true;
  EXPECT_EQ(identification_health(f).reason, "K not converged yet") << "no value is not converged";

  f = running_facts(false);
  f.last_output->frozen = true;
  h = identification_health(f);
  EXPECT_EQ(h.reason, "frozen by command: K held") << "frozen is said instead of not converged";
  EXPECT_EQ(h.level, Level::kOk);
}

TEST(IdentificationHealthDecision, ZeroMisalignmentTextsNeverRaiseTheLevel) {
  IdentificationHealthFacts f = running_facts(true);
  f.misalignment_heard = false;
  f.misalignments_applied = 0;
  ComponentHealth h = identification_health(f);
  EXPECT_EQ(h.reason, "no misalignment received yet: using zero");
  EXPECT_EQ(h.state, State::kRunning);
  EXPECT_EQ(h.level, Level::kOk);

  f.misalignment_heard = true;
  h = identification_health(f);
  EXPECT_EQ(h.reason, "misalignment not converged yet: using zero");
  EXPECT_EQ(h.state, State::kRunning);

  f.misalignment_absent = true;
  h = identification_health(f);
  EXPECT_EQ(h.reason, "using zero misalignment: no calibration");
  EXPECT_EQ(h.state, State::kDegraded) << "a calibration that went away degrades the node";
  EXPECT_EQ(h.level, Level::kOk);
  // Gone after some were applied: the core holds the last one, and the text says so (not "zero").
  {
    IdentificationHealthFacts held = f;
    held.misalignments_applied = 7;
    held.held_misalignment_t_s = 61.3;
    held.misalignment_silent_s = 3.4;
    EXPECT_EQ(identification_health(held).reason, "holding misalignment of t=61.3 s (calibration silent 3 s)");
    EXPECT_EQ(identification_health(held).state, State::kDegraded);
  }

  f = running_facts(false);
  f.misalignment_absent = true;
  EXPECT_EQ(identification_health(f).reason, "K not converged yet; using zero misalignment: no calibration");
  f.last_output.reset();
  h = identification_health(f);
  EXPECT_EQ(h.state, State::kStarting) << "only RUNNING becomes DEGRADED";
  EXPECT_EQ(h.reason, "waiting for the first GNSS epoch to process; using zero misalignment: no calibration");
}

TEST(IdentificationHealthDecision, RestoreNoteComesFirstUntilItExpires) {
  IdentificationHealthFacts f = running_facts(false);
  f.restore_note = "restored K=0.0126 m/pulse from checkpoint (t=61.200 s)";
  f.restore_note_until_s = 130.0;
  f.now_s = 129.99;
  ComponentHealth h = identification_health(f);
  EXPECT_EQ(h.reason, "restored K=0.0126 m/pulse from checkpoint (t=61.200 s); K not converged yet");
  EXPECT_EQ(h.level, Level::kOk);
  f.restore_warn = true;
  EXPECT_EQ(identification_health(f).level, Level::kWarn);
  f.now_s = 130.0;
  h = identification_health(f);
  EXPECT_EQ(h.reason, "K not converged yet");
  EXPECT_EQ(h.level, Level::kOk);
}

TEST(IdentificationHealthDecision, CheckpointErrorsWarnFirstUnlessAlreadyWarned) {
  IdentificationHealthFacts f = running_facts(false);
  f.checkpoint_errors = 2;
  ComponentHealth h = identification_health(f);
  EXPECT_EQ(h.level, Level::kWarn);
  EXPECT_EQ(h.reason, "2 checkpoint writes failed; K not converged yet");

  f.restore_note = "checkpoint /s/identification-v.ckpt was corrupt: moved aside; starting from nominal K";
  f.restore_warn = true;
  f.restore_note_until_s = 1e9;
  h = identification_health(f);
  EXPECT_EQ(h.level, Level::kWarn);
  EXPECT_EQ(h.reason, f.restore_note + "; K not converged yet") << "already WARN: the count is not added";
}

}  // namespace
