// The one checkpoint serialisation (checkpoint_state.hpp, checkpoint_file.hpp) across the three
// checkpointing components: each component's checkpoint, saved, restored into a fresh component and
// saved again, is the same file byte for byte; and the doubles JSON cannot hold (NaN, infinities)
// and those a careless writer loses (-0.0, subnormals, 17 significant digits) come back bit-exact.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <optional>
#include <vector>

#include "odonav/calibration/calibration_checkpoint.hpp"
#include "odonav/checkpoint_file.hpp"
#include "odonav/checkpoint_state.hpp"
#include "odonav/dead_reckoning/dead_reckoning_checkpoint.hpp"
#include "odonav/identification/checkpoint.hpp"
#include "scratch_dir.hpp"
#include "synthetic_drive.hpp"

namespace odonav {

/// Every kind of value a state holds, for the special doubles.
struct SpecialValues {
  std::vector<double> list;
  std::optional<double> maybe;
  std::optional<double> none;
  Eigen::Vector3d vector = Eigen::Vector3d::Zero();
  std::pair<double, double> pair;
  double single = 0.0;
};

ODONAV_STATE_FIELDS(SpecialValues) {
  a("list", s.list)("maybe", s.maybe)("none", s.none)("vector", s.vector)("pair", s.pair)("single", s.single);
}

namespace {

namespace fs = std::filesystem;
using test::read_text;
constexpr const char* kVehicle = "vehicle-07";
constexpr const char* kHash = "0123456789abcdef";
constexpr int64_t kUnixTime_s = 1700000000;

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

/// 60 s of a changing speed with a 0.05 s GNSS latency, a misalignment and noise.
synthetic::SyntheticData drive(double duration_s) {
  synthetic::SensorConfig c;
  c.duration_s = duration_s;
  c.velocity_noise_mps = 0.02;
  c.gnss_latency_s = 0.05;
  c.misalignment = Misalignment{deg_to_rad(0.6), deg_to_rad(-0.4)};
  return synthetic::simulate(synthetic::wavy_drive(), c);
}

class CheckpointRoundTrip : public ::testing::Test {
 protected:
  test::ScratchDir scratch_;
  fs::path dir_ = scratch_.path();
};

TEST_F(CheckpointRoundTrip, EveryComponentsCheckpointSavedRestoredAndSavedAgainIsTheSameBytes) {
  const synthetic::SyntheticData d = drive(60.0);
  const double cut_s = 37.3;  // mid-drive: buffers ahead of the last epoch, chains open

  {
    SCOPED_TRACE("identification");
    identification::IdentificationParams p;
    p.run_all_estimators = true;  // every estimator's state in it
    identification::IdentificationCore core(p);
    for (const auto& x : d.odometer) core.add_odometer(x);
    for (const auto& x : d.ins) core.add_ins(x);
    for (const auto& x : d.gnss)
      if (x.t_s < 45.0) core.add_gnss(x);
    core.process_until(cut_s);
    identification::IdentificationCheckpoint c;
    c.vehicle_id = kVehicle;
    c.config_hash = kHash;
    c.estimator_name = core.main_estimator_name();
    c.last_sample_t_s = cut_s;
    c.samples_accepted = 300;
    c.fed_until_s = {60.0, 44.9, 60.0, std::nullopt};
    c.held_misalignment_t_s = 30.0;
    c.core_state = core.save_state();
    ASSERT_EQ(c.core_state.at("side_by_side").size(), core.estimator_names().size());
    const std::string text = identification::serialize_checkpoint(c);
    const std::string path = identification::checkpoint_path(dir_.string(), kVehicle);
    write_file_atomically(path, text);
    identification::IdentificationCore restored(p);
    const identification::CheckpointLoadResult r =
        identification::load_identification_checkpoint(path, kVehicle, kHash, restored, kUnixTime_s);
    ASSERT_EQ(r.status, CheckpointLoadStatus::kRestored) << r.reason;
    identification::IdentificationCheckpoint again = *r.checkpoint;
    again.core_state = restored.save_state();
    EXPECT_EQ(identification::serialize_checkpoint(again), text);
    EXPECT_EQ(read_text(path), text);
  }
  {
    SCOPED_TRACE("calibration");
    calibration::MisalignmentCalibrator calibrator;
    for (const auto& x : d.ins) calibrator.add_ins(x);
    for (const auto& x : d.gnss) calibrator.add_gnss(x);
    calibrator.process_until(cut_s);
    ASSERT_GT(calibrator.current().samples_used, 100u);
    const std::string text = calibration::serialize_calibration_checkpoint(
        calibration::CalibrationCheckpoint{kVehicle, kHash, cut_s, calibrator.save_state()});
    const std::string path = calibration::calibration_checkpoint_path(dir_.string(), kVehicle);
    write_file_atomically(path, text);
    calibration::MisalignmentCalibrator restored;
    const calibration::CalibrationCheckpointLoad r =
        calibration::load_calibration_checkpoint(path, kVehicle, kHash, restored, kUnixTime_s);
    ASSERT_EQ(r.status, CheckpointLoadStatus::kRestored) << r.reason;
    EXPECT_EQ(calibration::serialize_calibration_checkpoint(
                  calibration::CalibrationCheckpoint{kVehicle, kHash, *r.restored_t_s, restored.save_state()}),
              text);
  }
  {
    SCOPED_TRACE("dead reckoning");
    dead_reckoning::DeadReckonerParams p;
    p.nominal_k_m_per_pulse = 0.0126;
    dead_reckoning::DeadReckoner core(p);
    dead_reckoning::AnchoredPositionFilter anchor;
    dead_reckoning::DeadReckoningConsumerState consumer(p.nominal_k_m_per_pulse);
    core.add_scale_factor(10.0, 0.0125, dead_reckoning::ScaleFactorSource::kIdentified);
    core.add_misalignment(12.0, Misalignment{0.01, -0.007});
    consumer.applied_misalignment.add(12.0, Misalignment{0.01, -0.007});
    consumer.misalignments_applied = 1;
    consumer.held_misalignment_t_s = 12.0;
    for (const auto& x : d.odometer) core.add_odometer(x);
    for (const auto& x : d.ins)
      if (x.t_s < 50.0) core.add_ins(x);
    for (const auto& x : d.gnss) core.add_gnss(x);
    for (const dead_reckoning::DeadReckoningOutput& o : core.process_until(cut_s)) anchor.step(o);
    ASSERT_TRUE(core.started());
    dead_reckoning::DeadReckoningCheckpoint c;
    c.vehicle_id = kVehicle;
    c.config_hash = kHash;
    c.last_output_t_s = cut_s;
    c.fed_until_s = {60.0, 60.0, 49.99, 12.0, std::nullopt};
    dead_reckoning::save_state_into(c, dead_reckoning::DeadReckoningStateRefs{core, anchor, consumer});
    ASSERT_FALSE(c.dead_reckoner_state.at("gnss").empty()) << "inputs buffered ahead are in it";
    const std::string text = dead_reckoning::serialize_dead_reckoning_checkpoint(c);
    const std::string path = dead_reckoning::dead_reckoning_checkpoint_path(dir_.string(), kVehicle);
    write_file_atomically(path, text);
    dead_reckoning::DeadReckoner core2(p);
    dead_reckoning::AnchoredPositionFilter anchor2;
    dead_reckoning::DeadReckoningConsumerState consumer2(p.nominal_k_m_per_pulse);
    const dead_reckoning::DeadReckoningCheckpointLoad r = dead_reckoning::load_dead_reckoning_checkpoint(
        path, kVehicle, kHash, dead_reckoning::DeadReckoningStateRefs{core2, anchor2, consumer2}, kUnixTime_s);
    ASSERT_EQ(r.status, CheckpointLoadStatus::kRestored) << r.reason;
    dead_reckoning::DeadReckoningCheckpoint again = *r.checkpoint;
    dead_reckoning::save_state_into(again, dead_reckoning::DeadReckoningStateRefs{core2, anchor2, consumer2});
    EXPECT_EQ(dead_reckoning::serialize_dead_reckoning_checkpoint(again), text);
  }
}

TEST(CheckpointStateValues, NonFiniteSubnormalAndNegativeZeroRoundTripBitExactly) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  SpecialValues v;
  v.list = {nan,
            -nan,
            inf,
            -inf,
            -0.0,
            0.0,
            std::numeric_limits<double>::denorm_min(),
            -std::numeric_limits<double>::denorm_min(),
            std::numeric_limits<double>::min() / 3.0,  // subnormal
            std::numeric_limits<double>::max(),
            std::numeric_limits<double>::lowest(),
            0.1,
            1700000123.456789012345,  // a Unix-epoch stamp: needs all 17 digits
            1.0 / 3.0};
  v.maybe = nan;
  v.vector = Eigen::Vector3d(-inf, -0.0, 5e-324);
  v.pair = {inf, -0.0};
  v.single = -nan;

