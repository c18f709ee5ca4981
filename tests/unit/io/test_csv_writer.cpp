// CsvWriter, odonav's one CSV writer (output files and dataset writer): header, shortest round-trip
// numbers, empty fields for NaN and absent values, the row-width check, and the in-memory mode the
// dataset writer builds its files with.
#include <gtest/gtest.h>

#include <charconv>
#include <cmath>
#include <cstring>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>
#include <stdexcept>

#include "scratch_dir.hpp"
#include "odonav/csv_writer.hpp"
#include "odonav/shortest_double.hpp"

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

// write_shortest_double must write what std::to_chars writes, byte for byte (the outputs of odonav are
// compared to the last byte across versions): every bit pattern class, the magnitudes of positions,
// times and small errors, decimals of every digit count, powers of two and their neighbours.
TEST(ShortestDouble, WritesExactlyWhatStdToCharsWrites) {
  std::size_t checked = 0, differing = 0;
  const auto check = [&](double v) {
    char expected[64], got[odonav::kShortestDoubleMaxChars];
    char* const expected_end = std::to_chars(expected, expected + sizeof expected, v).ptr;
    char* const got_end = odonav::write_shortest_double(got, v);
    ++checked;
    const std::string a(expected, expected_end), b(got, got_end);
    if (a != b && ++differing <= 10) ADD_FAILURE() << "std::to_chars " << a << " but " << b;
  };
  std::mt19937_64 rng(7);
  for (int i = 0; i < 1000000; ++i) {
    const uint64_t bits = rng();
    double v = 0.0;
    std::memcpy(&v, &bits, sizeof v);
    check(v);
  }
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::uniform_int_distribution<int> decade(-30, 30);
  for (int i = 0; i < 1000000; ++i) check(unit(rng) * std::pow(10.0, decade(rng)));
  for (int i = 0; i < 500000; ++i) {  // decimals of 1 to 17 digits, as a parser reads them
    const int digits = static_cast<int>(rng() % 17) + 1;
    const uint64_t mantissa = rng() % static_cast<uint64_t>(std::pow(10.0, digits));
    const std::string text = std::to_string(mantissa) + "e" + std::to_string(static_cast<int>(rng() % 50) - 35);
    const double v = std::strtod(text.c_str(), nullptr);
    check(v);
    check(-v);
  }
  for (int e = -1074; e < 1024; ++e) {
    const double p = std::ldexp(1.0, e);
    check(p);
    check(std::nextafter(p, 0.0));
    check(std::nextafter(p, std::numeric_limits<double>::infinity()));
  }
  for (int i = 0; i < 200000; ++i) {
    check(i);
    check(i / 10.0);
    check(i * 0.001);
    check(i * 1e-7);
    check(-i * 1e5);
    check(99999999.0 + i);  // every 8-digit block boundary
  }
  for (double v : {0.0, -0.0, 1e100, 1e-100, 123456789012345680000.0, 5e-324, 1.7976931348623157e308,
                   std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity(),
                   std::numeric_limits<double>::quiet_NaN()})
    check(v);
  EXPECT_EQ(differing, 0u) << "of " << checked;
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
