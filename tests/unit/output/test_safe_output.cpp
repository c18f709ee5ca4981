// Output safety: a run never writes over a user's file, through a link or over its own input, and a
// failed write is an error, never a silent short file.
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <unistd.h>

#include <csignal>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "error_of.hpp"
#include "odonav/safe_output.hpp"
#include "scratch_dir.hpp"

namespace fs = std::filesystem;
using namespace odonav;

namespace {

using test::ScratchDir;
using test::read_text;
using test::write_text;

// The message of the OutputError `f` throws ("" when it throws none).
template <class F>
std::string refusal(F f) {
  return test::message_if_thrown<OutputError>(f);
}

}  // namespace

TEST(OutputDirectory, CreatesAMissingDirectoryAndMarksItAsOdonavs) {
  ScratchDir s;
  const OutputDirectory out(s / "a/b/out", {});
  EXPECT_TRUE(fs::is_directory(s / "a/b/out"));
  EXPECT_TRUE(fs::exists(s / "a/b/out/.odonav-output"));
  // Marked: a second run may replace its files.
  write_text(s / "a/b/out/summary.json", "{}");
  EXPECT_EQ(refusal([&] { OutputDirectory again(s / "a/b/out", {}); }), "");
}

TEST(OutputDirectory, RefusesANonEmptyForeignDirectoryUnlessForced) {
  ScratchDir s;
  fs::create_directories(s / "mine");
  write_text(s / "mine/thesis.tex", "years of work");
  const std::string why = refusal([&] { OutputDirectory d(s / "mine", {}); });
  EXPECT_NE(why.find("not empty"), std::string::npos) << why;
  EXPECT_NE(why.find("--force"), std::string::npos) << why;
  EXPECT_NE(why.find(s / "mine"), std::string::npos) << why;
  EXPECT_FALSE(fs::exists(s / "mine/.odonav-output"));  // refused: nothing written
  OutputPolicy force;
  force.force = true;
  EXPECT_EQ(refusal([&] { OutputDirectory d(s / "mine", force); }), "");
  EXPECT_EQ(read_text(s / "mine/thesis.tex"), "years of work");
}

TEST(OutputDirectory, AnEmptyExistingDirectoryIsAccepted) {
  ScratchDir s;
  fs::create_directories(s / "empty");
  EXPECT_EQ(refusal([&] { OutputDirectory d(s / "empty", {}); }), "");
}

TEST(OutputDirectory, RefusesAFileAndTheDatasetItselfOrADirectoryHoldingIt) {
  ScratchDir s;
  write_text(s / "plain", "x");
  EXPECT_NE(refusal([&] { OutputDirectory d(s / "plain", {}); }).find("not a directory"), std::string::npos);
  fs::create_directories(s / "dataset");
  write_text(s / "dataset/gnss.csv", "t\n");
  OutputPolicy p;
  p.inputs = {s / "dataset"};
  p.force = true;  // even forced
  EXPECT_NE(refusal([&] { OutputDirectory d(s / "dataset", p); }).find("input of this run"), std::string::npos);
  EXPECT_NE(refusal([&] { OutputDirectory d(s / "dataset/out", p); }).find("is inside"), std::string::npos);
  fs::create_directories(s / "parent");
  p.inputs = {s / "parent/dataset"};
  EXPECT_NE(refusal([&] { OutputDirectory d(s / "parent", p); }).find("holds"), std::string::npos);
  EXPECT_EQ(read_text(s / "dataset/gnss.csv"), "t\n");
}

TEST(CheckOutputFile, RefusesSymlinksDirectoriesAndInputsUnderAnyName) {
  ScratchDir s;
  write_text(s / "victim", "precious");
  fs::create_symlink(s / "victim", s / "link");
  EXPECT_NE(refusal([&] { check_output_file(s / "link", {}); }).find("symbolic link"), std::string::npos);
  fs::create_directories(s / "dir");
  EXPECT_NE(refusal([&] { check_output_file(s / "dir", {}); }).find("directory"), std::string::npos);
  fs::create_directories(s / "ds");
  write_text(s / "ds/gnss.csv", "data");
  // The same file spelled with ".." and through a linked directory is still the input.
  fs::create_directory_symlink(s / "ds", s / "ds-link");
  for (const std::string& spelling : {s / "ds/gnss.csv", s / "dir/../ds/gnss.csv", s / "ds-link/gnss.csv"}) {
    const std::string why = refusal([&] { check_output_file(spelling, {s / "ds/gnss.csv"}); });
    EXPECT_NE(why.find("input of this run"), std::string::npos) << spelling << ": " << why;
  }
  // Inside an input directory.
  EXPECT_NE(refusal([&] { check_output_file(s / "ds/new.html", {s / "ds"}); }).find("input"), std::string::npos);
  EXPECT_EQ(refusal([&] { check_output_file(s / "other.csv", {s / "ds"}); }), "");
  EXPECT_EQ(read_text(s / "victim"), "precious");
}

