// Dataset reader validation: every bad-row kind of docs/DATASET.md, under fail (the exact message with
// file, line and column) and under skip (the counts, and every good row kept).
#include <gtest/gtest.h>
#include <spdlog/sinks/ringbuffer_sink.h>
#include <spdlog/spdlog.h>

#include "io_test_data.hpp"
#include "scratch_dir.hpp"
#include "odonav/dataset.hpp"

using namespace odonav;
using odonav::test::ScratchDir;

namespace {

using odonav::test::kGoodGnss;
using odonav::test::kGoodOdometer;

// A directory holding `file` with `content` and the good version of the other required file.
struct DatasetDir {
  ScratchDir dir;
  DatasetDir(const std::string& file, const std::string& content) {
    dir.write("odometer.csv", kGoodOdometer);
    dir.write("gnss.csv", kGoodGnss);
    dir.write(file, content);
  }
};

// The DatasetError text of reading `dir` under kFail; empty when it reads.
std::string fail_message(const ScratchDir& dir) {
  try {
    read_dataset(dir.str(), BadRowPolicy::kFail);
  } catch (const DatasetError& e) {
    return e.what();
  }
  return "";
}

// One bad odometer row between good ones: under fail the exact message, under skip one bad row
// counted with the same message and the three good rows kept.
// `what` is the message after "<file>:<line>: ".
void expect_bad_odometer_row(const std::string& bad_row, const std::string& column, const std::string& what) {
  SCOPED_TRACE(bad_row);
  DatasetDir d("odometer.csv", std::string("t,pulses,direction\n0.0,100,1\n0.5,180,1\n") + bad_row + "\n1.0,260,1\n");
  const std::string file = d.dir.file("odometer.csv");
  EXPECT_EQ(fail_message(d.dir), file + ":4: " + what);

  DatasetReadReport report;
  const Dataset ds = read_dataset(d.dir.str(), BadRowPolicy::kSkip, &report);
  ASSERT_EQ(ds.odometer.size(), 3u);
  EXPECT_EQ(ds.odometer[0].pulses, 100u);
  EXPECT_EQ(ds.odometer[1].pulses, 180u);
  EXPECT_EQ(ds.odometer[2].pulses, 260u);
  EXPECT_EQ(ds.odometer[2].t_s, 1.0);
  ASSERT_EQ(report.files.size(), 2u);
  EXPECT_EQ(report.files[0].file, file);
  EXPECT_EQ(report.files[0].rows_bad, 1u);
  EXPECT_EQ(report.files[0].rows_read, 3u);
  EXPECT_EQ(report.total_bad(), 1u);
  ASSERT_EQ(report.bad_rows.size(), 1u);
  EXPECT_EQ(report.bad_rows[0].line, 4u);
  EXPECT_EQ(report.bad_rows[0].column, column);
  EXPECT_EQ(report.bad_rows[0].message(), file + ":4: " + what);
}

// The same for one bad gnss row (line 3, between two good rows).
void expect_bad_gnss_row(const std::string& header, const std::string& bad_row, const std::string& column,
                         const std::string& reason) {
  SCOPED_TRACE(bad_row);
  DatasetDir d("gnss.csv", header + "\n0.0,52.5,13.4,40,1,2,0,0.5,0.05,4\n" + bad_row +
                               "\n1.0,52.5,13.4,40,1,2,0,0.5,0.05,4\n2.0,52.5,13.4,40,1,2,0,0.5,0.05,4\n");
  EXPECT_EQ(fail_message(d.dir), d.dir.file("gnss.csv") + ":3: column '" + column + "': " + reason);
  DatasetReadReport report;
  const Dataset ds = read_dataset(d.dir.str(), BadRowPolicy::kSkip, &report);
  ASSERT_EQ(ds.gnss.size(), 3u);
  EXPECT_EQ(ds.gnss[1].t_s, 1.0);
  EXPECT_EQ(ds.gnss[2].fix, 4);
  EXPECT_EQ(report.total_bad(), 1u);
}

const std::string kFullGnssHeader = "t,lat_deg,lon_deg,height_m,ve,vn,vu,pos_std_m,vel_std_mps,fix";

}  // namespace

