// DatasetStream and TruthStream against read_dataset: the same samples bit for bit, merged in
// event-time order; the same errors and counts for bad rows; bounded buffers on a long file.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <cstring>
#include <string>
#include <vector>

#include "odonav/simulator/simulator.hpp"
#include "error_of.hpp"
#include "io_test_data.hpp"
#include "scratch_dir.hpp"
#include "odonav/dataset.hpp"
#include "odonav/dataset_stream.hpp"

using namespace odonav;
using odonav::test::ScratchDir;

namespace {

// Bit equality of doubles (NaN equal to the same NaN): the stream must give exactly read_dataset's values.
bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }
bool same_bits(const std::optional<double>& a, const std::optional<double>& b) {
  return a.has_value() == b.has_value() && (!a || same_bits(*a, *b));
}
bool same_bits(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return same_bits(a.x(), b.x()) && same_bits(a.y(), b.y()) && same_bits(a.z(), b.z());
}
bool same_bits(const Geodetic& a, const Geodetic& b) {
  return same_bits(a.lat_rad, b.lat_rad) && same_bits(a.lon_rad, b.lon_rad) && same_bits(a.height_m, b.height_m);
}
bool same_bits(const Attitude& a, const Attitude& b) {
  return same_bits(a.heading_rad, b.heading_rad) && same_bits(a.pitch_rad, b.pitch_rad) &&
         same_bits(a.roll_rad, b.roll_rad);
}
bool same(const OdometerSample& a, const OdometerSample& b) {
  return same_bits(a.t_s, b.t_s) && a.pulses == b.pulses && a.direction == b.direction;
}
bool same(const GnssSample& a, const GnssSample& b) {
  return same_bits(a.t_s, b.t_s) && same_bits(a.position, b.position) && same_bits(a.vel_enu_mps, b.vel_enu_mps) &&
         same_bits(a.pos_std_m, b.pos_std_m) && same_bits(a.vel_std_mps, b.vel_std_mps) && a.fix == b.fix;
}
bool same(const InsSample& a, const InsSample& b) {
  return same_bits(a.t_s, b.t_s) && same_bits(a.attitude, b.attitude) &&
         a.vel_enu_mps.has_value() == b.vel_enu_mps.has_value() &&
         (!a.vel_enu_mps || same_bits(*a.vel_enu_mps, *b.vel_enu_mps));
}
bool same(const TruthSample& a, const TruthSample& b) {
  return same_bits(a.t_s, b.t_s) && same_bits(a.position, b.position) && same_bits(a.attitude, b.attitude) &&
         same_bits(a.k_true_m_per_pulse, b.k_true_m_per_pulse) && same_bits(a.distance_m, b.distance_m);
}

template <typename Sample>
void expect_same_rows(const std::vector<Sample>& streamed, const std::vector<Sample>& whole, const char* file) {
  ASSERT_EQ(streamed.size(), whole.size()) << file;
  for (std::size_t i = 0; i < whole.size(); ++i) {
    ASSERT_TRUE(same(streamed[i], whole[i])) << file << " row " << i << " t " << whole[i].t_s;
  }
}

int tie_rank(DatasetStreamKind kind) {
  switch (kind) {
    case DatasetStreamKind::kGnss: return 0;
    case DatasetStreamKind::kIns: return 1;
    case DatasetStreamKind::kOdometer: return 2;
  }
  return 3;
}

