// odonav-recorder's message -> row conversion: what reaches the CSV files from a message equals
// what odonav-offline writes for the core output the message was made from.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <optional>
#include <stdexcept>
#include <random>
#include <sstream>
#include <vector>

#include <sys/stat.h>

#include "node/recorder_node.hpp"
#include "odonav/calibration/misalignment_calibrator.hpp"
#include "odonav/dead_reckoning/dead_reckoner.hpp"
#include "odonav/dds/output_messages.hpp"
#include "odonav/dds/time.hpp"
#include "odonav/frames.hpp"

using namespace odonav;

namespace {
std::string read_file(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}
}  // namespace

TEST(RecorderRows, DegreesReachTheFileUnchanged) {
  // The producer sends rad_to_deg(r); the row holds exact_radians_of(d); the CSV writer writes
  // rad_to_deg(row): that must be d again, as odonav-offline writes rad_to_deg(r).
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> angle(-kPi / 2, kPi / 2);
  for (int i = 0; i < 20000; ++i) {
    const double r = angle(rng);
    const double d = rad_to_deg(r);
    ASSERT_EQ(rad_to_deg(exact_radians_of(d)), d) << r;
  }
}

TEST(RecorderRows, MisalignmentUnknownSigmaIsEmptyAndStateIsNamed) {
  odonav::msg::Misalignment m;
  m.header(odonav::dds::make_header(12.3, "body"));
  m.heading_rad(deg_to_rad(0.8));
  m.pitch_rad(deg_to_rad(-0.5));
  m.heading_std_rad(-1.0);
  m.pitch_std_rad(1e-4);
  m.samples_used(42);
  m.converged(false);
  m.state(odonav::msg::MISALIGNMENT_CALIBRATING);
  const results::MisalignmentRow r = odonav::dds::row_of(m);
  EXPECT_EQ(r.t_s, 12.3);
  EXPECT_EQ(r.heading_rad, deg_to_rad(0.8));
  EXPECT_TRUE(std::isnan(r.heading_std_rad));
  EXPECT_EQ(r.pitch_std_rad, 1e-4);
  EXPECT_EQ(r.samples_used, 42u);
  EXPECT_EQ(r.state, "calibrating");

  const std::string dir = std::string(ODONAV_BINARY_DIR) + "/test-recorder-rows";
  ::mkdir(dir.c_str(), 0755);
  {
    results::MisalignmentCsv csv(dir + "/misalignment.csv");
    csv.write(r);
    csv.close();
  }
  const std::string text = read_file(dir + "/misalignment.csv");
  // t, heading (deg), pitch (deg), heading sigma empty, pitch sigma (deg), converged 0, state, samples
  const std::string row = text.substr(text.find('\n') + 1);
  std::vector<std::string> f(1);
  for (char c : row) {
    if (c == ',')
      f.emplace_back();
    else if (c != '\n')
      f.back() += c;
  }
  ASSERT_EQ(f.size(), 8u) << text;
  EXPECT_EQ(f[0], "12.3");
  EXPECT_NEAR(std::stod(f[1]), 0.8, 1e-12);
  EXPECT_NEAR(std::stod(f[2]), -0.5, 1e-12);
  EXPECT_EQ(f[3], "");
  EXPECT_NEAR(std::stod(f[4]), rad_to_deg(1e-4), 1e-15);
  EXPECT_EQ(f[5], "0");
  EXPECT_EQ(f[6], "calibrating");
  EXPECT_EQ(f[7], "42");
}

TEST(RecorderRows, ScaleFactorWithoutValueAndWithValue) {
  odonav::msg::ScaleFactor m;
  m.header(odonav::dds::make_header(20.0, "odometer"));
  m.k_m_per_pulse(0.0);  // the producer's "no value yet"
  m.sigma_m_per_pulse(-1.0);
  m.forgetting_factor(1.0);
  m.window_fill(0.25);
  m.estimator("vff_lm_rls");
  m.samples_accepted(3);
  m.samples_rejected(7);
  results::ScaleFactorRow r = odonav::dds::row_of(m);
  EXPECT_FALSE(r.k_m_per_pulse.has_value());
  EXPECT_FALSE(r.sigma_m_per_pulse.has_value());
  EXPECT_FALSE(r.lambda_vff_lm_rls.has_value());
  ASSERT_EQ(r.k_by_estimator.size(), 1u);
  EXPECT_EQ(r.k_by_estimator[0].first, "vff_lm_rls");
  EXPECT_EQ(r.samples_rejected, 7u);

  m.k_m_per_pulse(0.0126875);
  m.sigma_m_per_pulse(2e-6);
  m.forgetting_factor(0.97);
  m.converged(true);
  r = odonav::dds::row_of(m);
  EXPECT_EQ(*r.k_m_per_pulse, 0.0126875);
  EXPECT_EQ(*r.k_by_estimator[0].second, 0.0126875);
  EXPECT_EQ(*r.sigma_m_per_pulse, 2e-6);
  EXPECT_EQ(*r.lambda_vff_lm_rls, 0.97);
  EXPECT_TRUE(r.converged);
}

