// Dead reckoning's K policy (scale_factor_selection.hpp), its health decision, the one
// DeadReckonerParams function shared with odonav-offline, and the commanded-K range of
// consumer_rules.hpp.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <sstream>

#include "odonav/consumer_rules.hpp"
#include "odonav/defaults.hpp"
#include "odonav/dead_reckoning/dead_reckoning_health.hpp"
#include "odonav/dead_reckoning/dead_reckoning_options.hpp"
#include "odonav/dead_reckoning/scale_factor_selection.hpp"
#include "odonav/lever_arm_option.hpp"
#include "odonav/nominal_k_option.hpp"
#include "dr_health_facts.hpp"

using namespace odonav;
using namespace odonav::dead_reckoning;

namespace {

constexpr double kNominalK = 0.0125;  // m/pulse
constexpr double kInf = std::numeric_limits<double>::infinity();

IdentifiedScaleFactor identified(double t_s, double k, bool converged = true,
                                 const std::string& source = "identification") {
  return IdentifiedScaleFactor{t_s, k, converged, source};
}

}  // namespace

// ---- consumer_rules.hpp: when an estimate replaces the nominal value ----

TEST(ScaleFactorApplicable, ConvergedIsAppliedWhateverItsDistanceFromTheNominal) {
  EXPECT_TRUE(scale_factor_applicable(true, true, kNominalK, 1e-6, 20, kNominalK));
  EXPECT_FALSE(scale_factor_applicable(false, true, kNominalK, 1e-6, 20, kNominalK));  // no value
}

TEST(ScaleFactorApplicable, ProvisionalKBeatingTheNominalByThreeSigmaIsApplied) {
  // Nominal 100 % wrong (true K 0.025): a 5-sample K of 0.0246 +- 0.0005 (2 %) is 24 sigma away.
  EXPECT_TRUE(scale_factor_applicable(true, false, 0.0246, 0.0005, 5, kNominalK));
  // 1.5 % away with sigma 0.45 %: 3.3 sigma, applied; with sigma 0.67 %: 2.2 sigma, not yet.
  EXPECT_TRUE(scale_factor_applicable(true, false, 0.0126875, 0.0125 * 0.0045, 29, kNominalK));
  EXPECT_FALSE(scale_factor_applicable(true, false, 0.0126875, 0.0125 * 0.0067, 13, kNominalK));
  // 2.9 sigma is not enough, 3.1 sigma is.
  EXPECT_FALSE(scale_factor_applicable(true, false, 0.01279, 0.0001, 50, kNominalK));
  EXPECT_TRUE(scale_factor_applicable(true, false, 0.01281, 0.0001, 50, kNominalK));
}

TEST(ScaleFactorApplicable, ProvisionalKNeedsFiveSamplesAndAKnownSigma) {
  EXPECT_FALSE(scale_factor_applicable(true, false, 0.025, 0.0001, 4, kNominalK));  // sigma rests on < 4 residuals
  EXPECT_TRUE(scale_factor_applicable(true, false, 0.025, 0.0001, 5, kNominalK));
  EXPECT_FALSE(scale_factor_applicable(true, false, 0.025, -1.0, 50, kNominalK));  // unknown (message)
  EXPECT_FALSE(scale_factor_applicable(true, false, 0.025, kInf, 50, kNominalK));
  EXPECT_FALSE(scale_factor_applicable(true, false, 0.025, 0.0, 50, kNominalK));
  EXPECT_FALSE(scale_factor_applicable(true, false, std::nan(""), 0.0001, 50, kNominalK));
}

TEST(ScaleFactorApplicable, ProvisionalKWhoseSigmaIsBelowTheNominalsIsAppliedWhateverTheirDifference) {
  const double nominal_sigma = 0.02 * kNominalK;  // 2 %
  // 0.5 % from the nominal with sigma 1 %: not 3 sigma away, but known better than the nominal.
  EXPECT_FALSE(scale_factor_applicable(true, false, 0.0125625, 0.0125 * 0.01, 20, kNominalK));
  EXPECT_TRUE(scale_factor_applicable(true, false, 0.0125625, 0.0125 * 0.01, 20, kNominalK, false, nominal_sigma));
  // Sigma 2.5 %: the nominal is the better known; and five samples first, a sigma known.
  EXPECT_FALSE(scale_factor_applicable(true, false, 0.0125625, 0.0125 * 0.025, 20, kNominalK, false, nominal_sigma));
  EXPECT_FALSE(scale_factor_applicable(true, false, 0.0125625, 0.0125 * 0.01, 4, kNominalK, false, nominal_sigma));
  EXPECT_FALSE(scale_factor_applicable(true, false, 0.0125625, -1.0, 20, kNominalK, false, nominal_sigma));
  // The selection weighs with the nominal's sigma it was given (default 3 %; 0: the 3 sigma test alone).
  EXPECT_TRUE(ScaleFactorSelection(kNominalK).on_identified(
      IdentifiedScaleFactor{1.0, 0.0125625, false, "identification", 0.0125 * 0.01, 20}, 0.0));
  EXPECT_FALSE(
      ScaleFactorSelection(kNominalK, 0.0)
          .on_identified(IdentifiedScaleFactor{1.0, 0.0125625, false, "identification", 0.0125 * 0.01, 20}, 0.0));
  EXPECT_FALSE(
      ScaleFactorSelection(kNominalK, 0.005)
          .on_identified(IdentifiedScaleFactor{1.0, 0.0125625, false, "identification", 0.0125 * 0.01, 20}, 0.0));
}

