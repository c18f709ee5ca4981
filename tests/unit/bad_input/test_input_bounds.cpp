// Input bounds of the dataset reader and the config parser: only regular files, a size cap, a
// line-length cap, and messages that quote at most 80 printable characters of what they read.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <future>
#include <string>
#include <vector>

#include "odonav/config.hpp"
#include "odonav/dataset.hpp"
#include "scratch_dir.hpp"

namespace fs = std::filesystem;
using namespace odonav;

namespace {

// A scratch folder with a valid odometer.csv and gnss.csv.
class Dir : public test::ScratchDir {
 public:
  Dir() {
    put("odometer.csv", "t,pulses,direction\n0,0,1\n0.01,1,1\n0.02,2,1\n");
    put("gnss.csv",
        "t,lat_deg,lon_deg,height_m,ve,vn,vu,fix\n0,52.5,13.4,80,0,1,0,1\n0.1,52.5000009,13.4,80,0,1,0,1\n");
  }
  /// Replaces <dir>/<name> (whatever it was) with a file holding `text`.
  void put(const std::string& name, const std::string& text) const {
    fs::remove(path() / name);
    write(name, text);
  }
};

// read_dataset's DatasetError message, bounded in time so a hang fails instead of blocking.
std::string read_error(const std::string& dir, BadRowPolicy policy = BadRowPolicy::kFail) {
  auto task = std::async(std::launch::async, [=]() -> std::string {
    try {
      read_dataset(dir, policy);
    } catch (const DatasetError& e) {
      return e.what();
    }
    return "";
  });
  if (task.wait_for(std::chrono::seconds(60)) != std::future_status::ready) {
    ADD_FAILURE() << "read_dataset did not return within 60 s";
    std::_Exit(1);  // a blocked reader thread cannot be cancelled
  }
  return task.get();
}

}  // namespace

TEST(InputBounds, ADirectoryWhereADatasetFileShouldBeIsNamed) {
  Dir d;
  fs::remove(d.file("gnss.csv"));
  fs::create_directory(d.file("gnss.csv"));
  const std::string why = read_error(d.str());
  EXPECT_NE(why.find(d.file("gnss.csv") + ": is a directory"), std::string::npos) << why;
}

TEST(InputBounds, AFifoOrADeviceIsRefusedWithoutBlocking) {
  Dir d;
  fs::remove(d.file("odometer.csv"));
  ASSERT_EQ(::mkfifo(d.file("odometer.csv").c_str(), 0600), 0);
  std::string why = read_error(d.str());
  EXPECT_NE(why.find("not a regular file"), std::string::npos) << why;
  fs::remove(d.file("odometer.csv"));
  fs::create_symlink("/dev/zero", d.file("odometer.csv"));
  why = read_error(d.str());
  EXPECT_NE(why.find("not a regular file"), std::string::npos) << why;
}

TEST(InputBounds, AFileOverTheSizeLimitIsRefusedBeforeReading) {
  Dir d;
  // Sparse: no disk space and no time to make, but its size says 2 GiB + 1.
  fs::resize_file(d.file("odometer.csv"), kMaxDatasetFileBytes + 1);
  const std::string why = read_error(d.str());
  EXPECT_NE(why.find("more than the limit of 2147483648 bytes"), std::string::npos) << why;
}

TEST(InputBounds, AHugeLineIsABadRowQuotedInEightyCharactersAndTheRestIsKept) {
  Dir d;
  const std::string huge(50 * 1024 * 1024, ',');
  d.put("odometer.csv", "t,pulses,direction\n0,0,1\n" + huge + "\n0.01,1,1\n0.02,2,1\n");
  const std::string why = read_error(d.str());
  EXPECT_NE(why.find("odometer.csv:3: line of 52428800 bytes, longer than the limit of 65536"), std::string::npos)
      << why.substr(0, 300);
  EXPECT_LT(why.size(), 400u) << "the message must not carry the line";
  DatasetReadReport report;
  const Dataset kept = read_dataset(d.str(), BadRowPolicy::kSkip, &report);
  EXPECT_EQ(kept.odometer.size(), 3u);
  EXPECT_EQ(report.total_bad(), 1u);
}

TEST(InputBounds, BinaryBytesInAFieldReachTheMessageEscaped) {
  Dir d;
  d.put("odometer.csv", std::string("t,pulses,direction\n0,0,1\n0.01,\x1b[31m\x00"
                                    "7,1\n",
                                    44));
  const std::string why = read_error(d.str());
  EXPECT_NE(why.find("odometer.csv:3: column 'pulses'"), std::string::npos) << why;
  EXPECT_NE(why.find("\\x1b[31m\\x007"), std::string::npos) << why;
  for (char c : why) EXPECT_TRUE(c >= 0x20 && c < 0x7f) << "unprintable byte " << int(c) << " in: " << why;
}