  const std::string text = to_state(v).dump();
  // JSON has no NaN or infinity: they are named, never null (which is an empty optional).
  EXPECT_NE(text.find("\"nan\""), std::string::npos) << text;
  EXPECT_NE(text.find("\"-nan\""), std::string::npos) << text;
  EXPECT_NE(text.find("\"-inf\""), std::string::npos) << text;
  EXPECT_NE(text.find("-0.0"), std::string::npos) << text;
  EXPECT_NE(text.find("5e-324"), std::string::npos) << text;
  EXPECT_NE(text.find("\"none\":null"), std::string::npos) << text;
  EXPECT_EQ(text.find("\"maybe\":null"), std::string::npos) << "a NaN is not an empty optional: " << text;

  SpecialValues back;
  const StateJson parsed = StateJson::parse(text);
  StateIn in(parsed, "");
  state_fields(in, back);
  ASSERT_EQ(back.list.size(), v.list.size());
  for (std::size_t i = 0; i < v.list.size(); ++i)
    if (std::isnan(v.list[i]))
      EXPECT_TRUE(std::isnan(back.list[i]) && std::signbit(back.list[i]) == std::signbit(v.list[i])) << i;
    else
      EXPECT_TRUE(same_bits(back.list[i], v.list[i])) << i << ": " << back.list[i] << " vs " << v.list[i];
  ASSERT_TRUE(back.maybe.has_value());
  EXPECT_TRUE(std::isnan(*back.maybe));
  EXPECT_FALSE(back.none.has_value());
  for (int i = 0; i < 3; ++i) EXPECT_TRUE(same_bits(back.vector[i], v.vector[i])) << i;
  EXPECT_TRUE(same_bits(back.pair.first, inf));
  EXPECT_TRUE(same_bits(back.pair.second, -0.0));
  EXPECT_TRUE(std::isnan(back.single) && std::signbit(back.single));
  EXPECT_EQ(to_state(back).dump(), text) << "saved again: the same bytes";