TEST(MisalignmentApplicable, ConvergedOrHundredEpochsAsBefore) {
  EXPECT_TRUE(misalignment_applicable(true, 3, 0.0, 0.0, 1.0, 1.0));
  EXPECT_TRUE(misalignment_applicable(false, 100, 0.0, 0.0, 1.0, 1.0));
  EXPECT_FALSE(misalignment_applicable(false, 99, 0.0, 0.0, 1.0, 1.0));
}

TEST(MisalignmentApplicable, ProvisionalWhenEitherAngleBeatsZeroByThreeSigma) {
  const double deg = M_PI / 180.0;
  // sim:terrain seed 1 after 11 epochs: heading 1.19 +- 0.29 deg (4.1 sigma), pitch -0.37 +- 0.14 deg.
  EXPECT_TRUE(misalignment_applicable(false, 11, 1.19 * deg, -0.37 * deg, 0.29 * deg, 0.14 * deg));
  // Heading alone within 3 sigma of zero, pitch 4 sigma away: applied (both angles).
  EXPECT_TRUE(misalignment_applicable(false, 20, 0.1 * deg, -0.4 * deg, 0.1 * deg, 0.1 * deg));
  // After 6 epochs, 1.32 +- 0.49 deg is 2.7 sigma and the pitch 1.6 sigma: zero is kept.
  EXPECT_FALSE(misalignment_applicable(false, 6, 1.32 * deg, -0.36 * deg, 0.49 * deg, 0.23 * deg));
  // Fewer than five epochs, or unknown sigmas (-1 in the message, infinity in the core): zero.
  EXPECT_FALSE(misalignment_applicable(false, 4, 5.0 * deg, 0.0, 0.01 * deg, 0.01 * deg));
  EXPECT_FALSE(misalignment_applicable(false, 50, 5.0 * deg, 5.0 * deg, -1.0, kInf));
}

TEST(DeadReckoningScaleFactorSelection, AppliesAProvisionalKThatBeatsTheNominal) {
  ScaleFactorSelection sel(kNominalK);
  IdentifiedScaleFactor k = identified(1.0, 0.025, false);
  k.sigma_m_per_pulse = 0.0005;
  k.samples_accepted = 4;
  EXPECT_FALSE(sel.on_identified(k, 0.0));  // four samples: not yet
  k.t_s = 1.1;
  k.samples_accepted = 5;
  const auto u = sel.on_identified(k, 0.0);
  ASSERT_TRUE(u);
  EXPECT_DOUBLE_EQ(u->k_m_per_pulse, 0.025);
  EXPECT_EQ(u->source, ScaleFactorSource::kIdentified);
  // Close to the nominal and not converged: the nominal stays, unless an estimate of the same
  // identification is in force already, which the later one replaces.
  ScaleFactorSelection fresh(kNominalK);
  k.t_s = 1.2;
  k.k_m_per_pulse = 0.0126;
  EXPECT_FALSE(fresh.on_identified(k, 0.0));
  EXPECT_TRUE(sel.on_identified(k, 0.0));
}

TEST(ScaleFactorApplicable, ALaterEstimateOfTheStreamInForceNeedsNotBeatTheNominalAgain) {
  // terrain seed 8, 1 Hz GNSS, 200 ms latency, 15.2 s: 0.012317 +- 0.000070 is 2.6 sigma from the
  // nominal 0.0125, but the K in force is the same instance's 0.012250 of one epoch before.
  EXPECT_FALSE(scale_factor_applicable(true, false, 0.012317, 7.0e-5, 9, kNominalK));
  EXPECT_TRUE(scale_factor_applicable(true, false, 0.012317, 7.0e-5, 9, kNominalK, true));
  // Still a valid value with kProvisionalMinSamples behind it.
  EXPECT_FALSE(scale_factor_applicable(true, false, 0.012317, 7.0e-5, 4, kNominalK, true));
  EXPECT_FALSE(scale_factor_applicable(false, false, 0.012317, 7.0e-5, 9, kNominalK, true));
}