TEST(DatasetValidation, MissingRequiredColumnIsAFileErrorUnderEitherPolicy) {
  DatasetDir d("gnss.csv", "t,lat_deg,height_m,ve,vn,vu\n0,52,40,1,2,0\n1,52,40,1,2,0\n");
  const std::string expected =
      d.dir.file("gnss.csv") + ":1: required column 'lon_deg' is missing (header: t,lat_deg,height_m,ve,vn,vu)";
  EXPECT_EQ(fail_message(d.dir), expected);
  try {
    read_dataset(d.dir.str(), BadRowPolicy::kSkip);
    FAIL() << "no error under skip";
  } catch (const DatasetError& e) {
    EXPECT_EQ(std::string(e.what()), expected);
  }
}

TEST(DatasetValidation, MissingRequiredFileOrDirectory) {
  ScratchDir dir;
  dir.write("odometer.csv", kGoodOdometer);
  EXPECT_EQ(fail_message(dir), dir.file("gnss.csv") + ": required file is missing");
  EXPECT_THROW(read_dataset(dir.file("nowhere"), BadRowPolicy::kSkip), DatasetError);
}

TEST(DatasetValidation, MissingValue) {
  expect_bad_odometer_row("0.7,,1", "pulses", "column 'pulses': missing value");
  expect_bad_odometer_row(",200,1", "t", "column 't': missing value");
  expect_bad_gnss_row(kFullGnssHeader, "0.5,52.5,13.4,40,1,,0,0.5,0.05,4", "vn", "missing value");
}

TEST(DatasetValidation, NonNumericIsRejectedStrictly) {
  expect_bad_odometer_row("0.7abc,200,1", "t", "column 't': not a number: '0.7abc'");
  expect_bad_odometer_row("0x1p3,200,1", "t", "column 't': not a number: '0x1p3'");
  expect_bad_odometer_row("0.7,12abc,1", "pulses", "column 'pulses': must be an integer in [0, 4294967295]: '12abc'");
  expect_bad_odometer_row("0.7,200.0,1", "pulses", "column 'pulses': must be an integer in [0, 4294967295]: '200.0'");
  expect_bad_odometer_row("0.7,2e2,1", "pulses", "column 'pulses': must be an integer in [0, 4294967295]: '2e2'");
  // A decimal comma (a locale's idea of a number) is not a number here.
  expect_bad_gnss_row(kFullGnssHeader, "0.5,52.5,13.4,40,1,2,0,0.5,0.05,4x", "fix", "must be an integer 0..9: '4x'");
  expect_bad_gnss_row(kFullGnssHeader, "0.5,52.5,13.4,4O,1,2,0,0.5,0.05,4", "height_m", "not a number: '4O'");
}

TEST(DatasetValidation, NaNIsRejected) {
  expect_bad_odometer_row("nan,200,1", "t", "column 't': NaN or infinity is not allowed: 'nan'");
  expect_bad_gnss_row(kFullGnssHeader, "0.5,52.5,13.4,40,1,2,NaN,0.5,0.05,4", "vu",
                      "NaN or infinity is not allowed: 'NaN'");
}

TEST(DatasetValidation, InfinityIsRejected) {
  expect_bad_gnss_row(kFullGnssHeader, "0.5,52.5,13.4,40,inf,2,0,0.5,0.05,4", "ve",
                      "NaN or infinity is not allowed: 'inf'");
  expect_bad_gnss_row(kFullGnssHeader, "0.5,52.5,13.4,-Infinity,1,2,0,0.5,0.05,4", "height_m",
                      "NaN or infinity is not allowed: '-Infinity'");
  expect_bad_gnss_row(kFullGnssHeader, "0.5,52.5,13.4,1e999,1,2,0,0.5,0.05,4", "height_m",
                      "number out of range of a double: '1e999'");
}

TEST(DatasetValidation, TimeEqualToThePreviousIsRejected) {
  expect_bad_odometer_row("0.5,200,1", "t", "column 't': t does not increase: 0.5 after 0.5 (line 3)");
}

TEST(DatasetValidation, TimeGoingBackIsRejected) {
  expect_bad_odometer_row("0.25,200,1", "t", "column 't': t does not increase: 0.25 after 0.5 (line 3)");
}

