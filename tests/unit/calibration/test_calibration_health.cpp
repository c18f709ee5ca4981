// calibration_health: the calibration node's health decision as a pure function.
#include <gtest/gtest.h>

#include "odonav/calibration/calibration_health.hpp"

namespace odonav::calibration {
namespace {

MisalignmentOutput output_in(CalibrationState state, const std::string& reason = "") {
  MisalignmentOutput o;
  o.state = state;
  o.reason = reason;
  return o;
}

TEST(CalibrationHealth, WithoutInsItIsDegradedAndSaysWhy) {
  CalibrationHealthFacts f;
  f.use_ins = false;
  f.current = output_in(CalibrationState::kConverged);
  const ComponentHealth h = calibration_health(f);
  EXPECT_EQ(h.state, ComponentHealth::State::kDegraded);
  EXPECT_EQ(h.level, ComponentHealth::Level::kWarn);
  EXPECT_EQ(h.reason, "no INS: the misalignment cannot be calibrated");
}

TEST(CalibrationHealth, StartingUntilTheFirstEpochThenNamesWhatIsMissing) {
  CalibrationHealthFacts f;
  ComponentHealth h = calibration_health(f);
  EXPECT_EQ(h.state, ComponentHealth::State::kStarting);
  EXPECT_EQ(h.level, ComponentHealth::Level::kOk);
  EXPECT_EQ(h.reason, "waiting for the first GNSS epoch to process");

  f.current = output_in(CalibrationState::kCalibrating, "collecting samples: 60 GNSS epochs used, 100 needed");
  h = calibration_health(f);
  EXPECT_EQ(h.state, ComponentHealth::State::kRunning);
  EXPECT_EQ(h.level, ComponentHealth::Level::kOk);  // converging is normal at the start of a drive
  EXPECT_EQ(h.reason, "not converged yet: collecting samples: 60 GNSS epochs used, 100 needed");

  f.current = output_in(CalibrationState::kFrozen);
  EXPECT_EQ(calibration_health(f).reason, "frozen by command");
  f.current = output_in(CalibrationState::kConverged);
  h = calibration_health(f);
  EXPECT_EQ(h.reason, "");
  EXPECT_EQ(h.level, ComponentHealth::Level::kOk);
}

TEST(CalibrationHealth, RestartNotesComeFirstAndRaiseTheLevelOnlyWhenTheySaySo) {
  CalibrationHealthFacts f;
  f.current = output_in(CalibrationState::kConverged);
  f.now_s = 100.0;
  f.restore_note = "restored from checkpoint t=40.0 s";
  f.restore_note_until_s = 130.0;
  ComponentHealth h = calibration_health(f);
  EXPECT_EQ(h.level, ComponentHealth::Level::kOk);
  EXPECT_NE(h.reason.find("restored from checkpoint t=40.0 s"), std::string::npos) << h.reason;

  f.now_s = 131.0;  // the note has expired
  EXPECT_EQ(calibration_health(f).reason, "");

  f.checkpoint_errors = 2;
  h = calibration_health(f);
  EXPECT_EQ(h.level, ComponentHealth::Level::kWarn);
  EXPECT_NE(h.reason.find("2 checkpoint writes failed"), std::string::npos) << h.reason;
}

}  // namespace
}  // namespace odonav::calibration