TEST(DeadReckoningScaleFactorSelection, LaterEstimatesOfTheSourceInForceReplaceItWithoutBeatingTheNominal) {
  // Before, the first provisional K (-3.5 %, 3.5 sigma from the nominal) stayed in force for 15 s
  // while the same identification's estimates moved to -2.5 ... -0.3 %, each under 3 sigma from
  // the nominal: the DR laid out 15 m of error in the first minute. (The nominal K's own sigma is
  // left out, 0: the 3 sigma test alone, which these estimates of 0.56 % would otherwise pass.)
  ScaleFactorSelection sel(kNominalK, 0.0);
  IdentifiedScaleFactor k = identified(14.2, 0.0122496, false, "id-a");
  k.sigma_m_per_pulse = 7.23e-5;
  k.samples_accepted = 8;
  ASSERT_TRUE(sel.on_identified(k, 0.0));
  EXPECT_EQ(sel.in_force_source(), "id-a");
  k.t_s = 15.2;
  k.k_m_per_pulse = 0.0123171;
  k.sigma_m_per_pulse = 7.02e-5;
  k.samples_accepted = 9;
  const auto next = sel.on_identified(k, 0.0);
  ASSERT_TRUE(next);
  EXPECT_EQ(next->k_m_per_pulse, 0.0123171);
  // Another instance's estimate is judged against the nominal until one of its own is in force.
  IdentifiedScaleFactor other = k;
  other.t_s = 16.2;
  other.source = "id-b";
  EXPECT_FALSE(sel.on_identified(other, 0.0));
  // A checkpoint keeps which source is in force: a restored selection takes the next estimate too.
  ScaleFactorSelection restored(kNominalK, 0.0);
  restored.restore_state(sel.state());
  EXPECT_EQ(restored.in_force_source(), "id-a");
  k.t_s = 17.2;
  k.k_m_per_pulse = 0.0123619;
  EXPECT_TRUE(restored.on_identified(k, 0.0));
  // A commanded K ends it: after the release the identified K must beat the nominal again.
  ASSERT_TRUE(restored.set_commanded_k(0.0127, 17.5).accepted);
  restored.release_commanded_k();
  EXPECT_EQ(restored.in_force_source(), "");
  k.t_s = 18.2;
  EXPECT_FALSE(restored.on_identified(k, 0.0));
}

// ---- consumer_rules.hpp: commanded_k_problem ----

TEST(CommandedKProblem, AcceptsTheTenthToTenTimesTheNominalBoundsIncluded) {
  EXPECT_FALSE(commanded_k_problem(0.0126, kNominalK));
  EXPECT_FALSE(commanded_k_problem(0.125, kNominalK));    // exactly 10x
  EXPECT_FALSE(commanded_k_problem(0.00125, kNominalK));  // exactly 0.1x (0.1 has no exact binary form)
  EXPECT_FALSE(commanded_k_problem(0.25, 0.025));         // the range follows the nominal given
}

TEST(CommandedKProblem, NamesTheValueAndTheRange) {
  const auto too_big = commanded_k_problem(0.126, kNominalK);
  ASSERT_TRUE(too_big);
  EXPECT_EQ(*too_big, "K = 0.126 m/pulse is outside [0.1, 10] x nominal K (0.0125 m/pulse)");
  const auto too_small = commanded_k_problem(0.00124, kNominalK);
  ASSERT_TRUE(too_small);
  EXPECT_EQ(*too_small, "K = 0.00124 m/pulse is outside [0.1, 10] x nominal K (0.0125 m/pulse)");
  // 1 m/pulse was accepted by dead reckoning's former (0, 10] range: a unit slip, now refused.
  EXPECT_TRUE(commanded_k_problem(1.0, kNominalK));
  for (double bad : {0.0, -0.0125, std::nan(""), kInf}) {
    const auto why = commanded_k_problem(bad, kNominalK);
    ASSERT_TRUE(why) << bad;
    EXPECT_NE(why->find("m/pulse is not finite and > 0"), std::string::npos) << *why;
  }
  EXPECT_EQ(*commanded_k_problem(-0.0125, kNominalK), "K = -0.0125 m/pulse is not finite and > 0");
  // A bad nominal is named, whatever K is.
  EXPECT_EQ(*commanded_k_problem(0.0125, 0.0), "nominal K = 0 m/pulse is not finite and > 0");
}

