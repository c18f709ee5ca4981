// The time-unit check of the dataset parser (docs/DATASET.md, "Time unit"): t in nanoseconds,
// microseconds or milliseconds (since 1970, or since the start at a low rate) is refused naming
// file, line, value and the unit it looks like, under either policy, by read_dataset and
// DatasetStream alike; seconds, UNIX seconds included, keep working.
#include <gtest/gtest.h>

#include <cstdio>
#include <functional>
#include <string>

#include "scratch_dir.hpp"
#include "odonav/dataset.hpp"
#include "odonav/dataset_stream.hpp"

using namespace odonav;
using odonav::test::ScratchDir;

namespace {

// `rows` data rows of a file, row i built by `row(i)`, after `header`.
std::string table(const std::string& header, int rows, const std::function<std::string(int)>& row) {
  std::string text = header + "\n";
  for (int i = 0; i < rows; ++i) text += row(i) + "\n";
  return text;
}
std::string odometer(int rows, const std::function<std::string(int)>& t) {
  return table("t,pulses,direction", rows, [&](int i) { return t(i) + "," + std::to_string(100 + 8 * i) + ",1"; });
}
std::string gnss(int rows, const std::function<std::string(int)>& t) {
  return table("t,lat_deg,lon_deg,height_m,ve,vn,vu", rows, [&](int i) { return t(i) + ",52.5,13.4,40,1,2,0"; });
}
std::string ins(int rows, const std::function<std::string(int)>& t) {
  return table("t,heading_deg,pitch_deg,roll_deg", rows, [&](int i) { return t(i) + ",10,0,0"; });
}
// t in seconds from `t0_s` in steps of `step_s`, printed in fixed notation with centiseconds.
std::function<std::string(int)> seconds(double t0_s, double step_s) {
  return [=](int i) {
    char text[64];
    std::snprintf(text, sizeof text, "%.2f", t0_s + i * step_s);
    return std::string(text);
  };
}
// An integer count `first + i * step` (stamps in ns, us or ms).
std::function<std::string(int)> count(long long first, long long step) {
  return [=](int i) { return std::to_string(first + i * step); };
}

// A dataset of 20 s with 10 Hz odometer and 1 Hz GNSS in seconds; then `file` replaced by `content`.
struct Dataset20s {
  ScratchDir dir;
  Dataset20s(const std::string& file, const std::string& content) {
    dir.write("odometer.csv", odometer(200, seconds(0.0, 0.1)));
    dir.write("gnss.csv", gnss(20, seconds(0.0, 1.0)));
    dir.write(file, content);
  }
};

std::string read_error(const std::string& dir, BadRowPolicy policy) {
  try {
    read_dataset(dir, policy);
  } catch (const DatasetError& e) {
    return e.what();
  }
  return "";
}
std::string stream_error(const std::string& dir, BadRowPolicy policy) {
  try {
    DatasetStream stream(dir, policy);
    while (stream.next()) {
    }
    TruthStream truth(dir, policy);
    while (truth.next()) {
    }
  } catch (const DatasetError& e) {
    return e.what();
  }
  return "";
}

// The dataset is refused with exactly `expected` by read_dataset and DatasetStream under both policies.
void expect_refused(const std::string& dir, const std::string& expected) {
  for (BadRowPolicy policy : {BadRowPolicy::kFail, BadRowPolicy::kSkip}) {
    SCOPED_TRACE(policy == BadRowPolicy::kFail ? "fail" : "skip");
    EXPECT_EQ(read_error(dir, policy), expected);
    EXPECT_EQ(stream_error(dir, policy), expected);
  }
}

}  // namespace

TEST(DatasetTimeUnit, NanosecondsSince1970AreRefusedAtTheFirstRow) {
  // What a ROS bag exported to CSV gives: 100 Hz in ns since 1970.
  Dataset20s d("odometer.csv", odometer(200, count(1700000000000000000LL, 10000000LL)));
  expect_refused(d.dir.str(), d.dir.file("odometer.csv") +
                                  ":2: column 't': 1700000000000000000 looks like nanoseconds since 1970; odonav "
                                  "expects seconds (docs/DATASET.md)");
}