  // Through a whole checkpoint file: the checksum survives the special values.
  const std::string file = seal_checkpoint(CheckpointIdentity{"test", 1, kVehicle, kHash}, to_state(v));
  const CheckpointContents contents = unseal_checkpoint(file);
  EXPECT_EQ(contents.payload.dump(), text);
  EXPECT_EQ(seal_checkpoint(contents.identity, contents.payload), file);

  // A fresh sample builder holds -inf (its watermark) and NaN (no GNSS period yet): its state in a
  // checkpoint comes back to the same bytes.
  const identification::IdentificationCore fresh{identification::IdentificationParams{}};
  const StateJson state = fresh.save_state();
  EXPECT_EQ(state.at("sample_builder").at("watermark_s"), "-inf");
  EXPECT_EQ(state.at("sample_builder").at("gnss_period_s"), "nan");
  identification::IdentificationCore restored{identification::IdentificationParams{}};
  restored.restore_state(StateJson::parse(state.dump()));
  EXPECT_EQ(restored.save_state().dump(), state.dump());
}

TEST(CheckpointStateValues, AFieldOfTheWrongKindIsNamedByItsPath) {
  SpecialValues v;
  StateJson j = to_state(v);
  j["vector"][1] = "north";
  SpecialValues back;
  StateIn in(j, "test");
  try {
    state_fields(in, back);
    FAIL() << "accepted";
  } catch (const CheckpointError& e) {
    EXPECT_EQ(std::string(e.what()), "field 'test.vector[1]' is not a number");
  }
  uint32_t small = 0;
  EXPECT_THROW(from_state(StateJson(uint64_t{1} << 40), small, "small"), CheckpointError);
  int negative_ok = 0;
  from_state(StateJson(-5), negative_ok, "i");
  EXPECT_EQ(negative_ok, -5);
  uint64_t big = 0;
  from_state(StateJson::parse("18446744073709551615"), big, "big");
  EXPECT_EQ(big, std::numeric_limits<uint64_t>::max());
  EXPECT_THROW(from_state(StateJson(-1), big, "big"), CheckpointError);
}

}  // namespace

}  // namespace odonav