// ---- the commanded-K latch ----

TEST(DeadReckoningScaleFactorSelection, SetLatchesTheKAndReleaseFollowsTheIdentifiedKAgain) {
  ScaleFactorSelection s(kNominalK);
  EXPECT_FALSE(s.commanded());
  const auto set = s.set_commanded_k(0.0127, 12.5);
  EXPECT_TRUE(set.accepted);
  EXPECT_EQ(set.detail, "K = 0.0127 m/pulse commanded (identified K ignored until release_k)");
  ASSERT_TRUE(set.update);
  EXPECT_EQ(set.update->k_m_per_pulse, 0.0127);
  EXPECT_EQ(set.update->source, ScaleFactorSource::kCommanded);
  EXPECT_EQ(set.update->t_s, std::nextafter(12.5, kInf));  // right after what was processed
  EXPECT_TRUE(s.commanded());
  EXPECT_EQ(s.last_k_stamp_s(), set.update->t_s);

  // Identified K is ignored while commanded, and counted.
  EXPECT_FALSE(s.on_identified(identified(13.0, 0.0126), 100.0));
  EXPECT_FALSE(s.on_identified(identified(13.1, 0.0126), 100.1));
  EXPECT_EQ(s.counters().k_ignored, 2u);
  EXPECT_EQ(s.counters().k_applied, 0u);

  const auto release = s.release_commanded_k();
  EXPECT_TRUE(release.accepted);
  EXPECT_EQ(release.detail, "following the identified K again (from its next estimate)");
  EXPECT_FALSE(release.update);
  EXPECT_FALSE(s.commanded());

  // The next applicable identified K is used, with its own stamp.
  const auto next = s.on_identified(identified(13.2, 0.01262), 100.2);
  ASSERT_TRUE(next);
  EXPECT_EQ(next->t_s, 13.2);
  EXPECT_EQ(next->k_m_per_pulse, 0.01262);
  EXPECT_EQ(next->source, ScaleFactorSource::kIdentified);
  EXPECT_EQ(s.counters().k_applied, 1u);
  EXPECT_EQ(s.counters().k_ignored, 2u);
}

TEST(DeadReckoningScaleFactorSelection, OutOfRangeSetKIsRejectedWithTheMessageAndChangesNothing) {
  ScaleFactorSelection s(kNominalK);
  ASSERT_TRUE(s.on_identified(identified(5.0, 0.0126), 1.0));
  for (double k : {0.126, 1.0, 10.0, 0.0, -0.0127, std::nan("")}) {
    const auto r = s.set_commanded_k(k, 6.0);
    EXPECT_FALSE(r.accepted) << k;
    EXPECT_FALSE(r.update) << k;
    EXPECT_EQ(r.detail.rfind("set_k: K = ", 0), 0u) << r.detail;
  }
  EXPECT_EQ(s.set_commanded_k(0.126, 6.0).detail,
            "set_k: K = 0.126 m/pulse is outside [0.1, 10] x nominal K (0.0125 m/pulse)");
  EXPECT_EQ(s.set_commanded_k(0.0, 6.0).detail, "set_k: K = 0 m/pulse is not finite and > 0");
  EXPECT_FALSE(s.commanded());
  EXPECT_EQ(s.last_k_stamp_s(), 5.0);
  // The range is the DR's own nominal K: 0.2 m/pulse is fine for a 0.025 m/pulse odometer.
  ScaleFactorSelection coarse_wheel(0.025);
  EXPECT_TRUE(coarse_wheel.set_commanded_k(0.2, 6.0).accepted);
  EXPECT_FALSE(coarse_wheel.set_commanded_k(0.26, 6.0).accepted);
}

