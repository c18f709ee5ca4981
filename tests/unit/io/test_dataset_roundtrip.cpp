// Dataset writer -> reader: a random dataset (fixed seed, every file, a wrapped counter) reads back
// with every double bit-for-bit equal; optional columns appear only when used.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>

#include "scratch_dir.hpp"
#include "odonav/dataset.hpp"

using namespace odonav;
using odonav::test::ScratchDir;

namespace {

// Bitwise equality that also treats two NaNs as equal (absent truth values are NaN).
bool same(double a, double b) { return (std::isnan(a) && std::isnan(b)) || a == b; }

using odonav::test::read_text;

std::string first_line(const std::string& path) {
  const std::string text = read_text(path);
  return text.substr(0, text.find('\n'));
}

// A random dataset. Angles are produced from degrees through deg_to_rad, as every value read from
// a file is: those are the values the writer must reproduce exactly.
Dataset random_dataset(uint32_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const auto uniform = [&](double lo, double hi) { return lo + (hi - lo) * unit(rng); };
  Dataset d;
  double t = uniform(1.0e5, 6.0e5);      // GNSS time of week, arbitrary fractional digits
  uint32_t pulses = 4294967295u - 700u;  // the counter wraps during the drive
  for (int i = 0; i < 400; ++i) {
    t += uniform(0.001, 0.02);
    pulses += static_cast<uint32_t>(uniform(0.0, 8.0));
    d.odometer.push_back(OdometerSample{t, pulses, static_cast<int>(std::floor(uniform(-1.0, 2.0)))});
  }
  t = d.odometer.front().t_s - 0.05;
  for (int i = 0; i < 120; ++i) {
    t += uniform(0.05, 0.2);
    GnssSample g;
    g.t_s = t;
    g.position = Geodetic{deg_to_rad(uniform(-90.0, 90.0)), deg_to_rad(uniform(-180.0, 180.0)), uniform(-50.0, 4000.0)};
    g.vel_enu_mps = Eigen::Vector3d(uniform(-30, 30), uniform(-30, 30), uniform(-2, 2));
    if (i % 3 != 0) g.pos_std_m = uniform(0.0, 5.0);
    if (i % 4 != 0) g.vel_std_mps = uniform(0.0, 0.5);
    g.fix = static_cast<int>(uniform(0.0, 9.999));
    d.gnss.push_back(g);
  }
  t = d.odometer.front().t_s + 0.003;
  for (int i = 0; i < 300; ++i) {
    t += uniform(0.005, 0.02);
    InsSample s;
    s.t_s = t;
    s.attitude =
        Attitude{deg_to_rad(uniform(0.0, 360.0)), deg_to_rad(uniform(-90.0, 90.0)), deg_to_rad(uniform(-180.0, 180.0))};
    if (i % 5 != 0) s.vel_enu_mps = Eigen::Vector3d(uniform(-30, 30), uniform(-30, 30), uniform(-2, 2));
    d.ins.push_back(s);
  }
  t = d.odometer.front().t_s;
  for (int i = 0; i < 80; ++i) {
    t += uniform(0.01, 0.3);
    TruthSample s;
    s.t_s = t;
    s.position = Geodetic{deg_to_rad(uniform(-90.0, 90.0)), deg_to_rad(uniform(-180.0, 180.0)), uniform(0.0, 100.0)};
    s.attitude =
        Attitude{deg_to_rad(uniform(0.0, 360.0)), deg_to_rad(uniform(-10.0, 10.0)), deg_to_rad(uniform(-5.0, 5.0))};
    if (i % 7 != 3) s.k_true_m_per_pulse = uniform(0.01, 0.02);  // some rows without a value
    s.distance_m = uniform(0.0, 1e4);
    d.truth.push_back(s);
  }
  d.meta.vehicle_id = "vehicle-42";
  d.meta.description = "random, seed " + std::to_string(seed) + ", comma, \"quote\" and ü";
  d.meta.k_nominal_m_per_pulse = uniform(0.01, 0.02);
  d.meta.k_nominal_sigma_percent = uniform(0.5, 3.0);
  d.meta.truth_misalignment_heading_deg = uniform(-1.0, 1.0);
  d.meta.truth_misalignment_pitch_deg = uniform(-1.0, 1.0);
  d.meta.raw_json = R"({"operator": "test bench", "odometer": {"sprocket_teeth": 13}, "format": "x"})";
  return d;
}

void expect_equal(const Dataset& a, const Dataset& b) {
  ASSERT_EQ(a.odometer.size(), b.odometer.size());
  for (std::size_t i = 0; i < a.odometer.size(); ++i) {
    EXPECT_EQ(a.odometer[i].t_s, b.odometer[i].t_s) << i;
    EXPECT_EQ(a.odometer[i].pulses, b.odometer[i].pulses) << i;
    EXPECT_EQ(a.odometer[i].direction, b.odometer[i].direction) << i;
  }
  ASSERT_EQ(a.gnss.size(), b.gnss.size());
  for (std::size_t i = 0; i < a.gnss.size(); ++i) {
    const GnssSample &x = a.gnss[i], &y = b.gnss[i];
    EXPECT_EQ(x.t_s, y.t_s) << i;
    EXPECT_EQ(x.position.lat_rad, y.position.lat_rad) << i;
    EXPECT_EQ(x.position.lon_rad, y.position.lon_rad) << i;
    EXPECT_EQ(x.position.height_m, y.position.height_m) << i;
    EXPECT_EQ(x.vel_enu_mps, y.vel_enu_mps) << i;
    EXPECT_EQ(x.pos_std_m, y.pos_std_m) << i;
    EXPECT_EQ(x.vel_std_mps, y.vel_std_mps) << i;
    EXPECT_EQ(x.fix, y.fix) << i;
  }
  ASSERT_EQ(a.ins.size(), b.ins.size());
  for (std::size_t i = 0; i < a.ins.size(); ++i) {
    const InsSample &x = a.ins[i], &y = b.ins[i];
    EXPECT_EQ(x.t_s, y.t_s) << i;
    EXPECT_EQ(x.attitude.heading_rad, y.attitude.heading_rad) << i;
    EXPECT_EQ(x.attitude.pitch_rad, y.attitude.pitch_rad) << i;
    EXPECT_EQ(x.attitude.roll_rad, y.attitude.roll_rad) << i;
    ASSERT_EQ(x.vel_enu_mps.has_value(), y.vel_enu_mps.has_value()) << i;
    if (x.vel_enu_mps) {
      EXPECT_EQ(*x.vel_enu_mps, *y.vel_enu_mps) << i;
    }
  }
  ASSERT_EQ(a.truth.size(), b.truth.size());
  for (std::size_t i = 0; i < a.truth.size(); ++i) {
    const TruthSample &x = a.truth[i], &y = b.truth[i];
    EXPECT_EQ(x.t_s, y.t_s) << i;
    EXPECT_TRUE(same(x.position.lat_rad, y.position.lat_rad)) << i;
    EXPECT_TRUE(same(x.position.lon_rad, y.position.lon_rad)) << i;
    EXPECT_TRUE(same(x.position.height_m, y.position.height_m)) << i;
    EXPECT_TRUE(same(x.attitude.heading_rad, y.attitude.heading_rad)) << i;
    EXPECT_TRUE(same(x.attitude.pitch_rad, y.attitude.pitch_rad)) << i;
    EXPECT_TRUE(same(x.attitude.roll_rad, y.attitude.roll_rad)) << i;
    EXPECT_TRUE(same(x.k_true_m_per_pulse, y.k_true_m_per_pulse)) << i;
    EXPECT_TRUE(same(x.distance_m, y.distance_m)) << i;
  }
  EXPECT_EQ(a.meta.format, b.meta.format);
  EXPECT_EQ(a.meta.vehicle_id, b.meta.vehicle_id);
  EXPECT_EQ(a.meta.description, b.meta.description);
  EXPECT_EQ(a.meta.k_nominal_m_per_pulse, b.meta.k_nominal_m_per_pulse);
  EXPECT_EQ(a.meta.k_nominal_sigma_percent, b.meta.k_nominal_sigma_percent);
  EXPECT_EQ(a.meta.truth_misalignment_heading_deg, b.meta.truth_misalignment_heading_deg);
  EXPECT_EQ(a.meta.truth_misalignment_pitch_deg, b.meta.truth_misalignment_pitch_deg);
}

}  // namespace

