// Resuming an unfinished recording (components/recorder/core/include/odonav/recorder/recording_resume.hpp): which files of
// a killed recorder are adopted, which of their rows, what is refused, and what is a repeat.
#include <gtest/gtest.h>

#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "odonav/recorder/recording_resume.hpp"
#include "scratch_dir.hpp"

using namespace odonav::recorder;
namespace fs = std::filesystem;

namespace {

const std::vector<std::string> kColumns{"t", "a", "b"};
const std::string kHeader = "t,a,b\n";

class Resume : public ::testing::Test {
 protected:
  std::string path(const std::string& name) const { return dir_.file(name); }
  void write(const std::string& name, const std::string& text) const { dir_.write(name, text); }
  std::string read(const std::string& name) const { return dir_.read(name); }
  void marker(long pid, const std::string& vehicle) const { write(kRecordingMarker, marker_text({pid, vehicle})); }
  ResumePlan plan(long own_pid = 100, bool alive = false) const {
    return plan_resume(dir_.str(), "car-1", {{"x.csv", kColumns}, {"y.csv", kColumns}}, {"gaps.csv"}, own_pid,
                       [alive](long) { return alive; });
  }
  odonav::test::ScratchDir dir_;
};

}  // namespace

TEST(AdoptRows, CompleteRowsAreTakenAndATornLastLineIsDroppedAndCounted) {
  const AdoptedRows r = adopt_rows(kHeader + "1.5,2,3\n1.6,,4\n1.7,5", kColumns, "x.csv.tmp-7");
  ASSERT_EQ(r.rows(), 2u);
  EXPECT_EQ(r.t_s, (std::vector<double>{1.5, 1.6}));
  EXPECT_EQ(r.text, "1.5,2,3\n1.6,,4\n");
  EXPECT_EQ(r.torn_lines, 1u);
  EXPECT_EQ(*r.last_t_s(), 1.6);

  const AdoptedRows whole = adopt_rows(kHeader + "1.5,2,3\n", kColumns, "x.csv");
  EXPECT_EQ(whole.rows(), 1u);
  EXPECT_EQ(whole.torn_lines, 0u);
}

TEST(AdoptRows, AnEmptyFileOrATornHeaderHasNoRows) {
  EXPECT_EQ(adopt_rows("", kColumns, "x").rows(), 0u);
  const AdoptedRows torn = adopt_rows("t,a", kColumns, "x");
  EXPECT_EQ(torn.rows(), 0u);
  EXPECT_EQ(torn.torn_lines, 1u);
  EXPECT_FALSE(torn.last_t_s());
}

TEST(AdoptRows, AnotherHeaderAMalformedRowOrStampIsRefusedNamingTheFileAndLine) {
  try {
    adopt_rows("t,a,c\n1,2,3\n", kColumns, "dir/x.csv.tmp-7");
    FAIL() << "another header adopted";
  } catch (const ResumeError& e) {
    EXPECT_NE(std::string(e.what()).find("'dir/x.csv.tmp-7' line 1: header \"t,a,c\""), std::string::npos) << e.what();
  }
  try {
    adopt_rows(kHeader + "1,2,3\n2,3\n3,4,5\n", kColumns, "x");
    FAIL() << "a row of 2 fields adopted";
  } catch (const ResumeError& e) {
    EXPECT_NE(std::string(e.what()).find("line 3: 2 fields, the header has 3"), std::string::npos) << e.what();
  }
  EXPECT_THROW(adopt_rows(kHeader + "x,2,3\n", kColumns, "x"), ResumeError);
  EXPECT_THROW(adopt_rows("t,a,b,c", kColumns, "x"), ResumeError);  // a torn line of another header
}

TEST(Marker, RoundTripsAndAMalformedOneIsRefused) {
  const RecordingMarker m = parse_marker(marker_text({4242, "car 7"}), "m");
  EXPECT_EQ(m.pid, 4242);
  EXPECT_EQ(m.vehicle_id, "car 7");
  EXPECT_EQ(parse_marker(marker_text({1, ""}), "m").vehicle_id, "");
  EXPECT_THROW(parse_marker("pid x\n", "m"), ResumeError);
  EXPECT_THROW(parse_marker("", "m"), ResumeError);
}

TEST_F(Resume, WithoutAMarkerNothingIsAdoptedAndOrphansAreLeftAsTheyAre) {
  // A cleanly finished recording (no marker) and an orphan of some other killed odonav run.
  write("x.csv", kHeader + "1,2,3\n");
  write("x.csv.tmp-55", kHeader + "1,2,3\n");
  const ResumePlan p = plan();
  EXPECT_FALSE(p.resumed());
  EXPECT_TRUE(p.files.empty());
  EXPECT_TRUE(p.remove.empty());
  EXPECT_EQ(p.ignored, (std::vector<std::string>{path("x.csv.tmp-55")}));
}