TEST(DeadReckoningScaleFactorSelection, StampsHandedOutAreStrictlyIncreasing) {
  ScaleFactorSelection s(kNominalK);
  // Before anything was processed (-inf) and without any K: the lowest finite time.
  const auto first = s.set_commanded_k(0.0125, -kInf);
  ASSERT_TRUE(first.update);
  EXPECT_TRUE(std::isfinite(first.update->t_s));
  EXPECT_EQ(first.update->t_s, std::nextafter(-std::numeric_limits<double>::max(), kInf));
  s.release_commanded_k();

  ASSERT_TRUE(s.on_identified(identified(20.0, 0.0126), 1.0));
  // Processed only up to 10 s (the K arrived ahead of the data): after the last K, not after 10 s.
  const auto a = s.set_commanded_k(0.0130, 10.0);
  ASSERT_TRUE(a.update);
  EXPECT_EQ(a.update->t_s, std::nextafter(20.0, kInf));
  // A second command at once: after the first.
  const auto b = s.set_commanded_k(0.0131, 10.0);
  ASSERT_TRUE(b.update);
  EXPECT_GT(b.update->t_s, a.update->t_s);
  EXPECT_EQ(b.update->t_s, std::nextafter(a.update->t_s, kInf));
  // Processed further than every K: after what was processed.
  const auto c = s.set_commanded_k(0.0132, 30.0);
  EXPECT_EQ(c.update->t_s, std::nextafter(30.0, kInf));

  // Released: an identified K stamped at or before the last K is not newer: ignored, counted.
  s.release_commanded_k();
  EXPECT_FALSE(s.on_identified(identified(30.0, 0.0126), 2.0));
  EXPECT_EQ(s.counters().k_ignored, 1u);
  const auto later = s.on_identified(identified(30.1, 0.0126), 2.1);
  ASSERT_TRUE(later);
  EXPECT_EQ(later->t_s, 30.1);
  EXPECT_EQ(s.counters().k_applied, 2u);
}

TEST(DeadReckoningScaleFactorSelection, InapplicableIdentifiedKIsNeitherAppliedNorCountedAsIgnored) {
  ScaleFactorSelection s(kNominalK);
  EXPECT_FALSE(s.on_identified(identified(1.0, 0.0126, /*converged=*/false), 1.0));
  EXPECT_FALSE(s.on_identified(identified(1.1, 0.0, true), 1.1));  // K = 0: no value yet
  EXPECT_FALSE(s.on_identified(identified(1.2, std::nan(""), true), 1.2));
  EXPECT_FALSE(s.on_identified(identified(1.3, -0.0126, true), 1.3));
  EXPECT_EQ(s.counters().k_applied, 0u);
  EXPECT_EQ(s.counters().k_ignored, 0u);
  EXPECT_FALSE(s.last_k_stamp_s());
}

TEST(DeadReckoningScaleFactorSelection, SourceChangeIsCountedNotedAndTheNoteExpires) {
  ScaleFactorSelection s(kNominalK);
  s.on_identified(identified(10.0, 0.0126, true, "identification"), 100.0);
  EXPECT_EQ(s.k_source(), "identification");
  EXPECT_EQ(s.counters().k_source_changes, 0u);  // the first source is not a change
  EXPECT_EQ(s.k_source_note(), "");
  s.on_identified(identified(10.1, 0.0126, true, "identification"), 100.1);
  EXPECT_EQ(s.counters().k_source_changes, 0u);
  // The standby takes over; its estimate is not converged, the change is noted all the same.
  s.on_identified(identified(42.5, 0.0, false, "identification/standby"), 200.0);
  EXPECT_EQ(s.counters().k_source_changes, 1u);
  EXPECT_EQ(s.k_source(), "identification/standby");
  EXPECT_EQ(s.k_source_note(), "K source changed from 'identification' to 'identification/standby' at t=42.5 s");
  EXPECT_EQ(s.k_source_changed_at_s(), 200.0);

  DeadReckoningHealthFacts f = odonav::test::running_dr_facts(2, 5);
  f.k_source_note = s.k_source_note();
  f.k_source_changed_at_s = s.k_source_changed_at_s();
  f.now_s = 229.9;  // within kDeadReckoningNoticeDuration_s (30 s)
  EXPECT_EQ(dead_reckoning_health(f).reason, s.k_source_note());
  EXPECT_EQ(dead_reckoning_health(f).level, ComponentHealth::Level::kOk);  // told, not warned
  f.now_s = 230.0;
  EXPECT_EQ(dead_reckoning_health(f).reason, "");

  // The primary comes back: a second change.
  s.on_identified(identified(60.0, 0.0126, true, "identification"), 300.0);
  EXPECT_EQ(s.counters().k_source_changes, 2u);
  EXPECT_EQ(s.k_source_note(), "K source changed from 'identification/standby' to 'identification' at t=60 s");
}

// ---- health ----

namespace {
DeadReckoningHealthFacts running_facts() {
  DeadReckoningHealthFacts f = odonav::test::running_dr_facts(3, 4);
  f.now_s = 1000.0;
  return f;
}
}  // namespace

TEST(DeadReckoningHealthDecision, AllWellIsRunningOkWithoutReason) {
  const ComponentHealth h = dead_reckoning_health(running_facts());
  EXPECT_EQ(h.state, ComponentHealth::State::kRunning);
  EXPECT_EQ(h.level, ComponentHealth::Level::kOk);
  EXPECT_EQ(h.reason, "");
}