TEST(DatasetRoundTrip, RandomDatasetReadsBackExactly) {
  const Dataset original = random_dataset(20240611);
  // The generator's counter does wrap, and every direction value occurs.
  bool wrapped = false;
  for (std::size_t i = 1; i < original.odometer.size(); ++i) {
    wrapped = wrapped || original.odometer[i].pulses < original.odometer[i - 1].pulses;
  }
  ASSERT_TRUE(wrapped);

  ScratchDir dir;
  write_dataset(dir.str(), original);
  DatasetReadReport report;
  const Dataset back = read_dataset(dir.str(), BadRowPolicy::kFail, &report);
  expect_equal(original, back);
  EXPECT_EQ(report.total_bad(), 0u);
  ASSERT_EQ(report.files.size(), 4u);  // odometer, gnss, ins, truth
  EXPECT_EQ(report.files[0].rows_read, 400u);
  EXPECT_EQ(report.files[1].rows_read, 120u);

  // Unknown meta.json keys are carried, known ones are the struct's (format overrides "x").
  const nlohmann::json meta = nlohmann::json::parse(back.meta.raw_json);
  EXPECT_EQ(meta.at("operator"), "test bench");
  EXPECT_EQ(meta.at("odometer").at("sprocket_teeth"), 13);
  EXPECT_EQ(meta.at("format"), "odonav-dataset/1");

  // Written twice, the files are identical (the second write starts from read-back values).
  const std::string first_gnss = read_text(dir.file("gnss.csv"));
  write_dataset(dir.str(), back);
  EXPECT_EQ(read_text(dir.file("gnss.csv")), first_gnss);
  expect_equal(original, read_dataset(dir.str(), BadRowPolicy::kFail));
}