TEST(AtomicFile, TheRealNameAppearsOnlyWhenComplete) {
  ScratchDir s;
  write_text(s / "out.csv", "old complete content\n");
  {
    AtomicFile f(s / "out.csv");
    f.write("new ");
    // While writing, the real name still has the previous complete file.
    EXPECT_EQ(read_text(s / "out.csv"), "old complete content\n");
    f.write(std::string("content\n"));
    f.commit();
  }
  EXPECT_EQ(read_text(s / "out.csv"), "new content\n");
  // Abandoned (an exception in the run): the old file stays, no temporary is left behind.
  {
    AtomicFile f(s / "out.csv");
    f.write("half");
  }
  EXPECT_EQ(read_text(s / "out.csv"), "new content\n");
  int files = 0;
  for (const auto& e : fs::directory_iterator(fs::path(s / "out.csv").parent_path())) {
    (void)e;
    ++files;
  }
  EXPECT_EQ(files, 1);
}

TEST(AtomicFile, AFailedWriteIsAnErrorNamingThePathAndTheOldFileSurvives) {
  // A file-size limit makes the kernel refuse writes past it (EFBIG), as a full disk does (ENOSPC).
  ScratchDir s;
  write_text(s / "summary.json", "{\"old\": true}");
  struct rlimit old_limit {};
  ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &old_limit), 0);
  const auto old_handler = std::signal(SIGXFSZ, SIG_IGN);
  struct rlimit small = old_limit;
  small.rlim_cur = 64 * 1024;
  ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &small), 0);
  std::string why;
  {
    AtomicFile f(s / "summary.json");
    why = refusal([&] {
      f.write(std::string(1024 * 1024, 'x'));
      f.commit();
    });
  }
  ::setrlimit(RLIMIT_FSIZE, &old_limit);
  std::signal(SIGXFSZ, old_handler);
  EXPECT_NE(why.find("summary.json"), std::string::npos) << why;
  EXPECT_NE(why.find("cannot write"), std::string::npos) << why;
  EXPECT_EQ(read_text(s / "summary.json"), "{\"old\": true}");
  // A directory removed under the writer: the rename fails, and says where.
  fs::create_directories(s / "gone");
  AtomicFile g(s / "gone/out.csv");
  g.write("t\n");
  fs::remove_all(s / "gone");
  const std::string rename_why = refusal([&] { g.commit(); });
  EXPECT_NE(rename_why.find("gone/out.csv"), std::string::npos) << rename_why;
  EXPECT_FALSE(g.committed());
}

TEST(AtomicFile, KeptOnFailureAnAbandonedOrFailedFileLeavesItsTemporaryAndTheOldFile) {
  ScratchDir s;
  write_text(s / "rows.csv", "old\n");
  const std::string temporary = (s / "rows.csv") + ".tmp-" + std::to_string(::getpid());
  {
    AtomicFile f(s / "rows.csv");
    f.keep_on_failure();
    f.write("t\n1\n");
  }  // abandoned: an exception in the run
  EXPECT_EQ(read_text(s / "rows.csv"), "old\n");
  EXPECT_EQ(read_text(temporary), "t\n1\n");
  // A failed write (the file-size limit, as a full disk): what reached the file stays.
  struct rlimit old_limit {};
  ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &old_limit), 0);
  const auto old_handler = std::signal(SIGXFSZ, SIG_IGN);
  struct rlimit small = old_limit;
  small.rlim_cur = 4096;
  ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &small), 0);
  std::string why;
  {
    AtomicFile f(s / "rows.csv");
    f.keep_on_failure();
    why = refusal([&] {
      f.write(std::string(100, 'r'));
      f.flush(false);
      f.write(std::string(8192, 'x'));
      f.commit();
    });
  }
  ::setrlimit(RLIMIT_FSIZE, &old_limit);
  std::signal(SIGXFSZ, old_handler);
  EXPECT_NE(why.find("rows.csv"), std::string::npos) << why;
  EXPECT_EQ(read_text(s / "rows.csv"), "old\n");
  EXPECT_EQ(read_text(temporary).substr(0, 100), std::string(100, 'r'));
}

TEST(AtomicFile, RefusesToWriteThroughALinkPlantedAtTheRealName) {
  ScratchDir s;
  write_text(s / "victim", "precious");
  fs::create_symlink(s / "victim", s / "summary.json");
  EXPECT_NE(refusal([&] { write_file_atomically(s / "summary.json", "{}"); }).find("symbolic link"), std::string::npos);
  EXPECT_EQ(read_text(s / "victim"), "precious");
}

TEST(AtomicFile, WriteFileAtomicallyReplacesTheWholeFile) {
  ScratchDir s;
  write_text(s / "f", std::string(10000, 'x'));
  write_file_atomically(s / "f", "short");
  EXPECT_EQ(read_text(s / "f"), "short");
}