TEST(DatasetValidation, TimeBeyondAStampIsRejected) {
  // A DDS stamp holds int32 seconds: a later row beyond it is a bad row, not an error in processing.
  expect_bad_odometer_row("3.3333333333333335e+116,200,1", "t",
                          "column 't': t 3.3333333333333335e+116 s is beyond what a DDS stamp carries (int32 seconds, "
                          "-2147483648 to 2147483647 s: UNIX time up to 2038-01-19)");
  expect_bad_odometer_row("4102444800,200,1", "t",  // UNIX time in 2100
                          "column 't': t 4102444800 s is beyond what a DDS stamp carries (int32 seconds, "
                          "-2147483648 to 2147483647 s: UNIX time up to 2038-01-19)");
}

TEST(DatasetValidation, SkippedRowsDoNotBecomeTheTimeReference) {
  // Line 4 jumps ahead to 9 but is bad (pulses); the reference stays 0.5 (line 3), so 1.0 is good.
  // Line 6 goes back to 0.9: bad against the last good t = 1.0 (line 5).
  ScratchDir dir;
  dir.write("gnss.csv", kGoodGnss);
  dir.write("odometer.csv", "t,pulses,direction\n0.0,100,1\n0.5,180,1\n9.0,x,1\n1.0,260,1\n0.9,270,1\n1.5,300,1\n");
  DatasetReadReport report;
  const Dataset ds = read_dataset(dir.str(), BadRowPolicy::kSkip, &report);
  ASSERT_EQ(ds.odometer.size(), 4u);
  EXPECT_EQ(ds.odometer[2].t_s, 1.0);
  EXPECT_EQ(ds.odometer[3].t_s, 1.5);
  ASSERT_EQ(report.bad_rows.size(), 2u);
  EXPECT_EQ(report.bad_rows[0].line, 4u);
  EXPECT_EQ(report.bad_rows[1].message(),
            dir.file("odometer.csv") + ":6: column 't': t does not increase: 0.9 after 1 (line 5)");
}

TEST(DatasetValidation, PulsesOutOfRange) {
  expect_bad_odometer_row("0.7,4294967296,1", "pulses",
                          "column 'pulses': must be an integer in [0, 4294967295]: '4294967296'");
  expect_bad_odometer_row("0.7,-1,1", "pulses", "column 'pulses': must be an integer in [0, 4294967295]: '-1'");
  expect_bad_odometer_row("0.7,99999999999999999999999,1", "pulses",
                          "column 'pulses': must be an integer in [0, 4294967295]: '99999999999999999999999'");
}

TEST(DatasetValidation, WrappedCounterIsNotAnError) {
  ScratchDir dir;
  dir.write("gnss.csv", kGoodGnss);
  dir.write("odometer.csv", "t,pulses\n0.0,4294967295\n0.1,0\n0.2,4294967295\n");  // +1, then -1 (a reversal)
  DatasetReadReport report;
  const Dataset ds = read_dataset(dir.str(), BadRowPolicy::kFail, &report);
  EXPECT_EQ(report.total_bad(), 0u);
  ASSERT_EQ(ds.odometer.size(), 3u);
  EXPECT_EQ(ds.odometer[0].pulses, 4294967295u);
  EXPECT_EQ(ds.odometer[1].direction, 1);  // absent column: forward
  EXPECT_EQ(pulse_increment(ds.odometer[0].pulses, ds.odometer[1].pulses), 1u);
  EXPECT_EQ(static_cast<int32_t>(pulse_increment(ds.odometer[1].pulses, ds.odometer[2].pulses)), -1);
}

TEST(DatasetValidation, TruncatedLastLine) {
  // The recorder died mid-line: no newline at the end, fewer fields than the header.
  ScratchDir dir;
  dir.write("gnss.csv", kGoodGnss);
  dir.write("odometer.csv", "t,pulses,direction\n0.0,100,1\n0.5,180,1\n1.0,26");
  EXPECT_EQ(fail_message(dir),
            dir.file("odometer.csv") + ":4: column 'direction': missing value: the row has 2 fields, the header 3");
  DatasetReadReport report;
  const Dataset ds = read_dataset(dir.str(), BadRowPolicy::kSkip, &report);
  EXPECT_EQ(ds.odometer.size(), 2u);
  EXPECT_EQ(report.files[0].rows_bad, 1u);
  // A complete last line without the trailing newline is a good row.
  dir.write("odometer.csv", "t,pulses,direction\n0.0,100,1\n0.5,180,1\n1.0,260,1");
  EXPECT_EQ(read_dataset(dir.str(), BadRowPolicy::kFail).odometer.size(), 3u);
}

