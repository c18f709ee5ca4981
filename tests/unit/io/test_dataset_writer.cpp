// DatasetWriter, the row-by-row dataset writer: a refused value names file, row and column and
// leaves no file of the dataset under its real name (nor temporaries once the writer is gone); the
// columns it was told about are the columns it writes; its memory does not grow with the rows.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include "error_of.hpp"
#include "scratch_dir.hpp"
#include "odonav/dataset.hpp"
#include "odonav/dataset_writer.hpp"

using namespace odonav;
using odonav::test::ScratchDir;
using odonav::test::error_of;

namespace {

const char* const kDatasetFiles[] = {"odometer.csv", "gnss.csv", "ins.csv", "truth.csv", "meta.json"};

using odonav::test::read_text;

// Every entry of the directory except the output marker.
std::vector<std::string> entries(const std::string& dir) {
  std::vector<std::string> names;
  for (const auto& e : std::filesystem::directory_iterator(dir)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

DatasetWriterOptions every_file() {
  DatasetWriterOptions o;
  o.gnss_pos_std_m = true;
  o.gnss_vel_std_mps = true;
  o.ins = true;
  o.truth = true;
  return o;
}

GnssSample gnss_at(double t_s) {
  GnssSample g;
  g.t_s = t_s;
  g.position = Geodetic{deg_to_rad(52.5), deg_to_rad(13.4), 80.0};
  g.pos_std_m = 1.5;
  g.vel_std_mps = 0.05;
  return g;
}

TruthSample truth_at(double t_s) {
  TruthSample s;
  s.t_s = t_s;
  s.position = Geodetic{deg_to_rad(52.5), deg_to_rad(13.4), 80.0};
  s.attitude = Attitude{0.1, 0.01, -0.02};
  s.k_true_m_per_pulse = 0.0125;
  s.distance_m = 10.0 * t_s;
  return s;
}

}  // namespace

TEST(DatasetWriter, BadValueNamesFileRowAndColumnAndLeavesNoDatasetFile) {
  ScratchDir dir;
  {
    DatasetWriter writer(dir.str(), every_file());
    for (int i = 0; i < 5; ++i) {
      writer.add(OdometerSample{0.1 * i, static_cast<uint32_t>(i), 1});
      writer.add(InsSample{0.1 * i, Attitude{0.0, 0.0, 0.0}, std::nullopt});
      writer.add(truth_at(0.1 * i));
    }
    writer.add(gnss_at(0.0));
    writer.add(gnss_at(0.1));
    GnssSample bad = gnss_at(0.2);
    bad.position.lat_rad = deg_to_rad(95.0);
    EXPECT_EQ(error_of<DatasetError>([&] { writer.add(bad); }),
              dir.file("gnss.csv") + ": cannot write row 3: column 'lat_deg' is outside [-90, 90] deg");
    // While the writer exists its rows are in temporaries, never under a real name.
    for (const char* name : kDatasetFiles) EXPECT_FALSE(std::filesystem::exists(dir.file(name))) << name;
    // A failed writer writes nothing more.
    EXPECT_THROW(writer.add(gnss_at(0.3)), std::logic_error);
    EXPECT_THROW(writer.finish(DatasetMeta{}), std::logic_error);
  }
  EXPECT_TRUE(entries(dir.str()).empty());  // the temporaries went with the writer

  // A non-finite value in truth.csv, row 2.
  DatasetWriter writer(dir.str(), every_file());
  writer.add(truth_at(0.0));
  TruthSample nan_height = truth_at(0.1);
  nan_height.k_true_m_per_pulse = std::numeric_limits<double>::infinity();
  EXPECT_EQ(error_of<DatasetError>([&] { writer.add(nan_height); }),
            dir.file("truth.csv") + ": cannot write row 2: column 'k_true' is not finite (inf)");
}

TEST(DatasetWriter, AFailedWriterLeavesAnEarlierDatasetAsItWas) {
  ScratchDir dir;
  Dataset old;
  old.odometer = {OdometerSample{0.0, 0, 1}, OdometerSample{0.1, 3, 1}};
  old.gnss = {gnss_at(0.0), gnss_at(1.0)};
  write_dataset(dir.str(), old);
  const std::string odometer_before = read_text(dir.file("odometer.csv"));
  const std::string gnss_before = read_text(dir.file("gnss.csv"));
  const std::string meta_before = read_text(dir.file("meta.json"));
  {
    DatasetWriter writer(dir.str(), every_file());
    writer.add(OdometerSample{5.0, 7, 1});
    writer.add(gnss_at(5.0));
    DatasetMeta bad_meta;
    bad_meta.k_nominal_m_per_pulse = std::nan("");
    EXPECT_THROW(writer.finish(bad_meta), DatasetError);  // refused before any rename
  }
  EXPECT_EQ(read_text(dir.file("odometer.csv")), odometer_before);
  EXPECT_EQ(read_text(dir.file("gnss.csv")), gnss_before);
  EXPECT_EQ(read_text(dir.file("meta.json")), meta_before);
  EXPECT_FALSE(std::filesystem::exists(dir.file("ins.csv")));
  EXPECT_FALSE(std::filesystem::exists(dir.file("truth.csv")));
}

TEST(DatasetWriter, WritesTheColumnsItWasToldAndRefusesValuesForOthers) {
  ScratchDir dir;
  DatasetWriterOptions o;  // no optional column, no ins.csv, truth.csv with three columns
  o.truth = true;
  o.truth_columns = TruthColumns{false, false, false, true, false, false, true, false};
  DatasetWriter writer(dir.str(), o);
  writer.add(OdometerSample{0.0, 0, 1});
  GnssSample g = gnss_at(0.0);
  g.pos_std_m.reset();
  g.vel_std_mps.reset();
  writer.add(g);
  TruthSample t;  // every value absent (NaN) but the two columns asked for
  t.t_s = 0.0;
  t.attitude.heading_rad = deg_to_rad(90.0);
  t.k_true_m_per_pulse = 0.0125;
  writer.add(t);
  // A value the file has no column for would be lost: refused, naming the column.
  g.t_s = 0.1;
  g.pos_std_m = 2.0;
  const std::string pos_std_error = error_of<DatasetError>([&] {
    DatasetWriter other(dir.str() + "/other", o);
    other.add(g);
  });
  EXPECT_NE(pos_std_error.find("gnss.csv: cannot write row 1: column 'pos_std_m'"), std::string::npos) << pos_std_error;
  const std::string ins_error = error_of<DatasetError>([&] {
    DatasetWriter other(dir.str() + "/other", o);
    other.add(InsSample{});
  });
  EXPECT_NE(ins_error.find("ins.csv"), std::string::npos) << ins_error;
  writer.finish(DatasetMeta{});
  EXPECT_EQ(read_text(dir.file("gnss.csv")), "t,lat_deg,lon_deg,height_m,ve,vn,vu,fix\n0,52.5,13.4,80,0,0,0,1\n");
  EXPECT_EQ(read_text(dir.file("truth.csv")), "t,heading_deg,k_true\n0,90,0.0125\n");
  EXPECT_FALSE(std::filesystem::exists(dir.file("ins.csv")));
  const DatasetRowCounts rows = writer.rows();
  EXPECT_EQ(rows.odometer, 1u);
  EXPECT_EQ(rows.gnss, 1u);
  EXPECT_EQ(rows.ins, 0u);
  EXPECT_EQ(rows.truth, 1u);
}

TEST(DatasetWriter, OptionsForADatasetAreWhatItsRowsUse) {
  Dataset d;
  d.gnss = {gnss_at(0.0), gnss_at(1.0)};
  d.gnss[0].pos_std_m.reset();
  d.gnss[1].pos_std_m.reset();
  d.gnss[0].vel_std_mps.reset();
  TruthSample t;
  t.distance_m = 3.0;
  d.truth = {t};
  const DatasetWriterOptions o = DatasetWriterOptions::for_dataset(d);
  EXPECT_FALSE(o.gnss_pos_std_m);
  EXPECT_TRUE(o.gnss_vel_std_mps);
  EXPECT_FALSE(o.ins);
  EXPECT_TRUE(o.truth);
  EXPECT_FALSE(o.truth_columns.lat_deg);
  EXPECT_TRUE(o.truth_columns.distance_m);
}

TEST(DatasetWriter, BufferDoesNotGrowWithTheRows) {
  // 200 000 rows per file (tens of MB of text): what the writer holds stays at its fixed buffers.
  ScratchDir dir;
  DatasetWriter writer(dir.str(), every_file());
  std::size_t at_half = 0, max_overall = 0;
  for (int i = 0; i < 200000; ++i) {
    const double t_s = 0.01 * i;
    writer.add(OdometerSample{t_s, static_cast<uint32_t>(4294967000u + 7u * i), 1});
    writer.add(InsSample{t_s, Attitude{0.1 + 1e-6 * i, 0.01, -0.02}, std::nullopt});
    writer.add(truth_at(t_s));
    if (i % 10 == 0) writer.add(gnss_at(t_s));
    const std::size_t bytes = writer.buffer_capacity_bytes();
    max_overall = std::max(max_overall, bytes);
    if (i == 100000) at_half = bytes;
  }
  writer.finish(DatasetMeta{});
  EXPECT_EQ(writer.rows().truth, 200000u);
  EXPECT_GT(std::filesystem::file_size(dir.file("truth.csv")), 10u * 1000 * 1000);
  // Four files, each buffer below twice the 64 KiB flush threshold plus a row.
  EXPECT_LE(max_overall, 4u * 2u * (64u * 1024u + 1024u));
  EXPECT_EQ(writer.buffer_capacity_bytes(), at_half);  // the second 100 000 rows added nothing
}