// Streams `dir` to its end and checks that the events, split by file, are read_dataset's vectors,
// that they come in event-time order (ties GNSS, INS, odometer), that TruthStream gives the truth
// vector, and that the reports agree. Returns the number of events whose t_s equals the previous one's.
std::size_t expect_stream_equals_read_dataset(const std::string& dir, BadRowPolicy policy = BadRowPolicy::kFail) {
  DatasetReadReport whole_report;
  const Dataset whole = read_dataset(dir, policy, &whole_report);

  DatasetReadReport stream_report;
  DatasetStream stream(dir, policy, &stream_report);
  EXPECT_EQ(stream.has_ins(), whole.has_ins());
  EXPECT_EQ(stream.has_truth(), whole.has_truth());
  EXPECT_EQ(stream.meta().raw_json, whole.meta.raw_json);
  EXPECT_EQ(stream.meta().k_nominal_m_per_pulse, whole.meta.k_nominal_m_per_pulse);
  EXPECT_EQ(stream.meta().gnss_lever_arm_m.has_value(), whole.meta.gnss_lever_arm_m.has_value());

  std::vector<OdometerSample> odometer;
  std::vector<GnssSample> gnss;
  std::vector<InsSample> ins;
  std::size_t ties = 0;
  std::optional<DatasetEvent> previous;
  while (std::optional<DatasetEvent> event = stream.next()) {
    switch (event->kind) {
      case DatasetStreamKind::kOdometer:
        EXPECT_TRUE(same_bits(event->t_s, event->odometer.t_s));
        odometer.push_back(event->odometer);
        break;
      case DatasetStreamKind::kGnss:
        EXPECT_TRUE(same_bits(event->t_s, event->gnss.t_s));
        gnss.push_back(event->gnss);
        break;
      case DatasetStreamKind::kIns:
        EXPECT_TRUE(same_bits(event->t_s, event->ins.t_s));
        ins.push_back(event->ins);
        break;
    }
    if (previous) {
      EXPECT_LE(previous->t_s, event->t_s) << "out of order at t " << event->t_s;
      if (previous->t_s == event->t_s) {
        ++ties;
        EXPECT_LT(tie_rank(previous->kind), tie_rank(event->kind)) << "tie order at t " << event->t_s;
      }
    }
    previous = event;
  }
  EXPECT_FALSE(stream.next().has_value()) << "the end stays the end";
  expect_same_rows(odometer, whole.odometer, "odometer");
  expect_same_rows(gnss, whole.gnss, "gnss");
  expect_same_rows(ins, whole.ins, "ins");

  TruthStream truth_stream(dir, policy, &stream_report);
  EXPECT_EQ(truth_stream.has_file(), std::filesystem::exists(dir + "/truth.csv"));
  std::vector<TruthSample> truth;
  while (std::optional<TruthSample> row = truth_stream.next()) truth.push_back(*row);
  expect_same_rows(truth, whole.truth, "truth");

  EXPECT_EQ(&stream.report(), &stream_report);
  EXPECT_EQ(stream_report.files.size(), whole_report.files.size());
  for (std::size_t i = 0; i < std::min(stream_report.files.size(), whole_report.files.size()); ++i) {
    EXPECT_EQ(stream_report.files[i].file, whole_report.files[i].file);
    EXPECT_EQ(stream_report.files[i].rows_read, whole_report.files[i].rows_read) << whole_report.files[i].file;
    EXPECT_EQ(stream_report.files[i].rows_bad, whole_report.files[i].rows_bad) << whole_report.files[i].file;
    EXPECT_EQ(stream_report.files[i].ignored_columns, whole_report.files[i].ignored_columns);
  }
  EXPECT_EQ(stream_report.total_bad(), whole_report.total_bad());
  return ties;
}

// The DatasetError text of `read`, empty when it does not throw.
template <typename F>
std::string error_of(F read) {
  return test::message_if_thrown<DatasetError>(read);
}

// The error of streaming `dir` to its end (opening included), empty when there is none.
std::string stream_error(const std::string& dir, BadRowPolicy policy) {
  return error_of([&] {
    DatasetStream stream(dir, policy);
    while (stream.next()) {
    }
    TruthStream truth(dir, policy);
    while (truth.next()) {
    }
  });
}

using odonav::test::kGoodGnss;
using odonav::test::kGoodOdometer;

}  // namespace

TEST(DatasetStream, ShippedSmartLocRecordingStreamsExactlyAsReadDataset) {
  const std::string dir = std::string(ODONAV_SOURCE_DIR) + "/tests/data/smartloc-berlin";
  const std::size_t ties = expect_stream_equals_read_dataset(dir);
  EXPECT_GT(ties, 0u) << "the recording stamps odometer, INS and GNSS on one grid: ties must be exercised";
}

TEST(DatasetStream, SimulatedDatasetsStreamExactlyAsReadDataset) {
  // terrain: 100 Hz odometer and INS, 10 Hz GNSS, 100 Hz truth on one grid (every GNSS epoch a
  // three-way tie); with receiver latency the GNSS stamps fall between; slow_robot has no INS.
  struct Case {
    const char* scenario;
    double gnss_latency_s;
  };
  for (const Case& c : {Case{"terrain", 0.0}, Case{"terrain", 0.037}, Case{"slow_robot", 0.0}}) {
    SCOPED_TRACE(std::string(c.scenario) + " latency " + std::to_string(c.gnss_latency_s));
    simulator::SimulationConfig config = simulator::scenario_config(c.scenario);
    config.gnss_latency_s = c.gnss_latency_s;
    ScratchDir dir;
    write_dataset(dir.str(), simulator::simulate(config));
    const std::size_t ties = expect_stream_equals_read_dataset(dir.str());
    if (c.gnss_latency_s == 0.0) {
      EXPECT_GT(ties, 0u);
    }
  }
}