TEST(DatasetValidation, TooManyFields) {
  expect_bad_odometer_row("0.7,200,1,5", "", "the row has 4 fields, the header 3");
}

TEST(DatasetValidation, BadDirection) {
  expect_bad_odometer_row("0.7,200,2", "direction", "column 'direction': must be -1, 0 or 1: '2'");
  expect_bad_odometer_row("0.7,200,1.0", "direction", "column 'direction': must be -1, 0 or 1: '1.0'");
}

TEST(DatasetValidation, GnssRangesFixAndStandardDeviations) {
  expect_bad_gnss_row(kFullGnssHeader, "0.5,90.001,13.4,40,1,2,0,0.5,0.05,4", "lat_deg",
                      "latitude outside [-90, 90]: '90.001'");
  expect_bad_gnss_row(kFullGnssHeader, "0.5,52.5,-180.5,40,1,2,0,0.5,0.05,4", "lon_deg",
                      "longitude outside [-180, 180]: '-180.5'");
  expect_bad_gnss_row(kFullGnssHeader, "0.5,52.5,13.4,40,1,2,0,0.5,0.05,10", "fix", "must be an integer 0..9: '10'");
  expect_bad_gnss_row(kFullGnssHeader, "0.5,52.5,13.4,40,1,2,0,0.5,0.05,-1", "fix", "must be an integer 0..9: '-1'");
  expect_bad_gnss_row(kFullGnssHeader, "0.5,52.5,13.4,40,1,2,0,-0.5,0.05,4", "pos_std_m",
                      "negative standard deviation: '-0.5'");
  expect_bad_gnss_row(kFullGnssHeader, "0.5,52.5,13.4,40,1,2,0,0.5,-0.01,4", "vel_std_mps",
                      "negative standard deviation: '-0.01'");
  // The limits themselves are valid, and empty optional fields read as absent / default.
  DatasetDir d("gnss.csv", kFullGnssHeader + "\n0,90,180,0,0,0,0,,,\n1,-90,-180,0,0,0,0,0,0,0\n");
  const Dataset ds = read_dataset(d.dir.str(), BadRowPolicy::kFail);
  EXPECT_EQ(ds.gnss[0].position.lat_rad, deg_to_rad(90.0));
  EXPECT_EQ(ds.gnss[1].position.lon_rad, deg_to_rad(-180.0));
  EXPECT_EQ(ds.gnss[0].position.lon_rad, deg_to_rad(-180.0));  // 180 is the same meridian: read as -180
  EXPECT_FALSE(ds.gnss[0].pos_std_m.has_value());
  EXPECT_EQ(ds.gnss[0].fix, 1);
  EXPECT_EQ(ds.gnss[1].fix, 0);
  EXPECT_FALSE(ds.gnss[1].valid());
}