TEST(DeadReckoningHealthDecision, EachKCaseHasItsReason) {
  DeadReckoningHealthFacts f = running_facts();
  f.started = false;
  f.scale_factor_heard = false;
  f.k_applied = 0;
  ComponentHealth h = dead_reckoning_health(f);
  EXPECT_EQ(h.state, ComponentHealth::State::kStarting);
  EXPECT_EQ(h.level, ComponentHealth::Level::kOk);
  EXPECT_EQ(h.reason, "waiting for a valid GNSS fix to start from; waiting for identification");

  f = running_facts();
  f.k_commanded = true;
  f.scale_factor_absent = true;  // commanded wins: the absence does not matter
  h = dead_reckoning_health(f);
  EXPECT_EQ(h.state, ComponentHealth::State::kRunning);
  EXPECT_EQ(h.level, ComponentHealth::Level::kOk);
  EXPECT_EQ(h.reason, "using commanded K");

  f = running_facts();
  f.scale_factor_absent = true;
  f.k_applied = 0;
  h = dead_reckoning_health(f);
  EXPECT_EQ(h.state, ComponentHealth::State::kDegraded);
  EXPECT_EQ(h.level, ComponentHealth::Level::kWarn);
  EXPECT_EQ(h.reason, "using nominal K: no identification");

  f.k_applied = 7;  // heard before: the DR keeps the last identified K
  h = dead_reckoning_health(f);
  EXPECT_EQ(h.state, ComponentHealth::State::kDegraded);
  EXPECT_EQ(h.reason, "no identification: keeping the last identified K");

  f.started = false;  // absent before the start: still starting, but warned
  h = dead_reckoning_health(f);
  EXPECT_EQ(h.state, ComponentHealth::State::kStarting);
  EXPECT_EQ(h.level, ComponentHealth::Level::kWarn);
  EXPECT_EQ(h.reason, "waiting for a valid GNSS fix to start from; no identification: keeping the last identified K");

  f = running_facts();
  f.k_applied = 0;  // heard, nothing applicable yet
  h = dead_reckoning_health(f);
  EXPECT_EQ(h.level, ComponentHealth::Level::kOk);
  EXPECT_EQ(h.reason, "K not converged yet: using nominal K");
}

TEST(DeadReckoningHealthDecision, PulseJumpsWarnForThirtySecondsAfterTheTotalChanged) {
  CountChangeTime jumps;
  EXPECT_EQ(jumps.changed_at_s(), -kInf);
  jumps.observe(0, 50.0);  // no change from 0
  EXPECT_EQ(jumps.changed_at_s(), -kInf);
  jumps.observe(2, 100.0);
  EXPECT_EQ(jumps.changed_at_s(), 100.0);
  jumps.observe(2, 110.0);  // same total: the window does not move
  EXPECT_EQ(jumps.changed_at_s(), 100.0);

  DeadReckoningHealthFacts f = running_facts();
  f.pulse_jumps_rejected = 2;
  f.pulse_jumps_changed_at_s = jumps.changed_at_s();
  f.now_s = 129.9;
  ComponentHealth h = dead_reckoning_health(f);
  EXPECT_EQ(h.state, ComponentHealth::State::kRunning);
  EXPECT_EQ(h.level, ComponentHealth::Level::kWarn);
  EXPECT_EQ(h.reason, "rejected 2 odometer samples: pulse jump (counter glitch)");
  f.now_s = 130.0;
  h = dead_reckoning_health(f);
  EXPECT_EQ(h.level, ComponentHealth::Level::kOk);
  EXPECT_EQ(h.reason, "");

  jumps.observe(3, 140.0);  // a new jump opens the window again, with the new total
  f.pulse_jumps_rejected = 3;
  f.pulse_jumps_changed_at_s = jumps.changed_at_s();
  f.now_s = 150.0;
  EXPECT_EQ(dead_reckoning_health(f).reason, "rejected 3 odometer samples: pulse jump (counter glitch)");
}

