#pragma once
// Writing a run's files without ever destroying a user's file, and without reporting success for a
// write that failed.
//
// The rules, for every odonav tool that writes (offline, evaluate, recorder, simulator):
// - an output directory is created if missing; an existing one is used only if it is empty or is an
//   odonav output directory (it holds the marker file kOutputMarker, written when odonav creates or
//   first fills it); anything else is refused unless the user says --force;
// - a file is never written through a symbolic link, never over an input of the run (the dataset's
//   files, the results being evaluated), and never over a directory;
// - every file is written under a temporary name in the same directory, every write and the close
//   are checked, and only a complete file is renamed to its real name (rename is atomic on POSIX):
//   a full disk or a killed process leaves the previous file, never a truncated one.
// Errors are OutputError (a std::runtime_error) naming the path and the rule or the system error.
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

namespace odonav {

/// A refused or failed output; what() names the path and why.
class OutputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// File name of the marker that makes a directory an odonav output directory.
inline constexpr const char* kOutputMarker = ".odonav-output";

struct OutputPolicy {
  /// Use an existing non-empty directory that is not an odonav output directory (the user's choice).
  bool force = false;
  /// Paths (files or directories) the run reads: never written to, and an output directory may
  /// neither be one of them nor contain one.
  std::vector<std::string> inputs;
};

/// The one directory a run writes into, checked when constructed (see the file comment).
class OutputDirectory {
 public:
  /// Creates `path` (and parents) if missing, or checks the existing directory, then writes the
  /// marker. Throws OutputError naming `path` and the rule it breaks.
  OutputDirectory(const std::string& path, OutputPolicy policy);

  const std::string& path() const { return path_; }
  /// `<path>/<name>` after check_output_file (name: a plain file name or a relative path inside).
  std::string file(const std::string& name) const;
  const OutputPolicy& policy() const { return policy_; }

 private:
  std::string path_;
  OutputPolicy policy_;
};

/// Throws OutputError when `path` must not be written: it is a symbolic link, a directory, or the
/// same file as one of `inputs` (or inside an input directory).
void check_output_file(const std::string& path, const std::vector<std::string>& inputs);

/// A file written under a temporary name and renamed over `path` by commit(). Every write is
/// checked; an object destroyed without commit() removes its temporary and leaves `path` as it was.
class AtomicFile {
 public:
  /// Checks `path` with check_output_file, then opens `<path>.tmp-<pid>` for writing.
  explicit AtomicFile(const std::string& path, const std::vector<std::string>& inputs = {});
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  /// Appends bytes; throws OutputError naming the path on a failed write.
  void write(const char* data, std::size_t size);
  void write(const std::string& text) { write(text.data(), text.size()); }
  /// Hands what was written to the kernel (a killed process then leaves it in the temporary);
  /// `sync` also forces it to the disk (fsync). OutputError naming the path on failure.
  void flush(bool sync);
  /// Flushes, closes and renames to the real name; throws OutputError naming the path on failure
  /// (the temporary is then removed). Once committed, further writes are a logic error.
  void commit();

  /// From now on a failed write or a destruction without commit() leaves the temporary (with what
  /// was written) instead of removing it: for a recording whose rows must survive an error, picked
  /// up at the next start (odonav-recorder resumes it). The real name is still never touched.
  void keep_on_failure() { keep_on_failure_ = true; }

  const std::string& path() const { return path_; }
  bool committed() const { return committed_; }

 private:
  void fail(const std::string& what);
  std::string path_;
  std::string temporary_;
  std::FILE* file_ = nullptr;
  bool committed_ = false;
  bool keep_on_failure_ = false;
};

/// Writes `text` to `path` through AtomicFile.
void write_file_atomically(const std::string& path, const std::string& text,
                           const std::vector<std::string>& inputs = {});

}  // namespace odonav
