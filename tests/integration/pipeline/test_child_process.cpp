// tests/support/child_process.hpp, the child-process helper of the multi-process tests and of the
// benchmarks: exit codes, a start that fails, the kill after a timeout, the child's CPU time and
// peak RSS from wait4.
#include <gtest/gtest.h>
#include <signal.h>

#include <cerrno>
#include <chrono>

#include "child_process.hpp"

namespace odonav::test {
namespace {

using std::chrono::milliseconds;

TEST(ChildProcess, ReportsTheExitStatusAndTheOutputFile) {
  const auto dir = fresh_dir("test-child-process", "exit");
  ChildProcess p("/bin/sh", {"-c", "echo hello; echo oops >&2; exit 3"}, dir / "out.log", dir / "out.log");
  ASSERT_TRUE(p.started());
  EXPECT_EQ(p.spawn_error(), 0);
  ASSERT_TRUE(p.wait_exit(milliseconds(10000)));
  EXPECT_TRUE(p.exited());
  EXPECT_FALSE(p.running());
  EXPECT_EQ(p.exit_code(), 3);
  EXPECT_EQ(p.out(), "hello\noops\n");
}

TEST(ChildProcess, AMissingProgramDoesNotStartAndSaysWhy) {
  ChildProcess p("/nonexistent/odonav-program", {});
  EXPECT_FALSE(p.started());
  EXPECT_EQ(p.spawn_error(), ENOENT);
  EXPECT_FALSE(p.wait_exit(milliseconds(0)));
  EXPECT_FALSE(p.running());
}

TEST(ChildProcess, WaitExitOrKillKillsAfterTheTimeout) {
  ChildProcess p("/bin/sleep", {"30"});
  ASSERT_TRUE(p.started());
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_FALSE(p.wait_exit_or_kill(milliseconds(200)));
  const double waited_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_GE(waited_s, 0.2);
  EXPECT_LT(waited_s, 10.0);
  EXPECT_TRUE(p.exited());
  EXPECT_EQ(p.exit_code(), 128 + SIGKILL);
}

TEST(ChildProcess, WaitExitOrKillReturnsTrueForAProgramThatEndsInTime) {
  ChildProcess p("/bin/sh", {"-c", "exit 0"});
  ASSERT_TRUE(p.started());
  EXPECT_TRUE(p.wait_exit_or_kill(milliseconds(10000)));
  EXPECT_EQ(p.exit_code(), 0);
}

TEST(ChildProcess, CpuTimeAndPeakRssOfTheChildFromWait4) {
  // Half a million shell loop iterations: about 0.4 s of CPU, all in the child (no fork), however
  // long a loaded machine makes it wait.
  ChildProcess p("/bin/sh", {"-c", "i=0; while [ $i -lt 500000 ]; do i=$((i+1)); done"});
  ASSERT_TRUE(p.started());
  EXPECT_EQ(p.cpu_s(), 0.0) << "known only once it exited";
  ASSERT_TRUE(p.wait_exit(milliseconds(30000)));
  EXPECT_EQ(p.exit_code(), 0);
  EXPECT_GT(p.cpu_s(), 0.05);
  EXPECT_LT(p.cpu_s(), 30.0);
  EXPECT_GT(p.max_rss_kb(), 100);  // a shell is some hundred kB at least
}

}  // namespace
}  // namespace odonav::test