TEST(DatasetRoundTrip, ArbitraryRadianAnglesComeBackWithinOneUlp) {
  // Not every double is d * (pi/180) for some double d; for those the nearest is written. Angles
  // from a simulator are arbitrary radians: they must come back within one ulp, most exactly.
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> angle(-3.14159, 3.14159), latitude(-1.5707, 1.5707);
  Dataset d;
  for (int i = 0; i < 2000; ++i) {
    d.odometer.push_back(OdometerSample{0.01 * i, static_cast<uint32_t>(i), 1});
    GnssSample g;
    g.t_s = 0.01 * i;
    g.position = Geodetic{latitude(rng), angle(rng), 12.5};
    d.gnss.push_back(g);
  }
  ScratchDir dir;
  write_dataset(dir.str(), d);
  const Dataset back = read_dataset(dir.str(), BadRowPolicy::kFail);
  int exact = 0;
  for (std::size_t i = 0; i < d.gnss.size(); ++i) {
    for (auto [a, b] : {std::pair{d.gnss[i].position.lat_rad, back.gnss[i].position.lat_rad},
                        std::pair{d.gnss[i].position.lon_rad, back.gnss[i].position.lon_rad}}) {
      const double ulp = std::nextafter(std::abs(a), 10.0) - std::abs(a);
      EXPECT_LE(std::abs(a - b), ulp) << i;
      exact += (a == b);
    }
  }
  EXPECT_GT(exact, 3000);  // about 91 % of random doubles have an exact degree pre-image
}

TEST(DatasetRoundTrip, OptionalColumnsAndFilesOnlyWhenUsed) {
  Dataset d;
  for (int i = 0; i < 3; ++i) {
    d.odometer.push_back(OdometerSample{0.1 * i, static_cast<uint32_t>(10 * i), 1});
    GnssSample g;
    g.t_s = 0.1 * i;
    d.gnss.push_back(g);
    InsSample s;
    s.t_s = 0.1 * i;
    d.ins.push_back(s);
  }
  ScratchDir dir;
  write_dataset(dir.str(), d);
  EXPECT_EQ(first_line(dir.file("odometer.csv")), "t,pulses,direction");
  EXPECT_EQ(first_line(dir.file("gnss.csv")), "t,lat_deg,lon_deg,height_m,ve,vn,vu,fix");
  EXPECT_EQ(first_line(dir.file("ins.csv")), "t,heading_deg,pitch_deg,roll_deg");
  EXPECT_FALSE(std::filesystem::exists(dir.file("truth.csv")));

  d.gnss[1].vel_std_mps = 0.05;
  d.ins[2].vel_enu_mps = Eigen::Vector3d(1.0, 2.0, 3.0);
  write_dataset(dir.str(), d);
  EXPECT_EQ(first_line(dir.file("gnss.csv")), "t,lat_deg,lon_deg,height_m,ve,vn,vu,vel_std_mps,fix");
  EXPECT_EQ(first_line(dir.file("ins.csv")), "t,heading_deg,pitch_deg,roll_deg,ve,vn,vu");
  const Dataset back = read_dataset(dir.str(), BadRowPolicy::kFail);
  EXPECT_FALSE(back.gnss[0].vel_std_mps.has_value());
  EXPECT_EQ(back.gnss[1].vel_std_mps, 0.05);
  EXPECT_FALSE(back.ins[0].vel_enu_mps.has_value());
  EXPECT_EQ(*back.ins[2].vel_enu_mps, Eigen::Vector3d(1.0, 2.0, 3.0));

  // Written again without INS, a stale ins.csv must not survive: the directory is degraded-mode.
  d.ins.clear();
  write_dataset(dir.str(), d);
  EXPECT_FALSE(read_dataset(dir.str(), BadRowPolicy::kFail).has_ins());
}

