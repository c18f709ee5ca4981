#pragma once
// What the multi-process tests and the benchmarks share (no gtest in here): odonav executables of
// this build started as child processes that are always killed on failure, their output in files,
// their CPU time and peak RSS, scratch folders and `fastdds shm clean`. Every test suite and
// benchmark that starts processes includes this one header, so there is one ChildProcess in
// odonav::test (tests/integration/{nodes,ground,pipeline,...} and bench/pipeline_bench.cpp used to
// carry their own copies).
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "text_files.hpp"

extern char** environ;

namespace odonav::test {

#ifdef ODONAV_BINARY_DIR  // tests (odonav_add_gtest) define it; benchmarks find their executables themselves
/// Path of an odonav executable of this build.
inline std::string binary(const std::string& name) { return std::string(ODONAV_BINARY_DIR) + "/bin/" + name; }
#endif

/// A shell command's exit status (-1: it did not exit normally) and its output, stderr included.
struct CommandResult {
  int status = -1;
  std::string output;
};
/// Runs `command` with /bin/sh, waits, and returns its status and combined output.
inline CommandResult run_command(const std::string& command) {
  CommandResult r;
  FILE* pipe = ::popen((command + " 2>&1").c_str(), "r");
  if (pipe == nullptr) return r;
  char buffer[4096];
  while (fgets(buffer, sizeof buffer, pipe) != nullptr) r.output += buffer;
  const int status = ::pclose(pipe);
  r.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

/// `fastdds shm clean` (removes only unused shared-memory segments; safe while others run).
inline void shm_clean() { [[maybe_unused]] int rc = std::system("fastdds shm clean >/dev/null 2>&1"); }

#ifdef ODONAV_BINARY_DIR
/// An empty folder ODONAV_BINARY_DIR/<suite>/<name> (removed first if it exists).
inline std::filesystem::path fresh_dir(const std::string& suite, const std::string& name) {
  const auto dir = std::filesystem::path(ODONAV_BINARY_DIR) / suite / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}
#endif

/// A child process started with posix_spawn (so its pid is the program's own), standard output
/// and error inherited or written to files (the same file for both if they are equal), in a
/// process group of its own if asked (for a program that starts daemons: signal -pid() to reach
/// them all). Reaped with wait4, so its resource usage is known once it exited. The destructor
/// kills it (SIGKILL) and reaps it if it still runs, so a failing test never leaves an orphan.
class ChildProcess {
 public:
  ChildProcess(const std::string& path, const std::vector<std::string>& args,
               const std::filesystem::path& out_file = {}, const std::filesystem::path& err_file = {},
               bool own_process_group = false)
      : out_(out_file), err_(err_file) {
    std::vector<char*> argv;
    argv.push_back(const_cast<char*>(path.c_str()));
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    constexpr int kFlags = O_WRONLY | O_CREAT | O_TRUNC;
    if (!out_.empty()) posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, out_.c_str(), kFlags, 0644);
    if (!err_.empty()) {
      if (err_ == out_) {
        posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
      } else {
        posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, err_.c_str(), kFlags, 0644);
      }
    }
    posix_spawnattr_t attributes;
    posix_spawnattr_init(&attributes);
    if (own_process_group) {
      posix_spawnattr_setflags(&attributes, POSIX_SPAWN_SETPGROUP);
      posix_spawnattr_setpgroup(&attributes, 0);
    }
    spawn_error_ = posix_spawn(&pid_, path.c_str(), &actions, &attributes, argv.data(), environ);
    if (spawn_error_ != 0) pid_ = -1;
    posix_spawnattr_destroy(&attributes);
    posix_spawn_file_actions_destroy(&actions);
  }
  ~ChildProcess() { kill_and_reap(); }
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;

  bool started() const { return pid_ > 0; }
  /// posix_spawn's error number when it could not start (0 when started()).
  int spawn_error() const { return spawn_error_; }
  pid_t pid() const { return pid_; }
  /// True once it was reaped (exit_code(), cpu_s() and max_rss_kb() are then valid).
  bool exited() const { return exited_; }
  void signal(int sig) {
    if (pid_ > 0 && !exited_) ::kill(pid_, sig);
  }
  /// Waits up to timeout for the exit; true if it exited (exit_code() then valid: the exit status,
  /// or 128 + signal).
  bool wait_exit(std::chrono::milliseconds timeout) {
    if (pid_ <= 0) return false;
    const auto end = std::chrono::steady_clock::now() + timeout;
    while (!exited_) {
      if (reap(WNOHANG)) break;
      if (std::chrono::steady_clock::now() > end) return false;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return true;
  }
  /// wait_exit(timeout), then SIGKILL and reap when it still runs. True if it exited by itself;
  /// either way it has exited afterwards (a started process).
  bool wait_exit_or_kill(std::chrono::milliseconds timeout) {
    if (wait_exit(timeout)) return true;
    kill_and_reap();
    return false;
  }
  /// Whether it still runs (reaps it if it has exited).
  bool running() { return started() && !exited_ && !wait_exit(std::chrono::milliseconds(0)); }
  int exit_code() const { return exit_code_; }
  /// User + system CPU time of its whole life, s (after it exited; 0 before).
  double cpu_s() const { return cpu_s_; }
  /// ru_maxrss of wait4, kB (after it exited). Linux carries ru_maxrss across exec, so a process
  /// spawned by a larger one reports at least the parent's size at the fork: sample VmHWM from
  /// /proc/<pid>/status while it runs for the program's own peak.
  long max_rss_kb() const { return max_rss_kb_; }
  /// What it wrote so far to its output / error file ("" when inherited).
  std::string out() const { return out_.empty() ? std::string() : read_text(out_); }
  std::string err() const { return err_.empty() ? std::string() : read_text(err_); }

 private:
  // wait4 with `options` (WNOHANG or 0); true, with the status and usage recorded, once reaped.
  bool reap(int options) {
    int status = 0;
    struct rusage usage {};
    const pid_t r = wait4(pid_, &status, options, &usage);
    if (r != pid_) return false;
    exited_ = true;
    exit_code_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    cpu_s_ = static_cast<double>(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
             1e-6 * static_cast<double>(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
    max_rss_kb_ = usage.ru_maxrss;
    return true;
  }
  void kill_and_reap() {
    if (pid_ > 0 && !exited_) {
      ::kill(pid_, SIGKILL);
      if (!reap(0)) exited_ = true;  // reaped elsewhere (or never ours): nothing left to wait for
    }
  }

  std::filesystem::path out_;
  std::filesystem::path err_;
  pid_t pid_ = -1;
  int spawn_error_ = 0;
  bool exited_ = false;
  int exit_code_ = -1;
  double cpu_s_ = 0.0;
  long max_rss_kb_ = 0;
};

#ifdef ODONAV_BINARY_DIR
/// `binary(name) args...` with standard output and error both in `log`.
inline std::unique_ptr<ChildProcess> start_logged(const std::string& name, const std::vector<std::string>& args,
                                                  const std::filesystem::path& log) {
  return std::make_unique<ChildProcess>(binary(name), args, log, log);
}
#endif

}  // namespace odonav::test