TEST(DatasetTimeUnit, MicrosecondsSince1970AreRefused) {
  Dataset20s d("gnss.csv", "# exported from a logger\n" + gnss(20, count(1700000000000000LL, 1000000LL)));
  expect_refused(d.dir.str(), d.dir.file("gnss.csv") +
                                  ":3: column 't': 1700000000000000 looks like microseconds since 1970; odonav "
                                  "expects seconds (docs/DATASET.md)");
}

TEST(DatasetTimeUnit, MillisecondsSince1970AreRefusedInAnyFileTruthIncluded) {
  Dataset20s d("ins.csv", ins(200, count(1700000000000LL, 10)));
  expect_refused(d.dir.str(), d.dir.file("ins.csv") +
                                  ":2: column 't': 1700000000000 looks like milliseconds since 1970; odonav "
                                  "expects seconds (docs/DATASET.md)");
  Dataset20s t("truth.csv", "t,k_true\n1700000000000.5,0.0125\n1700000000010.5,0.0125\n");
  expect_refused(t.dir.str(), t.dir.file("truth.csv") +
                                  ":2: column 't': 1700000000000.5 looks like milliseconds since 1970; odonav "
                                  "expects seconds (docs/DATASET.md)");
}

TEST(DatasetTimeUnit, StampsSinceTheStartAreJudgedByTheirMedianStep) {
  // 1 Hz GNSS in ms since the start: steps of 1000.
  Dataset20s g("gnss.csv", gnss(20, count(0, 1000)));
  expect_refused(g.dir.str(), g.dir.file("gnss.csv") +
                                  ":2: column 't': 0 then steps of 1000 (the median of the first 8 rows) look like "
                                  "milliseconds; odonav expects seconds (docs/DATASET.md)");
  // 100 Hz odometer in us since the start, one gap among the first rows: the median ignores it.
  Dataset20s o("odometer.csv",
               odometer(200, [](int i) { return std::to_string(5000000LL + i * 10000LL + (i >= 3 ? 7000000LL : 0)); }));
  expect_refused(o.dir.str(), o.dir.file("odometer.csv") +
                                  ":2: column 't': 5000000 then steps of 10000 (the median of the first 8 rows) "
                                  "look like microseconds; odonav expects seconds (docs/DATASET.md)");
  // 100 Hz INS in ns since the start.
  Dataset20s n("ins.csv", ins(200, count(0, 10000000LL)));
  expect_refused(n.dir.str(), n.dir.file("ins.csv") +
                                  ":2: column 't': 0 then steps of 1e7 (the median of the first 8 rows) look like "
                                  "nanoseconds; odonav expects seconds (docs/DATASET.md)");
}

TEST(DatasetTimeUnit, SecondsKeepWorkingUnixTimeIncluded) {
  // UNIX seconds (2023, and 2038 close to the int32 end of a DDS stamp) at 100 Hz and 1 Hz, GPS
  // time of week, and the row values read exactly.
  for (double t0_s : {1700000000.0, 2147000000.0, 518400.0, 0.0}) {
    SCOPED_TRACE(t0_s);
    ScratchDir dir;
    dir.write("odometer.csv", odometer(2000, seconds(t0_s, 0.01)));
    dir.write("gnss.csv", gnss(20, seconds(t0_s, 1.0)));
    dir.write("ins.csv", ins(2000, seconds(t0_s, 0.01)));
    dir.write("truth.csv", "t,k_true\n" + seconds(t0_s, 1.0)(0) + ",0.0125\n");
    const Dataset ds = read_dataset(dir.str(), BadRowPolicy::kFail);
    ASSERT_EQ(ds.odometer.size(), 2000u);
    EXPECT_EQ(ds.odometer[1999].t_s, std::stod(seconds(t0_s, 0.01)(1999)));
    EXPECT_EQ(stream_error(dir.str(), BadRowPolicy::kFail), "");
  }
  // Sparse but plausible: a GNSS file of a few rows far apart, truth points 5000 s apart.
  Dataset20s sparse("gnss.csv", gnss(3, seconds(0.0, 10000.0)));
  sparse.dir.write("truth.csv", table("t,k_true", 10, [](int i) { return std::to_string(i * 5000) + ",0.0125"; }));
  EXPECT_EQ(read_error(sparse.dir.str(), BadRowPolicy::kFail), "");
  EXPECT_EQ(stream_error(sparse.dir.str(), BadRowPolicy::kFail), "");
}
