#pragma once
// What the multi-process tests share (no gtest in here): odonav executables of this build started
// as child processes that are always killed on failure, their output in files, scratch folders
// and `fastdds shm clean`. Every test suite that starts components includes this one header, so
// there is one ChildProcess in odonav::test (tests/integration/{nodes,ground,...} used to carry
// their own copies).
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace odonav::test {

/// Path of an odonav executable of this build.
inline std::string binary(const std::string& name) { return std::string(ODONAV_BINARY_DIR) + "/bin/" + name; }

/// `fastdds shm clean` (removes only unused shared-memory segments; safe while others run).
inline void shm_clean() { [[maybe_unused]] int rc = std::system("fastdds shm clean >/dev/null 2>&1"); }

/// The whole content of a file ("" if it cannot be read).
inline std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

/// An empty folder ODONAV_BINARY_DIR/<suite>/<name> (removed first if it exists).
inline std::filesystem::path fresh_dir(const std::string& suite, const std::string& name) {
  const auto dir = std::filesystem::path(ODONAV_BINARY_DIR) / suite / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

/// A child process started with posix_spawn (so its pid is the program's own), standard output
/// and error inherited or written to files (the same file for both if they are equal), in a
/// process group of its own if asked (for a program that starts daemons: signal -pid() to reach
/// them all). The destructor kills it (SIGKILL) and reaps it if it still runs, so a failing test
/// never leaves an orphan.
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
    if (posix_spawn(&pid_, path.c_str(), &actions, &attributes, argv.data(), environ) != 0) pid_ = -1;
    posix_spawnattr_destroy(&attributes);
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
  pid_t pid() const { return pid_; }
  void signal(int sig) {
    if (pid_ > 0 && !exited_) ::kill(pid_, sig);
  }
  /// Waits up to timeout for the exit; true if it exited (exit_code() then valid: the exit status,
  /// or 128 + signal).
  bool wait_exit(std::chrono::milliseconds timeout) {
    if (pid_ <= 0) return false;
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
  /// Whether it still runs (reaps it if it has exited).
  bool running() { return started() && !exited_ && !wait_exit(std::chrono::milliseconds(0)); }
  int exit_code() const { return exit_code_; }
  /// What it wrote so far to its output / error file ("" when inherited).
  std::string out() const { return out_.empty() ? std::string() : read_text(out_); }
  std::string err() const { return err_.empty() ? std::string() : read_text(err_); }

 private:
  std::filesystem::path out_;
  std::filesystem::path err_;
  pid_t pid_ = -1;
  bool exited_ = false;
  int exit_code_ = -1;
};

/// `binary(name) args...` with standard output and error both in `log`.
inline std::unique_ptr<ChildProcess> start_logged(const std::string& name, const std::vector<std::string>& args,
                                                  const std::filesystem::path& log) {
  return std::make_unique<ChildProcess>(binary(name), args, log, log);
}

}  // namespace odonav::test
