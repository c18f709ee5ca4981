// CsvWriter, odonav's one CSV writer (output files and dataset writer): header, shortest round-trip
// numbers, empty fields for NaN and absent values, the row-width check, and the in-memory mode the
// dataset writer builds its files with.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "scratch_dir.hpp"
#include "odonav/csv_writer.hpp"

using odonav::CsvWriter;
using odonav::test::read_text;
using odonav::test::ScratchDir;

TEST(CsvWriter, WritesHeaderAndShortestRoundTripFields) {
  ScratchDir dir;
  const std::string path = dir.file("x.csv");
  CsvWriter csv(path, {"t", "k", "n", "flag", "name", "opt"});
  csv.field(0.1).field(1.0 / 3.0).field(int64_t{-42}).field(true).field("vff").field(std::optional<double>{});
  csv.end_row();
  csv.field(std::numeric_limits<double>::quiet_NaN())
      .field(1e-300)
      .field(uint64_t{18446744073709551615ull})
      .field(false)
      .field(std::string("a b"))
      .field(std::optional<double>(-0.0125));
  csv.end_row();
  EXPECT_EQ(csv.rows(), 2u);
  csv.close();
  EXPECT_EQ(read_text(path),
            "t,k,n,flag,name,opt\n"
            "0.1,0.3333333333333333,-42,1,vff,\n"
            ",1e-300,18446744073709551615,0,a b,-0.0125\n");
}

TEST(CsvWriter, EveryWrittenDoubleReadsBackToTheSameBits) {
  CsvWriter csv(CsvWriter::InMemory{}, "mem.csv", {"v"});
  const double values[] = {0.1 + 0.2, 6378137.0, 2.220446049250313e-16, -123456.789012345678, 5e-324};
  for (double v : values) {
    csv.field(v);
    csv.end_row();
  }
  std::istringstream lines(csv.text());
  std::string line;
  std::getline(lines, line);
  EXPECT_EQ(line, "v");
  for (double v : values) {
    ASSERT_TRUE(std::getline(lines, line));
    EXPECT_EQ(std::strtod(line.c_str(), nullptr), v) << line;  // strtod: stod refuses subnormals
  }
}

TEST(CsvWriter, InMemoryWriterTouchesNoFileAndHoldsTheWholeText) {
  ScratchDir dir;
  const std::string path = dir.file("never.csv");
  {
    CsvWriter csv(CsvWriter::InMemory{}, path, {"a", "b"});
    EXPECT_EQ(csv.text(), "a,b\n");
    csv.field(1).empty();
    csv.end_row();
    csv.close();  // nothing to close
    EXPECT_EQ(csv.text(), "a,b\n1,\n");
    EXPECT_EQ(csv.path(), path);
  }
  EXPECT_FALSE(std::ifstream(path).good());
}

TEST(CsvWriter, RowWithTheWrongNumberOfFieldsIsALogicError) {
  CsvWriter csv(CsvWriter::InMemory{}, "w.csv", {"a", "b", "c"});
  csv.field(1.5).field(2.5);
  try {
    csv.end_row();
    FAIL() << "no exception";
  } catch (const std::logic_error& e) {
    EXPECT_STREQ(e.what(), "w.csv: row 1 has 2 fields, header has 3");
  }
}

TEST(CsvWriter, FileWriterHasNoTextAndAMissingFolderIsNamed) {
  ScratchDir dir;
  CsvWriter csv(dir.file("f.csv"), {"a"});
  EXPECT_THROW(csv.text(), std::logic_error);
  const std::string bad = dir.file("no/such/folder/f.csv");
  try {
    CsvWriter missing(bad, {"a"});
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()).rfind(bad + ": cannot create: ", 0), 0u) << e.what();
  }
}