TEST(DeadReckoningHealthDecision, MisalignmentReasonsAndTheirOrderAfterK) {
  DeadReckoningHealthFacts f = running_facts();
  f.misalignment_absent = true;
  EXPECT_EQ(dead_reckoning_health(f).reason, "using zero misalignment: no calibration");
  EXPECT_EQ(dead_reckoning_health(f).level, ComponentHealth::Level::kOk);
  // Absent after some were applied: the last one is held, and the text says so (not "zero").
  f.misalignments_applied = 12;
  f.held_misalignment_t_s = 40.0;
  f.misalignment_silent_s = 5.2;
  EXPECT_EQ(dead_reckoning_health(f).reason, "holding misalignment of t=40.0 s (calibration silent 5 s)");
  f.misalignments_applied = 0;
  f.held_misalignment_t_s.reset();
  f.misalignment_absent = false;
  f.misalignments_applied = 0;
  EXPECT_EQ(dead_reckoning_health(f).reason, "misalignment not converged yet: using zero");
  f.misalignment_heard = false;  // neither heard nor absent: nothing to say yet
  EXPECT_EQ(dead_reckoning_health(f).reason, "");

  // Everything at once, in README order: K, source note, pulse jumps, misalignment.
  f = running_facts();
  f.k_commanded = true;
  f.k_source_note = "K source changed from 'a' to 'b' at t=3 s";
  f.k_source_changed_at_s = 990.0;
  f.pulse_jumps_rejected = 1;
  f.pulse_jumps_changed_at_s = 995.0;
  f.misalignment_absent = true;
  const ComponentHealth h = dead_reckoning_health(f);
  EXPECT_EQ(h.level, ComponentHealth::Level::kWarn);
  EXPECT_EQ(h.reason,
            "using commanded K; K source changed from 'a' to 'b' at t=3 s; rejected 1 odometer samples: pulse jump "
            "(counter glitch); using zero misalignment: no calibration");
}

// ---- the one DeadReckonerParams function ----

TEST(DeadReckoningParams, NominalKIsTheOptionElseTheDatasetsElseTheDefault) {
  DeadReckoningFacts f;
  DeadReckonerParams p = dead_reckoner_params(f);
  EXPECT_EQ(p.nominal_k_m_per_pulse, 0.0125);
  EXPECT_EQ(p.nominal_k_m_per_pulse, kDefaultNominalK_m_per_pulse);
  EXPECT_TRUE(p.use_ins);
  EXPECT_FALSE(p.lever_arm_body_m);
  EXPECT_EQ(p.mode, DeadReckoningMode::k3D);

  f.dataset_nominal_k_m_per_pulse = 0.0122;
  EXPECT_EQ(dead_reckoner_params(f).nominal_k_m_per_pulse, 0.0122);
  f.nominal_k_option_m_per_pulse = 0.0131;
  EXPECT_EQ(dead_reckoner_params(f).nominal_k_m_per_pulse, 0.0131);
  // Its sigma likewise: the option, else the dataset's, else 3 %.
  EXPECT_EQ(p.nominal_k_rel_sigma, kDefaultNominalKRelSigma);
  EXPECT_EQ(kDefaultNominalKRelSigma, 0.03);
  f.dataset_nominal_k_sigma_percent = 1.0;
  EXPECT_EQ(dead_reckoner_params(f).nominal_k_rel_sigma, 0.01);
  f.nominal_k_sigma_option_percent = 5.0;
  EXPECT_EQ(dead_reckoner_params(f).nominal_k_rel_sigma, 0.05);

  f.use_ins = false;
  f.mode = DeadReckoningMode::k2D;
  f.lever_arm_body_m = Eigen::Vector3d(0.5, -0.25, 1.5);
  p = dead_reckoner_params(f);
  EXPECT_FALSE(p.use_ins);
  EXPECT_EQ(p.mode, DeadReckoningMode::k2D);
  ASSERT_TRUE(p.lever_arm_body_m);
  EXPECT_EQ(*p.lever_arm_body_m, Eigen::Vector3d(0.5, -0.25, 1.5));
  // The rest stays DeadReckonerParams' defaults.
  EXPECT_EQ(p.max_speed_mps, 100.0);
  EXPECT_EQ(p.max_bracket_s, 1.0);
}