TEST(RecorderRows, DeadReckoningWithoutReference) {
  odonav::msg::DeadReckoning m;
  m.header(odonav::dds::make_header(100.25, "wgs84"));
  m.latitude_deg(52.5001);
  m.longitude_deg(13.4002);
  m.height_m(81.5);
  m.distance_m(1234.5);
  m.k_m_per_pulse(0.0125);
  m.k_source(odonav::msg::K_SOURCE_IDENTIFIED);
  m.heading_rad(1.0);
  m.horizontal_error_m(-1.0);
  m.error_percent_distance(-1.0);
  const results::DeadReckoningRow r = odonav::dds::row_of(m);
  EXPECT_EQ(r.t_s, 100.25);
  EXPECT_EQ(rad_to_deg(r.lat_rad), 52.5001);
  EXPECT_EQ(rad_to_deg(r.lon_rad), 13.4002);
  EXPECT_EQ(r.k_source, "identified");
  EXPECT_TRUE(std::isnan(r.horizontal_error_m));
  EXPECT_TRUE(std::isnan(r.error_percent));
}

TEST(RecorderRows, NavigationPositionUnknownsAreEmptyAndStatusIsNamedAsOfflineWritesIt) {
  odonav::msg::NavigationPosition m;
  m.header(odonav::dds::make_header(100.25, "wgs84"));
  m.latitude_deg(52.5001);
  m.longitude_deg(13.4002);
  m.height_m(81.5);
  m.enu_east_m(12.5);
  m.enu_north_m(-3.25);
  m.enu_up_m(0.5);
  // Before the first fix: covariance, last fix and distance unknown on the wire (-1).
  m.position_covariance_east_m2(-1.0);
  m.position_covariance_north_m2(-1.0);
  m.position_covariance_up_m2(-1.0);
  m.position_covariance_type(0);
  m.status(odonav::msg::NAVIGATION_STATUS_NOT_STARTED);
  m.last_fix_stamp_s(-1.0);
  m.distance_since_fix_m(-1.0);
  results::NavigationPositionRow r = odonav::dds::row_of(m);
  EXPECT_EQ(r.t_s, 100.25);
  EXPECT_EQ(rad_to_deg(r.lat_rad), 52.5001);
  EXPECT_EQ(r.east_m, 12.5);
  EXPECT_EQ(r.status, "not_started");  // to_string(AnchorStatus::kNotStarted), as odonav-offline writes it
  EXPECT_TRUE(std::isnan(r.var_east_m2) && std::isnan(r.var_up_m2) && std::isnan(r.last_fix_t_s) &&
              std::isnan(r.distance_since_fix_m));
  // Bridging an outage: every value known.
  m.position_covariance_east_m2(1.5);
  m.position_covariance_north_m2(1.25);
  m.position_covariance_up_m2(3.0);
  m.position_covariance_type(2);
  m.status(odonav::msg::NAVIGATION_STATUS_DEAD_RECKONING);
  m.last_fix_stamp_s(98.5);
  m.distance_since_fix_m(17.5);
  r = odonav::dds::row_of(m);
  EXPECT_EQ(r.status, "dead_reckoning");
  EXPECT_EQ(r.var_north_m2, 1.25);
  EXPECT_EQ(r.last_fix_t_s, 98.5);
  EXPECT_EQ(r.distance_since_fix_m, 17.5);
}

// The field table (odonav/dds/output_messages.hpp) carries every column a row shares with its
// message: a row written to its file, and the same row sent as a message and recorded, give the same
// text, for random values with each "unknown" taken at random, and every enumeration name the cores
// write crosses the wire unchanged.
template <class Row, class Csv>
std::string file_text_of(const Row& row, const std::string& path) {
  {
    Csv csv(path);
    csv.write(row);
    csv.close();
  }
  return read_file(path);
}