TEST(DatasetStream, FileChecksAtOpenGiveReadDatasetsMessages) {
  ScratchDir dir;
  const auto both = [&](const std::string& context) {
    SCOPED_TRACE(context);
    const std::string expected = error_of([&] { read_dataset(dir.str(), BadRowPolicy::kSkip); });
    EXPECT_FALSE(expected.empty());
    EXPECT_EQ(error_of([&] { DatasetStream(dir.str(), BadRowPolicy::kSkip); }), expected);
  };
  EXPECT_EQ(error_of([&] { DatasetStream(dir.file("nowhere"), BadRowPolicy::kFail); }),
            dir.file("nowhere") + ": dataset directory does not exist");
  both("no odometer.csv");
  dir.write("odometer.csv", kGoodOdometer);
  both("no gnss.csv");
  dir.write("gnss.csv", "t,lat_deg,height_m,ve,vn,vu\n0,52,40,1,2,0\n1,52,40,1,2,0\n");
  both("a required column missing");
  dir.write("gnss.csv", "t,lat_deg,lon_deg,height_m,ve,vn,vu\n0,52,13,40,1,2,0\n1,52,13,40,x,2,0\n");
  both("one good gnss row");
  dir.write("gnss.csv", kGoodGnss);
  dir.write("ins.csv", "t,heading_deg,pitch_deg,roll_deg,ve\n0,1,0,0,1\n");
  both("ins.csv with only ve");
  dir.write("ins.csv", "t,heading_deg,pitch_deg,roll_deg\n");
  dir.write("truth.csv", "t,t\n");
  both("duplicate truth column");
  dir.write("truth.csv", "t,k_true\n0,0.0125\n");
  dir.write("meta.json", "[1, 2]");
  both("meta.json not an object");
  dir.write("meta.json", "{\"odometer\": {\"k_nominal_m_per_pulse\": 0.0126, \"k_nominal_sigma_percent\": 0}}");
  both("k_nominal_sigma_percent");  // (0, 100] %
  dir.write("meta.json", "{\"odometer\": {\"k_nominal_m_per_pulse\": 0.0126, \"k_nominal_sigma_percent\": 1.5}}");
  DatasetStream stream(dir.str(), BadRowPolicy::kFail);
  EXPECT_FALSE(stream.has_ins()) << "an ins.csv without a data row is absent";
  EXPECT_TRUE(stream.has_truth());
  EXPECT_EQ(stream.meta().k_nominal_m_per_pulse, 0.0126);
  EXPECT_EQ(stream.meta().k_nominal_sigma_percent, 1.5);
  expect_stream_equals_read_dataset(dir.str());
}

TEST(DatasetStream, BadRowsInTheMiddleFailOrAreSkippedAsReadDatasetDoes) {
  ScratchDir dir;
  dir.write("odometer.csv",
            "t,pulses,direction\n0.0,100,1\n0.5,180,1\n# a comment\n0.7,x,1\n1.0,260,1\n0.9,270,1\n1.5,300,1,7\n"
            "2.0,340,1\n");
  dir.write("gnss.csv",
            "t,lat_deg,lon_deg,height_m,ve,vn,vu,fix\n0.0,52.5,13.4,40,1,2,0,1\n1.0,52.5,13.4,40,1,2,0,1\n"
            "1.2,52.5,13.4,40,1e6,2,0,1\n2.0,52.5,13.4,40,1,2,0,1\n");
  dir.write("ins.csv", "t,heading_deg,pitch_deg,roll_deg\n0.0,10,0,0\n0.25,10,95,0\n0.5,10,0,0\n1.0,10,0,0\n");
  dir.write("truth.csv", "t,k_true\n0,0.0125\n0.5,nan\n1,0.0125\n");

  // skip: the same samples and counts.
  expect_stream_equals_read_dataset(dir.str(), BadRowPolicy::kSkip);
  DatasetReadReport whole_report, stream_report;
  read_dataset(dir.str(), BadRowPolicy::kSkip, &whole_report);
  {
    DatasetStream stream(dir.str(), BadRowPolicy::kSkip, &stream_report);
    while (stream.next()) {
    }
    TruthStream truth(dir.str(), BadRowPolicy::kSkip, &stream_report);
    while (truth.next()) {
    }
  }
  // The same bad rows in detail; the stream meets them in event-time order, read_dataset file by file.
  std::vector<std::string> whole_messages, stream_messages;
  for (const BadRow& bad : whole_report.bad_rows) whole_messages.push_back(bad.message());
  for (const BadRow& bad : stream_report.bad_rows) stream_messages.push_back(bad.message());
  EXPECT_EQ(whole_messages.size(), 6u);
  std::sort(whole_messages.begin(), whole_messages.end());
  std::sort(stream_messages.begin(), stream_messages.end());
  EXPECT_EQ(stream_messages, whole_messages);

  // fail: with one bad row at a time, the same message; what the stream gave before it was good.
  const std::string odometer_bad =
      dir.file("odometer.csv") + ":5: column 'pulses': must be an integer in [0, 4294967295]: 'x'";
  EXPECT_EQ(error_of([&] { read_dataset(dir.str(), BadRowPolicy::kFail); }), odometer_bad);
  // The first bad row in event time is the INS one (t 0.25).
  const std::string ins_bad = dir.file("ins.csv") + ":3: column 'pitch_deg': pitch outside [-90, 90]: '95'";
  EXPECT_EQ(stream_error(dir.str(), BadRowPolicy::kFail), ins_bad);
  dir.write("ins.csv", "t,heading_deg,pitch_deg,roll_deg\n0.0,10,0,0\n0.5,10,0,0\n1.0,10,0,0\n");
  DatasetStream stream(dir.str(), BadRowPolicy::kFail);
  std::vector<double> odometer_t;
  const std::string why = error_of([&] {
    while (std::optional<DatasetEvent> event = stream.next()) {
      if (event->kind == DatasetStreamKind::kOdometer) odometer_t.push_back(event->t_s);
    }
  });
  EXPECT_EQ(why, odometer_bad);
  EXPECT_EQ(odometer_t, (std::vector<double>{0.0, 0.5})) << "the rows before the bad one, and no other";
  dir.write("odometer.csv", kGoodOdometer);
  EXPECT_EQ(stream_error(dir.str(), BadRowPolicy::kFail),
            error_of([&] { read_dataset(dir.str(), BadRowPolicy::kFail); }));
  EXPECT_NE(stream_error(dir.str(), BadRowPolicy::kFail).find("gnss.csv:4: column 've'"), std::string::npos);
  dir.write("gnss.csv", kGoodGnss);
  EXPECT_EQ(stream_error(dir.str(), BadRowPolicy::kFail),
            dir.file("truth.csv") + ":3: column 'k_true': NaN or infinity is not allowed: 'nan'");
}

