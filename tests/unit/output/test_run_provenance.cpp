// Provenance of a results folder: results are checked against the dataset they claim to come from.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "odonav/run_provenance.hpp"
#include "odonav/safe_output.hpp"

namespace fs = std::filesystem;
using namespace odonav;

namespace {

// A small drive: 10 s of 10 Hz GNSS and 100 Hz odometer, position moving north by `speed_mps`.
Dataset drive(const std::string& vehicle, double speed_mps, double t0_s = 0.0) {
  Dataset d;
  d.meta.vehicle_id = vehicle;
  for (int i = 0; i <= 1000; ++i) {
    OdometerSample o;
    o.t_s = t0_s + 0.01 * i;
    o.pulses = static_cast<uint32_t>(std::lround(speed_mps * 0.01 * i / 0.0125));
    d.odometer.push_back(o);
  }
  for (int i = 0; i <= 100; ++i) {
    GnssSample g;
    g.t_s = t0_s + 0.1 * i;
    g.position = Geodetic{deg_to_rad(52.5) + speed_mps * 0.1 * i / 6.4e6, deg_to_rad(13.4), 80.0};
    g.fix = 1;
    d.gnss.push_back(g);
  }
  return d;
}

}  // namespace

TEST(RunProvenance, FingerprintIsStableAndSeesAnotherDriveWithTheSameVehicleAndSpan) {
  const Dataset a = drive("sim-tracked-01", 10.0), again = drive("sim-tracked-01", 10.0);
  const Dataset b = drive("sim-tracked-01", 9.0);  // same vehicle, same span, another drive
  EXPECT_EQ(dataset_fingerprint(a), dataset_fingerprint(again));
  EXPECT_EQ(dataset_fingerprint(a).size(), 16u);
  EXPECT_NE(dataset_fingerprint(a), dataset_fingerprint(b));
  const RunProvenance p = provenance_of(a, "odonav-offline");
  EXPECT_TRUE(provenance_mismatches(p, 0.0, 10.0, a).empty());
  const auto m = provenance_mismatches(p, 0.0, 10.0, b);
  ASSERT_EQ(m.size(), 1u);
  EXPECT_NE(m[0].find("another recording"), std::string::npos) << m[0];
}

TEST(RunProvenance, AnotherVehicleAndRowsOutsideTheSpanAreNamed) {
  const Dataset a = drive("veh-A", 10.0), b = drive("veh-B", 10.0, 1000.0);
  RunProvenance recorder;  // e.g. an older run that recorded the dataset's vehicle
  recorder.tool = "odonav-offline";
  recorder.vehicle_id = "veh-A";
  EXPECT_TRUE(provenance_mismatches(recorder, 0.0, 10.0, a).empty());
  const auto m = provenance_mismatches(recorder, 0.0, 10.0, b);
  ASSERT_EQ(m.size(), 2u);
  EXPECT_NE(m[0].find("'veh-A'"), std::string::npos) << m[0];
  EXPECT_NE(m[0].find("'veh-B'"), std::string::npos) << m[0];
  EXPECT_NE(m[1].find("outside the dataset's 1000 .. 1010 s"), std::string::npos) << m[1];
  // No provenance at all (an older results folder): the time span is still checked.
  EXPECT_EQ(provenance_mismatches(std::nullopt, 0.0, 10.0, b).size(), 1u);
  EXPECT_TRUE(provenance_mismatches(std::nullopt, 1000.5, 1010.5, b).empty());  // within the 1 s tolerance
  // The pipeline's DDS vehicle id is not the dataset's: never compared.
  RunProvenance pipeline;
  pipeline.tool = "odonav-recorder";
  pipeline.dds_vehicle_id = "vehicle-01";
  EXPECT_TRUE(provenance_mismatches(pipeline, 1000.0, 1010.0, b).empty());
}

TEST(RunProvenance, RoundTripsThroughRunJsonAndABadFileIsNamed) {
  const fs::path dir = fs::temp_directory_path() / ("odonav-provenance-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  EXPECT_FALSE(read_provenance(dir.string()).has_value());
  const RunProvenance p = provenance_of(drive("veh-A", 10.0), "odonav-offline");
  write_file_atomically((dir / kProvenanceFile).string(), provenance_json(p));
  const auto back = read_provenance(dir.string());
  ASSERT_TRUE(back.has_value());
  EXPECT_EQ(back->tool, "odonav-offline");
  EXPECT_EQ(back->vehicle_id, "veh-A");
  EXPECT_EQ(back->dataset_fingerprint, p.dataset_fingerprint);
  EXPECT_DOUBLE_EQ(back->t_first_s, 0.0);
  EXPECT_DOUBLE_EQ(back->t_last_s, 10.0);
  write_file_atomically((dir / kProvenanceFile).string(), "not json");
  try {
    read_provenance(dir.string());
    FAIL() << "accepted a bad run.json";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("run.json"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}