TEST(DatasetRoundTrip, WriterRefusesNonFiniteValues) {
  Dataset d;
  d.odometer = {OdometerSample{0.0, 0, 1}, OdometerSample{std::nan(""), 5, 1}};
  d.gnss = {GnssSample{}, GnssSample{}};
  d.gnss[1].t_s = 1.0;
  ScratchDir dir;
  try {
    write_dataset(dir.str(), d);
    FAIL() << "no error";
  } catch (const DatasetError& e) {
    EXPECT_EQ(std::string(e.what()), dir.file("odometer.csv") + ": cannot write row 2: column 't' is not finite (nan)");
  }
  EXPECT_FALSE(std::filesystem::exists(dir.file("odometer.csv")));  // nothing half-written
}

TEST(DatasetRoundTrip, WrappedCounterGivesTheDistanceAcrossTheWrap) {
  ScratchDir dir;
  dir.write("odometer.csv", "t,pulses,direction\n0.0,4294967290,1\n0.1,4294967295,1\n0.2,3,1\n0.3,10,1\n");
  dir.write("gnss.csv", "t,lat_deg,lon_deg,height_m,ve,vn,vu\n0,52,13,40,1,0,0\n1,52,13,40,1,0,0\n");
  const Dataset d = read_dataset(dir.str(), BadRowPolicy::kFail);
  ASSERT_EQ(d.odometer.size(), 4u);
  EXPECT_EQ(d.odometer[2].pulses, 3u);
  EXPECT_EQ(pulse_increment(d.odometer[0].pulses, d.odometer[1].pulses), 5u);
  EXPECT_EQ(pulse_increment(d.odometer[1].pulses, d.odometer[2].pulses), 4u);  // 4294967295 -> 0 -> 3
  uint32_t total = 0;
  for (std::size_t i = 1; i < d.odometer.size(); ++i)
    total += pulse_increment(d.odometer[i - 1].pulses, d.odometer[i].pulses);
  const double k_m_per_pulse = 0.0125;
  EXPECT_DOUBLE_EQ(k_m_per_pulse * total, 0.0125 * 16);  // 5 + 4 + 7 pulses, not 4294967276
}

TEST(DatasetRoundTrip, WriterWrapsLongitudeAndRefusesImpossibleLatitude) {
  // A dead-reckoned track may cross the antimeridian with lon beyond pi: the file gets the same
  // meridian inside [-180, 180]. A latitude beyond the pole cannot be written.
  Dataset d;
  d.odometer = {OdometerSample{0.0, 0, 1}, OdometerSample{1.0, 5, 1}};
  d.gnss.resize(2);
  d.gnss[1].t_s = 1.0;
  d.gnss[0].position.lon_rad = deg_to_rad(181.5);
  d.gnss[1].position.lon_rad = deg_to_rad(-190.0);
  ScratchDir dir;
  write_dataset(dir.str(), d);
  const Dataset back = read_dataset(dir.str(), BadRowPolicy::kFail);
  EXPECT_NEAR(rad_to_deg(back.gnss[0].position.lon_rad), -178.5, 1e-12);
  EXPECT_NEAR(rad_to_deg(back.gnss[1].position.lon_rad), 170.0, 1e-12);

  d.gnss[1].position.lat_rad = deg_to_rad(90.5);
  try {
    write_dataset(dir.str(), d);
    FAIL() << "no error";
  } catch (const DatasetError& e) {
    EXPECT_EQ(std::string(e.what()),
              dir.file("gnss.csv") + ": cannot write row 2: column 'lat_deg' is outside [-90, 90] deg");
  }
}