TEST(DatasetStream, TwoMillionOdometerRowsStreamWithBoundedBuffers) {
  ScratchDir dir;
  constexpr std::size_t kRows = 2'000'000;  // 20 000 s at 100 Hz
  {
    std::FILE* out = std::fopen(dir.file("odometer.csv").c_str(), "wb");
    ASSERT_NE(out, nullptr);
    std::fputs("t,pulses,direction\n", out);
    for (std::size_t i = 0; i < kRows; ++i) std::fprintf(out, "%zu.%02zu,%zu,1\n", i / 100, i % 100, i);
    std::fclose(out);
  }
  dir.write("gnss.csv",
            "t,lat_deg,lon_deg,height_m,ve,vn,vu\n0.005,52.5,13.4,40,1,2,0\n10000.005,52.5,13.4,40,1,2,0\n"
            "19999.995,52.5,13.4,40,1,2,0\n");

  DatasetStream stream(dir.str(), BadRowPolicy::kFail);
  const std::size_t at_open = stream.buffered_bytes();
  // Two sensor files: each a read buffer, at most one spanning line and a row's fields, a few rows.
  EXPECT_LT(at_open, 2 * (256 * 1024u)) << "buffers at open";
  std::size_t odometer_rows = 0, gnss_rows = 0;
  std::optional<std::size_t> after_first_rows;
  double previous_t = -1.0;
  uint32_t expected_pulses = 0;
  while (std::optional<DatasetEvent> event = stream.next()) {
    ASSERT_GE(event->t_s, previous_t);
    previous_t = event->t_s;
    if (event->kind == DatasetStreamKind::kGnss) {
      ++gnss_rows;
      continue;
    }
    ASSERT_EQ(event->odometer.pulses, expected_pulses);
    ++expected_pulses;
    if (++odometer_rows % 100'000 == 0) {
      // The spanning-line buffer is made when the first line crosses a read; after that nothing grows.
      if (!after_first_rows) after_first_rows = stream.buffered_bytes();
      ASSERT_EQ(stream.buffered_bytes(), *after_first_rows) << "buffers grew at odometer row " << odometer_rows;
    }
  }
  EXPECT_EQ(odometer_rows, kRows);
  EXPECT_EQ(gnss_rows, 3u);
  EXPECT_EQ(stream.report().files.at(0).rows_read, kRows);
  ASSERT_TRUE(after_first_rows.has_value());
  EXPECT_LE(*after_first_rows, 2 * (256 * 1024u));
  EXPECT_EQ(stream.buffered_bytes(), *after_first_rows);
}