/// `row` sent as its message and recorded gives the same file text (in dir) as `row` written.
template <class Csv, class Row>
void expect_same_text_after_the_wire(const Row& row, const std::string& dir) {
  const Row recorded = odonav::dds::row_of(odonav::dds::message_of(row));
  ASSERT_EQ((file_text_of<Row, Csv>(recorded, dir + "/b.csv")), (file_text_of<Row, Csv>(row, dir + "/a.csv")));
}

TEST(OutputMessages, EverySharedColumnCrossesTheWireUnchanged) {
  const std::string dir = std::string(ODONAV_BINARY_DIR) + "/test-output-messages";
  ::mkdir(dir.c_str(), 0755);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::bernoulli_distribution unknown(0.3);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  auto maybe = [&](double v) { return unknown(rng) ? nan : v; };
  auto maybe_opt = [&](double v) { return unknown(rng) ? std::nullopt : std::optional<double>(v); };
  // The names as the cores write them into odonav-offline's files.
  const char* calibration_states[] = {
      to_string(calibration::CalibrationState::kWaiting), to_string(calibration::CalibrationState::kCalibrating),
      to_string(calibration::CalibrationState::kConverged), to_string(calibration::CalibrationState::kFrozen)};
  const char* k_sources[] = {to_string(dead_reckoning::ScaleFactorSource::kNominal),
                             to_string(dead_reckoning::ScaleFactorSource::kIdentified),
                             to_string(dead_reckoning::ScaleFactorSource::kCommanded)};
  const char* statuses[] = {to_string(dead_reckoning::AnchorStatus::kNotStarted),
                            to_string(dead_reckoning::AnchorStatus::kAnchored),
                            to_string(dead_reckoning::AnchorStatus::kDeadReckoning)};
  for (int i = 0; i < 200; ++i) {
    const double t = 100.0 + 0.01 * i;
    results::MisalignmentRow mr;
    mr.t_s = t;
    mr.heading_rad = 0.02 * u(rng);
    mr.pitch_rad = 0.02 * u(rng);
    mr.heading_std_rad = maybe(1e-4 * (1.0 + u(rng)));
    mr.pitch_std_rad = maybe(1e-4 * (1.0 + u(rng)));
    mr.converged = u(rng) > 0;
    mr.state = calibration_states[i % 4];
    mr.samples_used = static_cast<uint64_t>(i * 7);
    ASSERT_NO_FATAL_FAILURE(expect_same_text_after_the_wire<results::MisalignmentCsv>(mr, dir));

    results::ScaleFactorRow kr;
    kr.t_s = t;
    kr.estimator = "vff_lm_rls";
    kr.k_m_per_pulse = maybe_opt(0.0125 * (1.0 + 0.1 * u(rng)));
    kr.k_by_estimator = {{kr.estimator, kr.k_m_per_pulse}};
    if (kr.k_m_per_pulse) kr.sigma_m_per_pulse = maybe_opt(1e-6 * (1.0 + u(rng)));
    kr.forgetting_factor = 0.99 + 0.01 * u(rng);
    if (kr.k_m_per_pulse) kr.lambda_vff_lm_rls = kr.forgetting_factor;
    kr.window_fill = 0.5 + 0.5 * u(rng);
    kr.converged = kr.k_m_per_pulse && u(rng) > 0;
    kr.samples_accepted = static_cast<uint64_t>(i * 3);
    kr.samples_rejected = static_cast<uint64_t>(i);
    kr.gnss_latency_s = 0.1 * u(rng);
    kr.gnss_latency_sigma_s = maybe_opt(1e-3 * (1.0 + u(rng)));
    kr.turn_slip_s_per_rad = 0.05 * (1.0 + u(rng));
    kr.turn_slip_sigma_s_per_rad = maybe_opt(1e-3 * (1.0 + u(rng)));
    kr.turn_slip_applies = u(rng) > 0;
    ASSERT_NO_FATAL_FAILURE(expect_same_text_after_the_wire<results::ScaleFactorCsv>(kr, dir));

    results::DeadReckoningRow dr;
    dr.t_s = t;
    dr.lat_rad = 1.2 * u(rng);
    dr.lon_rad = 3.0 * u(rng);
    dr.height_m = 100.0 * u(rng);
    dr.distance_m = 1000.0 * (1.0 + u(rng));
    dr.k_m_per_pulse = 0.0125 * (1.0 + 0.1 * u(rng));
    dr.k_source = k_sources[i % 3];
    dr.east_m = 500.0 * u(rng);
    dr.north_m = 500.0 * u(rng);
    dr.up_m = 10.0 * u(rng);
    dr.heading_rad = 3.0 * (1.0 + u(rng));
    dr.horizontal_error_m = maybe(2.0 * (1.0 + u(rng)));
    dr.error_percent = maybe(0.1 * (1.0 + u(rng)));
    dr.error_t_s = maybe(t - 0.05);
    ASSERT_NO_FATAL_FAILURE(expect_same_text_after_the_wire<results::DeadReckoningCsv>(dr, dir));

    results::NavigationPositionRow nr;
    nr.t_s = t;
    nr.lat_rad = 1.2 * u(rng);
    nr.lon_rad = 3.0 * u(rng);
    nr.height_m = 100.0 * u(rng);
    nr.east_m = 500.0 * u(rng);
    nr.north_m = 500.0 * u(rng);
    nr.up_m = 10.0 * u(rng);
    nr.var_east_m2 = maybe(1.0 + u(rng));
    nr.var_north_m2 = maybe(1.0 + u(rng));
    nr.var_up_m2 = maybe(4.0 + u(rng));
    nr.status = statuses[i % 3];
    nr.last_fix_t_s = maybe(t - 0.1);
    nr.distance_since_fix_m = maybe(10.0 * (1.0 + u(rng)));
    ASSERT_NO_FATAL_FAILURE(expect_same_text_after_the_wire<results::NavigationPositionCsv>(nr, dir));
  }
}