TEST(DeadReckoningParams, FactsFromOptions) {
  Options o("odonav-test", "dead-reckoning facts");
  add_dead_reckoning_options(o);
  add_lever_arm_option(o);
  std::ostringstream help;
  ASSERT_EQ(o.parse({"--nominal-k", "0.0131", "--dr-mode", "2d", "--lever-arm", "0.5,0,1.5",
                     "--nominal-k-sigma-percent", "3"},
                    help),
            ParseResult::kRun);
  const DeadReckoningFacts f = dead_reckoning_facts_from(o);
  EXPECT_EQ(f.nominal_k_option_m_per_pulse, 0.0131);
  EXPECT_EQ(f.nominal_k_sigma_option_percent, 3.0);
  EXPECT_EQ(dead_reckoner_params(f).nominal_k_rel_sigma, 0.03);
  EXPECT_EQ(f.mode, DeadReckoningMode::k2D);
  ASSERT_TRUE(f.lever_arm_body_m);
  EXPECT_EQ(*f.lever_arm_body_m, Eigen::Vector3d(0.5, 0.0, 1.5));
  EXPECT_TRUE(f.use_ins);
  EXPECT_FALSE(f.dataset_nominal_k_m_per_pulse);

  Options none("odonav-test", "defaults");
  add_dead_reckoning_options(none);
  add_lever_arm_option(none);
  ASSERT_EQ(none.parse(std::vector<std::string>{}, help), ParseResult::kRun);
  const DeadReckoningFacts d = dead_reckoning_facts_from(none);
  EXPECT_EQ(d.nominal_k_option_m_per_pulse, 0.0);  // not given
  EXPECT_EQ(dead_reckoner_params(d).nominal_k_m_per_pulse, 0.0125);
  EXPECT_FALSE(d.lever_arm_body_m);
}

TEST(NominalKOption, OneFlagOneResolutionForEveryProgram) {
  // The flag given wins, then the dataset's meta.json, then the product default.
  EXPECT_EQ(resolve_nominal_k(0.0131, 0.0127), 0.0131);
  EXPECT_EQ(resolve_nominal_k(0.0, 0.0127), 0.0127);
  EXPECT_EQ(resolve_nominal_k(0.0), kDefaultNominalK_m_per_pulse);
  // Declared once in a tool holding both identification and dead-reckoning options; its range
  // takes 0 (not given) and refuses a negative K, naming the flag.
  Options o("odonav-test", "nominal K");
  add_nominal_k_option(o);
  add_dead_reckoning_options(o);
  add_lever_arm_option(o);
  std::ostringstream help;
  ASSERT_EQ(o.parse({"--nominal-k", "0.02"}, help), ParseResult::kRun);
  EXPECT_EQ(nominal_k_option_from(o), 0.02);
  EXPECT_EQ(dead_reckoner_params(dead_reckoning_facts_from(o)).nominal_k_m_per_pulse, 0.02);
  Options bad("odonav-test", "nominal K");
  add_nominal_k_option(bad);
  try {
    bad.parse({"--nominal-k", "-0.01"}, help);
    FAIL() << "a negative nominal K was accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("--nominal-k"), std::string::npos) << e.what();
  }
}

TEST(DeadReckoningParams, ThePulseJumpGateUsesTheNominalKOfTheFunction) {
  // Gate: max increment = max_speed / K x dt + 2 pulses. At dt = 0.01 s and 100 m/s: 82 pulses at
  // 0.0125 m/pulse, 42 at 0.025 m/pulse. 60 pulses in 0.01 s pass the first, not the second.
  for (double nominal : {0.0125, 0.025}) {
    DeadReckoningFacts f;
    f.dataset_nominal_k_m_per_pulse = nominal;
    DeadReckoner dr(dead_reckoner_params(f));
    EXPECT_EQ(dr.add_odometer(OdometerSample{0.0, 1000, 1}), OdometerAddResult::kAccepted);
    const OdometerAddResult r = dr.add_odometer(OdometerSample{0.01, 1060, 1});
    EXPECT_EQ(r, nominal == 0.0125 ? OdometerAddResult::kAccepted : OdometerAddResult::kJumpRejected) << nominal;
  }
}

TEST(DeadReckoningHealthDecision, WithinAKilometreOfAPoleItWarnsWithTheDistance) {
  DeadReckoningHealthFacts f = running_facts();
  f.pole_distance_m = 311.2;
  f.pole_north = false;
  const ComponentHealth h = dead_reckoning_health(f);
  EXPECT_EQ(h.state, ComponentHealth::State::kRunning);
  EXPECT_EQ(h.level, ComponentHealth::Level::kWarn);
  EXPECT_EQ(h.reason,
            "within 312 m of the South Pole: true north turns by 1/312 rad per metre across the meridian there, so "
            "each metre of position error is that much heading error (the heading is ill-defined inside 1000 m)");
  // Where the DR core says so: from 1000 m of the pole inwards, never at mid-latitudes.
  EXPECT_FALSE(polar_heading_distance_m(Geodetic{deg_to_rad(52.5), 0.0, 0.0}));
  EXPECT_FALSE(polar_heading_distance_m(Geodetic{0.5 * kPi - 1001.0 / 6399593.6, 0.0, 0.0}));
  EXPECT_NEAR(*polar_heading_distance_m(Geodetic{-0.5 * kPi + 999.0 / 6399593.6, 2.0, 0.0}), 999.0, 0.01);
}