TEST(DatasetValidation, InsRowsAndVelocityGroup) {
  ScratchDir dir;
  dir.write("odometer.csv", kGoodOdometer);
  dir.write("gnss.csv", kGoodGnss);
  dir.write(
      "ins.csv",
      "t,heading_deg,pitch_deg,roll_deg,ve,vn,vu\n0,10,1,2,,,\n0.1,10,91,2,,,\n0.2,10,1,2,1,,3\n0.3,350,-2,-3,1,2,3\n");
  EXPECT_EQ(fail_message(dir), dir.file("ins.csv") + ":3: column 'pitch_deg': pitch outside [-90, 90]: '91'");
  DatasetReadReport report;
  const Dataset ds = read_dataset(dir.str(), BadRowPolicy::kSkip, &report);
  ASSERT_EQ(ds.ins.size(), 2u);
  EXPECT_FALSE(ds.ins[0].vel_enu_mps.has_value());
  EXPECT_EQ(*ds.ins[1].vel_enu_mps, Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(ds.ins[1].attitude.heading_rad, deg_to_rad(350.0));
  ASSERT_EQ(report.bad_rows.size(), 2u);
  EXPECT_EQ(report.bad_rows[1].message(), dir.file("ins.csv") + ":4: column 'vn': missing value");
  // Only some of the velocity columns in the header: a file error.
  dir.write("ins.csv", "t,heading_deg,pitch_deg,roll_deg,ve\n0,10,1,2,1\n");
  EXPECT_EQ(fail_message(dir),
            dir.file("ins.csv") + ": the velocity columns ve, vn, vu must be all present or all absent");
}

TEST(DatasetValidation, MalformedMetaJson) {
  DatasetDir d("meta.json", "{\n  \"vehicle_id\": \"v1\",\n  \"odometer\": {\"k_nominal_m_per_pulse\": 0.0125,}\n}\n");
  // The stray '}' after the trailing comma: line 3 is `  "odometer": {"k_nominal_m_per_pulse": 0.0125,}`,
  // the '}' its 48th character; lines 1 and 2 hold 2 + 22 bytes, so it is byte 24 + 48 = 72.
  const std::string message = fail_message(d.dir);
  EXPECT_EQ(message.rfind(d.dir.file("meta.json") + ": malformed JSON (byte 72): ", 0), 0u) << message;
  EXPECT_NE(message.find("line 3, column 48"), std::string::npos) << message;
  // Malformed JSON is not a row: skip does not excuse it.
  EXPECT_THROW(read_dataset(d.dir.str(), BadRowPolicy::kSkip), DatasetError);
  // A known key of the wrong type is named.
  d.dir.write("meta.json", R"({"odometer": {"k_nominal_m_per_pulse": "0.0125"}})");
  EXPECT_EQ(fail_message(d.dir), d.dir.file("meta.json") + ": key 'odometer.k_nominal_m_per_pulse' must be a number");
}

TEST(DatasetValidation, MetaJsonKnownAndUnknownKeys) {
  const std::string text = R"({"format": "odonav-dataset/1", "vehicle_id": "vehicle-01", "description": "ring",
    "odometer": {"k_nominal_m_per_pulse": 0.0125}, "truth": {"misalignment_heading_deg": 0.8,
    "misalignment_pitch_deg": -0.5}, "weather": "rain"})";
  DatasetDir d("meta.json", text);
  const Dataset ds = read_dataset(d.dir.str(), BadRowPolicy::kFail);
  EXPECT_EQ(ds.meta.vehicle_id, "vehicle-01");
  EXPECT_EQ(ds.meta.description, "ring");
  EXPECT_EQ(ds.meta.k_nominal_m_per_pulse, 0.0125);
  EXPECT_EQ(ds.meta.truth_misalignment_heading_deg, 0.8);
  EXPECT_EQ(ds.meta.truth_misalignment_pitch_deg, -0.5);
  EXPECT_EQ(ds.meta.raw_json, text);
}

TEST(DatasetValidation, HeaderOnlyFiles) {
  // An optional file with only a header is valid and empty; a required one cannot be used.
  DatasetDir d("ins.csv", "t,heading_deg,pitch_deg,roll_deg\n");
  const Dataset ds = read_dataset(d.dir.str(), BadRowPolicy::kFail);
  EXPECT_FALSE(ds.has_ins());
  d.dir.write("odometer.csv", "# no data\nt,pulses,direction\n");
  EXPECT_EQ(fail_message(d.dir), d.dir.file("odometer.csv") + ": 0 good row(s), at least 2 are needed");
  // Under skip, bad rows that leave fewer than two good ones say so.
  d.dir.write("odometer.csv", "t,pulses,direction\n0,1,1\n1,x,1\n");
  try {
    read_dataset(d.dir.str(), BadRowPolicy::kSkip, nullptr);
    FAIL() << "no error";
  } catch (const DatasetError& e) {
    EXPECT_EQ(std::string(e.what()), d.dir.file("odometer.csv") + ": 1 good row(s), at least 2 are needed");
  }
  d.dir.write("odometer.csv", "");
  EXPECT_EQ(fail_message(d.dir),
            d.dir.file("odometer.csv") + ": no header line (the file is empty or holds only comments)");
}

TEST(DatasetValidation, HeaderProblems) {
  DatasetDir d("odometer.csv", "t,pulses,t\n0,1,0\n1,2,1\n");
  EXPECT_EQ(fail_message(d.dir), d.dir.file("odometer.csv") + ":1: column 't' appears twice in the header");
  d.dir.write("odometer.csv", "t,,pulses\n0,1,0\n1,2,1\n");
  EXPECT_EQ(fail_message(d.dir), d.dir.file("odometer.csv") + ":1: empty column name in the header at position 2");
}

