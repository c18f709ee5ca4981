#pragma once
// Helpers of the ground-station tests: child processes with their output in files (always killed
// on failure), the loopback participant, shell commands, file reading.
#include <gtest/gtest.h>
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "odonav/dds/participant.hpp"
#include "odonav/topics.hpp"

extern char** environ;

namespace odonav::test {

inline std::string loopback_profile() { return std::string(ODONAV_SOURCE_DIR) + "/deploy/profiles/loopback.xml"; }
inline std::string binary(const std::string& name) { return std::string(ODONAV_BINARY_DIR) + "/bin/" + name; }

/// `fastdds shm clean` (removes only unused shared-memory segments; safe while others run).
inline void shm_clean() { [[maybe_unused]] int rc = std::system("fastdds shm clean >/dev/null 2>&1"); }

inline dds::ParticipantOptions participant_options(int domain, const std::string& name) {
  dds::ParticipantOptions p;
  p.profiles_file = loopback_profile();
  p.participant_profile = topics::kLoopbackParticipantProfile;
  p.domain_id = domain;
  p.participant_name = name;
  return p;
}

/// A fresh folder under the build tree for one test.
inline std::filesystem::path scratch_dir(const std::string& name) {
  const auto dir = std::filesystem::path(ODONAV_BINARY_DIR) / "tests" / "ground" / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

inline std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

/// A child process started with posix_spawn, stdout and stderr to files. The destructor kills it
/// (SIGKILL) if it still runs, so a failing test never leaves an orphan.
class ChildProcess {
 public:
  ChildProcess(const std::string& path, const std::vector<std::string>& args, const std::filesystem::path& out_file,
               const std::filesystem::path& err_file)
      : out_(out_file), err_(err_file) {
    std::vector<char*> argv;
    argv.push_back(const_cast<char*>(path.c_str()));
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, out_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, err_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (posix_spawn(&pid_, path.c_str(), &actions, nullptr, argv.data(), environ) != 0) pid_ = -1;
    posix_spawn_file_actions_destroy(&actions);
  }
  ~ChildProcess() {
    if (pid_ > 0 && !exited_) {
      ::kill(pid_, SIGKILL);
      int status = 0;
      waitpid(pid_, &status, 0);
    }
  }
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;

  bool started() const { return pid_ > 0; }
  void signal(int sig) {
    if (pid_ > 0 && !exited_) ::kill(pid_, sig);
  }
  /// Waits up to timeout for the exit; true if it exited (exit_code() then valid: the exit status,
  /// or 128 + signal).
  bool wait_exit(std::chrono::milliseconds timeout) {
    const auto end = std::chrono::steady_clock::now() + timeout;
    while (!exited_) {
      int status = 0;
      const pid_t r = waitpid(pid_, &status, WNOHANG);
      if (r == pid_) {
        exited_ = true;
        exit_code_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
        break;
      }
      if (std::chrono::steady_clock::now() > end) return false;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return true;
  }
  int exit_code() const { return exit_code_; }
  std::string out() const { return read_text(out_); }
  std::string err() const { return read_text(err_); }

 private:
  pid_t pid_ = -1;
  bool exited_ = false;
  int exit_code_ = -1;
  std::filesystem::path out_, err_;
};

/// Runs a program to its end (bounded by timeout, then killed): exit code, stdout, stderr.
struct RunResult {
  int exit_code = -1;
  std::string out, err;
};
inline RunResult run(const std::string& path, const std::vector<std::string>& args, const std::filesystem::path& dir,
                     const std::string& tag, std::chrono::milliseconds timeout = std::chrono::seconds(120)) {
  ChildProcess child(path, args, dir / (tag + ".out"), dir / (tag + ".err"));
  RunResult r;
  if (!child.started()) {
    ADD_FAILURE() << "cannot start " << path;
    return r;
  }
  if (!child.wait_exit(timeout)) {
    ADD_FAILURE() << path << " did not finish within " << timeout.count() << " ms";
    child.signal(SIGKILL);
    child.wait_exit(std::chrono::seconds(5));
  }
  r.exit_code = child.exit_code();
  r.out = child.out();
  r.err = child.err();
  return r;
}

/// The common DDS flags of odonav-ground under test.
inline std::vector<std::string> ground_args(const std::string& action, int domain, std::vector<std::string> extra = {}) {
  std::vector<std::string> a{action, "--domain", std::to_string(domain), "--profile", loopback_profile(),
                             "--log-level", "warn"};
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}

}  // namespace odonav::test