TEST_F(Resume, TheOrphansOfADeadRecorderOfTheSameVehicleAreAdopted) {
  write("x.csv", kHeader + "0.5,0,0\n");  // an earlier, finished recording's file: replaced, not adopted
  fs::last_write_time(path("x.csv"), fs::file_time_type::clock::now() - std::chrono::hours(1));
  marker(55, "car-1");
  write("x.csv.tmp-55", kHeader + "1,2,3\n2,3,4\n3,4");
  write("y.csv.tmp-55", kHeader);
  write("gaps.csv.tmp-55", kHeader);
  write("x.csv.tmp-54", kHeader + "9,9,9\n");  // another process's: not this recording's
  const ResumePlan p = plan();
  ASSERT_TRUE(p.resumed());
  EXPECT_EQ(p.previous->pid, 55);
  ASSERT_EQ(p.files.size(), 2u);
  EXPECT_EQ(p.files[0].name, "x.csv");
  EXPECT_EQ(p.files[0].from, path("x.csv.tmp-55"));
  EXPECT_EQ(p.files[0].rows.t_s, (std::vector<double>{1, 2}));
  EXPECT_EQ(p.files[0].rows.torn_lines, 1u);
  EXPECT_EQ(p.files[1].rows.rows(), 0u);
  EXPECT_EQ(p.remove, (std::vector<std::string>{path("x.csv.tmp-55"), path("y.csv.tmp-55"), path("gaps.csv.tmp-55")}));
  EXPECT_EQ(p.ignored, (std::vector<std::string>{path("x.csv.tmp-54")}));
  // Deciding changes nothing on disk.
  EXPECT_EQ(read("x.csv.tmp-55"), kHeader + "1,2,3\n2,3,4\n3,4");
}

TEST_F(Resume, AFileCommittedWhileTheRecorderClosedIsAdoptedAndKept) {
  marker(55, "car-1");
  write("x.csv", kHeader + "1,2,3\n");  // committed after the marker: killed while closing
  write("y.csv.tmp-55", kHeader + "1,2,3\n");
  const ResumePlan p = plan();
  ASSERT_EQ(p.files.size(), 2u);
  EXPECT_EQ(p.files[0].from, path("x.csv"));
  EXPECT_EQ(p.files[0].rows.rows(), 1u);
  EXPECT_EQ(p.remove, (std::vector<std::string>{path("y.csv.tmp-55")}));
}

TEST_F(Resume, ARunningRecorderOrAnotherVehicleIsRefusedAndNothingMoves) {
  marker(55, "car-1");
  write("x.csv.tmp-55", kHeader + "1,2,3\n");
  try {
    plan(100, true);
    FAIL() << "a running recorder's directory adopted";
  } catch (const ResumeError& e) {
    EXPECT_NE(std::string(e.what()).find("running odonav-recorder (pid 55"), std::string::npos) << e.what();
  }
  marker(55, "car-2");
  try {
    plan();
    FAIL() << "another vehicle's recording adopted";
  } catch (const ResumeError& e) {
    EXPECT_NE(std::string(e.what()).find("of vehicle 'car-2'"), std::string::npos) << e.what();
  }
  EXPECT_EQ(read("x.csv.tmp-55"), kHeader + "1,2,3\n");
}

TEST_F(Resume, AHeaderOfAnotherVersionIsRefusedAndTheOrphanKept) {
  marker(55, "car-1");
  write("x.csv.tmp-55", "t,a\n1,2\n");
  EXPECT_THROW(plan(), ResumeError);
  EXPECT_EQ(read("x.csv.tmp-55"), "t,a\n1,2\n");
}

TEST_F(Resume, AnOrphanOfThisProcesssOwnPidIsMovedAsideBeforeItsWriterOpens) {
  marker(100, "car-1");
  write("x.csv.tmp-100", kHeader + "1,2,3\n");
  const ResumePlan p = plan(100);
  ASSERT_EQ(p.files.size(), 1u);
  EXPECT_EQ(p.files[0].from, path("x.csv.adopt-100"));
  EXPECT_FALSE(fs::exists(path("x.csv.tmp-100")));
  EXPECT_EQ(read("x.csv.adopt-100"), kHeader + "1,2,3\n");
  EXPECT_EQ(p.remove, (std::vector<std::string>{path("x.csv.adopt-100")}));
  // A start killed right after that finds it there.
  const ResumePlan again = plan(101);
  ASSERT_EQ(again.files.size(), 1u);
  EXPECT_EQ(again.files[0].from, path("x.csv.adopt-100"));
}

TEST(RowStamps, RowsAtOrBeforeTheLastRecordedAreRepeats) {
  // A recorder restarted after t = 40 s: the producers hand it their 30 s of history (100 Hz, from
  // t = 10.01 s), then go on.
  RowStamps s;
  ASSERT_TRUE(s.admit(40.0));
  std::uint64_t written = 0;
  for (int i = 1001; i <= 4100; ++i) written += s.admit(i * 0.01) ? 1 : 0;
  EXPECT_EQ(s.repeats, 3000u);  // t = 10.01 ... 40.00 (4000 * 0.01 == 40.0 exactly)
  EXPECT_EQ(written, 100u);     // t = 40.01 ... 41.00
  EXPECT_EQ(*s.last_t_s, 4100 * 0.01);
  EXPECT_FALSE(s.admit(41.0));  // a heartbeat of the last one
  EXPECT_EQ(s.repeats, 3001u);
}