TEST(OutputMessages, AnEnumerationNameTheTopicDoesNotKnowIsRefusedByName) {
  results::MisalignmentRow r;
  r.state = "calibratin";
  try {
    (void)odonav::dds::message_of(r);
    FAIL() << "accepted an unknown state";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'calibratin'"), std::string::npos) << e.what();
  }
}

// gaps.csv: 10 Hz GNSS epochs 0.0-20.0 s; the calibration's rows are all there, the
// identification's of 5.1-8.0 s (30 epochs) are not; dead reckoning lost 100 outputs at 100 Hz
// (12.01-13.00 s). Rows per topic in the order the file promises, and the file as written.
TEST(RecorderGaps, EstimateRowsMissingAgainstGnssAndOutputHolesAreNamed) {
  std::vector<double> epochs, k;
  for (int i = 0; i <= 200; ++i) {
    epochs.push_back(i * 0.1);
    if (i <= 50 || i > 80) k.push_back(i * 0.1);
  }
  GapDetector dr(0.01);
  std::vector<OutputGap> dr_gaps;
  for (int i = 0; i <= 2000; ++i)
    if (i <= 1200 || i > 1300)
      if (const auto g = dr.offer(i * 0.01)) dr_gaps.push_back(*g);
  const auto rows = recorder::recording_gaps(epochs, epochs, k, dr_gaps, {});
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0].topic, "rt/odonav/scale_factor");
  EXPECT_NEAR(rows[0].first_missing_t_s, 5.1, 1e-9);
  EXPECT_NEAR(rows[0].last_missing_t_s, 8.0, 1e-9);
  EXPECT_EQ(rows[0].count, 30u);
  EXPECT_EQ(rows[1].topic, "rt/odonav/dead_reckoning");
  EXPECT_NEAR(rows[1].first_missing_t_s, 12.01, 1e-9);
  EXPECT_NEAR(rows[1].last_missing_t_s, 13.00, 1e-9);
  EXPECT_EQ(rows[1].count, 100u);

  char dir_template[] = "/tmp/odonav-recorder-gaps-XXXXXX";
  ASSERT_NE(mkdtemp(dir_template), nullptr);
  const std::string path = std::string(dir_template) + "/gaps.csv";
  {
    recorder::GapsCsv csv(path);
    for (const auto& r : rows) csv.write(r);
    csv.close();
  }
  const std::string text = read_file(path);
  EXPECT_EQ(text.substr(0, text.find('\n')), "topic,first_missing_t_s,last_missing_t_s,count,reason");
  EXPECT_NE(text.find("\nrt/odonav/scale_factor,5.1"), std::string::npos) << text;
  EXPECT_NE(text.find(",8,30,no scale factor for these GNSS epochs"), std::string::npos) << text;
  EXPECT_NE(text.find("\nrt/odonav/dead_reckoning,12.01,13,100,no dead-reckoning outputs"), std::string::npos) << text;
  // Lossless: the header only.
  EXPECT_TRUE(recorder::recording_gaps(epochs, epochs, epochs, {}, {}).empty());
}