TEST(InputBounds, ALongFieldIsQuotedInAtMostEightyCharacters) {
  Dir d;
  d.put("odometer.csv", "t,pulses,direction\n0,0,1\n0.01," + std::string(5000, 'x') + ",1\n");
  const std::string why = read_error(d.str());
  EXPECT_NE(why.find("'" + std::string(80, 'x') + "... (5000 bytes)'"), std::string::npos) << why.substr(0, 300);
  EXPECT_LT(why.size(), 300u);
}

TEST(InputBounds, TheConfigParserRefusesAFifoADirectoryAndAHugeFile) {
  Dir d;
  const auto parse_error = [&](const std::string& path) -> std::string {
    Options o("odonav-test", "test");
    o.add_double("min-speed", 2.0, "m/s", 0.0, 100.0);
    const std::string flag = "--config=" + path;
    const char* argv[] = {"odonav-test", flag.c_str()};
    try {
      o.parse(2, const_cast<char**>(argv));
    } catch (const ConfigError& e) {
      return e.what();
    }
    return "";
  };
  ASSERT_EQ(::mkfifo(d.file("fifo.conf").c_str(), 0600), 0);
  EXPECT_NE(parse_error(d.file("fifo.conf")).find("not a regular file"), std::string::npos);
  fs::create_directory(d.file("dir.conf"));
  EXPECT_NE(parse_error(d.file("dir.conf")).find("is a directory"), std::string::npos);
  d.put("big.conf", std::string(2 << 20, '#'));
  EXPECT_NE(parse_error(d.file("big.conf")).find("larger than"), std::string::npos);
  d.put("binary.conf", std::string("\x07\x1b garbage\n", 11));
  const std::string why = parse_error(d.file("binary.conf"));
  EXPECT_NE(why.find("\\x07\\x1b garbage"), std::string::npos) << why;
}

// ---- physical limits of a land vehicle (docs/DATASET.md "Physical limits") ----

TEST(PhysicalLimits, ImpossibleValuesAreBadRowsNamingFileLineAndColumn) {
  struct Case {
    const char* file;
    std::string text;
    const char* expect;
  };
  const std::string ins_header = "t,heading_deg,pitch_deg,roll_deg\n";
  const std::vector<Case> cases = {
      {"gnss.csv", "t,lat_deg,lon_deg,height_m,ve,vn,vu,fix\n0,52.5,13.4,80,0,1,0,1\n0.1,52.5,13.4,1e300,0,1,0,1\n",
       "gnss.csv:3: column 'height_m': height (m) of a land vehicle outside [-1000, 10000]: '1e300'"},
      {"gnss.csv", "t,lat_deg,lon_deg,height_m,ve,vn,vu,fix\n0,52.5,13.4,80,0,1,0,1\n0.1,52.5,13.4,80,1e6,1,0,1\n",
       "gnss.csv:3: column 've': velocity (m/s) of a land vehicle outside [-500, 500]: '1e6'"},
      {"ins.csv", ins_header + "0,10,0,0\n0.01,1e300,0,0\n",
       "ins.csv:3: column 'heading_deg': heading outside [-720, 720]"},
      {"ins.csv", ins_header + "0,10,0,0\n0.01,10,0,270\n", "ins.csv:3: column 'roll_deg': roll outside [-180, 180]"},
  };
  for (const Case& c : cases) {
    Dir d;
    d.put(c.file, c.text);
    const std::string why = read_error(d.str());
    EXPECT_NE(why.find(c.expect), std::string::npos) << why;
  }
}

TEST(PhysicalLimits, MetaJsonNominalKAndLeverArmOutOfRangeAreNamed) {
  Dir d;
  d.put("meta.json", R"({"format": "odonav-dataset/1", "odometer": {"k_nominal_m_per_pulse": 0}})");
  EXPECT_NE(read_error(d.str()).find("key 'odometer.k_nominal_m_per_pulse' = 0"), std::string::npos);
  d.put("meta.json", R"({"format": "odonav-dataset/1", "gnss": {"lever_arm_m": [1e6, 0, 2]}})");
  const std::string why = read_error(d.str());
  EXPECT_NE(why.find("key 'gnss.lever_arm_m' has a component beyond +-20 m"), std::string::npos) << why;
  d.put("meta.json", R"({"format": "odonav-dataset/1", "gnss": {"lever_arm_m": [-0.5, 0.3, 2.2]}})");
  EXPECT_EQ(read_error(d.str()), "");
}

TEST(PhysicalLimits, ManualAndSimulatedFixesAreNoReferenceButPpsAndSbasAre) {
  for (int fix = 0; fix <= 9; ++fix) {
    GnssSample g;
    g.fix = fix;
    const bool measured = fix != 0 && fix != 6 && fix != 7 && fix != 8;
    EXPECT_EQ(g.valid(), measured) << "fix " << fix;
  }
}