TEST(DatasetValidation, CommentsBlankLinesCrlfAndBom) {
  // Line numbers count comment and blank lines; CRLF and a byte-order mark are tolerated.
  ScratchDir dir;
  dir.write("gnss.csv", kGoodGnss);
  dir.write(
      "odometer.csv",
      "\xEF\xBB\xBF# recorded 2024-06-11\r\nt,pulses,direction\r\n\r\n0.0,100,1\r\n# pause\r\n   \r\n0.5,180,-1\r\n1.0,abc,1\r\n");
  EXPECT_EQ(fail_message(dir),
            dir.file("odometer.csv") + ":8: column 'pulses': must be an integer in [0, 4294967295]: 'abc'");
  const Dataset ds = read_dataset(dir.str(), BadRowPolicy::kSkip);
  ASSERT_EQ(ds.odometer.size(), 2u);
  EXPECT_EQ(ds.odometer[1].direction, -1);
  EXPECT_EQ(ds.odometer[1].t_s, 0.5);
}

TEST(DatasetValidation, UnknownColumnsAreIgnoredAndReportedOnce) {
  auto sink = std::make_shared<spdlog::sinks::ringbuffer_sink_mt>(100);
  auto previous = spdlog::default_logger();
  spdlog::set_default_logger(std::make_shared<spdlog::logger>("capture", sink));
  ScratchDir dir;
  dir.write("gnss.csv", kGoodGnss);
  dir.write("odometer.csv", "t,temperature_c,pulses,note\n0.0,21.5,100,a\n0.5,21.6,180,b\n1.0,21.7,260,c\n");
  DatasetReadReport report;
  const Dataset ds = read_dataset(dir.str(), BadRowPolicy::kFail, &report);
  spdlog::set_default_logger(previous);
  ASSERT_EQ(ds.odometer.size(), 3u);
  EXPECT_EQ(ds.odometer[2].pulses, 260u);
  EXPECT_EQ(report.files[0].ignored_columns, (std::vector<std::string>{"temperature_c", "note"}));
  EXPECT_TRUE(report.files[1].ignored_columns.empty());
  const std::vector<std::string> lines = sink->last_formatted();
  int warnings_naming_them = 0;
  for (const std::string& line : lines) {
    if (line.find("'temperature_c', 'note'") != std::string::npos) ++warnings_naming_them;
  }
  EXPECT_EQ(warnings_naming_them, 1);
  EXPECT_EQ(lines.size(), 1u);
}

TEST(DatasetValidation, ReorderedColumnsReadTheSame) {
  ScratchDir a, b;
  a.write("odometer.csv", kGoodOdometer);
  a.write("gnss.csv", kFullGnssHeader + "\n0,52.5,13.4,40,1,2,0.1,0.5,0.05,4\n1,52.6,13.5,41,3,4,0.2,,0.06,5\n");
  b.write("odometer.csv", "direction,pulses,t\n1,100,0.0\n1,180,0.5\n1,260,1.0\n");
  b.write("gnss.csv",
          "fix,vu,vn,ve,vel_std_mps,pos_std_m,height_m,lon_deg,lat_deg,t\n"
          "4,0.1,2,1,0.05,0.5,40,13.4,52.5,0\n5,0.2,4,3,0.06,,41,13.5,52.6,1\n");
  const Dataset x = read_dataset(a.str(), BadRowPolicy::kFail), y = read_dataset(b.str(), BadRowPolicy::kFail);
  ASSERT_EQ(x.odometer.size(), y.odometer.size());
  for (std::size_t i = 0; i < x.odometer.size(); ++i) {
    EXPECT_EQ(x.odometer[i].t_s, y.odometer[i].t_s);
    EXPECT_EQ(x.odometer[i].pulses, y.odometer[i].pulses);
  }
  ASSERT_EQ(x.gnss.size(), 2u);
  ASSERT_EQ(y.gnss.size(), 2u);
  for (std::size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(x.gnss[i].position.lat_rad, y.gnss[i].position.lat_rad);
    EXPECT_EQ(x.gnss[i].position.lon_rad, y.gnss[i].position.lon_rad);
    EXPECT_EQ(x.gnss[i].vel_enu_mps, y.gnss[i].vel_enu_mps);
    EXPECT_EQ(x.gnss[i].pos_std_m, y.gnss[i].pos_std_m);
    EXPECT_EQ(x.gnss[i].vel_std_mps, y.gnss[i].vel_std_mps);
    EXPECT_EQ(x.gnss[i].fix, y.gnss[i].fix);
  }
  EXPECT_EQ(y.gnss[1].vel_enu_mps, Eigen::Vector3d(3, 4, 0.2));
  EXPECT_EQ(y.gnss[1].position.lat_rad, deg_to_rad(52.6));
  EXPECT_FALSE(y.gnss[1].pos_std_m.has_value());
}

TEST(DatasetValidation, SkipCountsEveryKindAndKeepsEveryGoodRow) {
  // 10 data rows, 6 bad of different kinds; the 4 good ones are kept in order.
  ScratchDir dir;
  dir.write("gnss.csv", kGoodGnss);
  dir.write("odometer.csv",
            "t,pulses,direction\n"
            "0.0,100,1\n"    // good
            "0.1,,1\n"       // missing value
            "0.2,x,1\n"      // non-numeric
            "nan,120,1\n"    // NaN
            "0.3,130,1\n"    // good
            "0.3,140,1\n"    // t equal
            "0.4,-5,1\n"     // negative pulses
            "0.5,150,7\n"    // bad direction
            "0.6,160,1\n"    // good
            "0.7,170,1\n");  // good
  DatasetReadReport report;
  const Dataset ds = read_dataset(dir.str(), BadRowPolicy::kSkip, &report);
  ASSERT_EQ(ds.odometer.size(), 4u);
  const uint32_t expected_pulses[] = {100, 130, 160, 170};
  for (int i = 0; i < 4; ++i) EXPECT_EQ(ds.odometer[i].pulses, expected_pulses[i]);
  EXPECT_EQ(report.files[0].rows_read, 4u);
  EXPECT_EQ(report.files[0].rows_bad, 6u);
  EXPECT_EQ(report.files[1].rows_bad, 0u);
  EXPECT_EQ(report.total_bad(), 6u);
  std::vector<std::size_t> lines;
  for (const BadRow& r : report.bad_rows) lines.push_back(r.line);
  EXPECT_EQ(lines, (std::vector<std::size_t>{3, 4, 5, 7, 8, 9}));
}

TEST(DatasetValidation, DetailIsCappedAtOneHundredButCountsAreNot) {
  ScratchDir dir;
  dir.write("gnss.csv", kGoodGnss);
  std::string text = "t,pulses\n0,0\n";
  for (int i = 1; i <= 250; ++i) text += std::to_string(i) + (i % 2 ? ",bad\n" : ",5\n");
  dir.write("odometer.csv", text);
  DatasetReadReport report;
  const Dataset ds = read_dataset(dir.str(), BadRowPolicy::kSkip, &report);
  EXPECT_EQ(ds.odometer.size(), 126u);
  EXPECT_EQ(report.total_bad(), 125u);
  EXPECT_EQ(report.bad_rows.size(), 100u);
}

TEST(DatasetValidation, BadRowPolicyNames) {
  EXPECT_EQ(parse_bad_row_policy("fail"), BadRowPolicy::kFail);
  EXPECT_EQ(parse_bad_row_policy("skip"), BadRowPolicy::kSkip);
  try {
    parse_bad_row_policy("ignore");
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()), "bad-row policy 'ignore': must be fail or skip");
  }
}

TEST(DatasetValidation, SmartLocBerlinReadsWithoutBadRows) {
  const std::string dir = ODONAV_SOURCE_DIR "/tests/data/smartloc-berlin";
  ASSERT_TRUE(std::filesystem::is_directory(dir)) << dir << " is part of the repository";
  DatasetReadReport report;
  const Dataset ds = read_dataset(dir, BadRowPolicy::kFail, &report);
  EXPECT_EQ(report.total_bad(), 0u);
  EXPECT_EQ(ds.odometer.size(), 1372u);
  EXPECT_EQ(ds.gnss.size(), 1372u);
  EXPECT_EQ(ds.ins.size(), 1372u);
  EXPECT_EQ(ds.meta.vehicle_id, "smartloc-berlin");
  // First GNSS row, checked against the file's text.
  EXPECT_EQ(ds.gnss[0].position.lat_rad, deg_to_rad(52.5045700668));
  EXPECT_EQ(ds.gnss[0].fix, 4);
  EXPECT_EQ(ds.odometer[1].pulses, 89u);
}
