#include "odonav/safe_output.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <system_error>

namespace odonav {

namespace fs = std::filesystem;

namespace {

// "<path>: <what>: <system error>", the file-first form of every odonav I/O message.
std::string system_message(const std::string& what, const std::string& path, int error) {
  return path + ": " + what + ": " + std::strerror(error);
}

// The absolute, symlink-resolved form of a path that may not exist yet (its existing prefix is
// resolved), so that two spellings of one file compare equal.
fs::path resolved(const std::string& path) {
  std::error_code ec;
  fs::path p = fs::weakly_canonical(fs::absolute(path, ec), ec);
  return ec ? fs::absolute(path).lexically_normal() : p;
}

bool is_inside(const fs::path& child, const fs::path& parent) {
  auto c = child.begin();
  for (auto p = parent.begin(); p != parent.end(); ++p, ++c) {
    if (p->empty()) continue;  // a trailing separator
    if (c == child.end() || *c != *p) return false;
  }
  return true;
}

// The input `path` is, or is inside, if any: "" when none.
std::string input_hit(const fs::path& path, const std::vector<std::string>& inputs) {
  for (const std::string& input : inputs) {
    if (input.empty()) continue;
    const fs::path in = resolved(input);
    std::error_code ec;
    if (fs::is_directory(in, ec) ? is_inside(path, in) : (path == in || fs::equivalent(path, in, ec))) return input;
  }
  return "";
}

}  // namespace

void check_output_file(const std::string& path, const std::vector<std::string>& inputs) {
  std::error_code ec;
  const fs::file_status link = fs::symlink_status(path, ec);
  if (fs::is_symlink(link))
    throw OutputError("refusing to write '" + path + "': it is a symbolic link (odonav never writes through one)");
  if (fs::is_directory(link)) throw OutputError("refusing to write '" + path + "': it is a directory");
  if (fs::exists(link) && !fs::is_regular_file(link))
    throw OutputError("refusing to write '" + path + "': it is not a regular file");
  const std::string hit = input_hit(resolved(path), inputs);
  if (!hit.empty()) throw OutputError("refusing to write '" + path + "': it is an input of this run ('" + hit + "')");
}

OutputDirectory::OutputDirectory(const std::string& path, OutputPolicy policy)
    : path_(path), policy_(std::move(policy)) {
  if (path_.empty()) throw OutputError("output directory: no path given");
  std::error_code ec;
  const fs::path dir = resolved(path_);
  for (const std::string& input : policy_.inputs) {
    if (input.empty()) continue;
    const fs::path in = resolved(input);
    if (is_inside(dir, in) || is_inside(in, dir)) {
      const char* how = dir == in ? "is" : is_inside(in, dir) ? "holds" : "is inside";
      throw OutputError("refusing output directory '" + path_ + "': it " + std::string(how) +
                        " an input of this run ('" + input + "')");
    }
  }
  const fs::file_status st = fs::status(path_, ec);
  if (!fs::exists(st)) {
    fs::create_directories(path_, ec);
    if (ec) throw OutputError("cannot create output directory '" + path_ + "': " + ec.message());
  } else if (!fs::is_directory(st)) {
    throw OutputError("refusing output directory '" + path_ + "': it exists and is not a directory");
  } else if (!fs::exists(fs::path(path_) / kOutputMarker) && !policy_.force) {
    const bool empty = fs::is_empty(path_, ec);
    if (ec) throw OutputError("cannot read output directory '" + path_ + "': " + ec.message());
    if (!empty)
      throw OutputError("refusing output directory '" + path_ +
                        "': it is not empty and is not an odonav output directory (no " + kOutputMarker +
                        " file); choose another directory or pass --force");
  }
  const std::string marker = (fs::path(path_) / kOutputMarker).string();
  if (fs::is_symlink(fs::symlink_status(marker, ec)))
    throw OutputError("refusing output directory '" + path_ + "': its " + kOutputMarker + " is a symbolic link");
  if (!fs::exists(marker, ec))
    write_file_atomically(marker, "This directory holds the output of an odonav run; odonav may replace its files.\n");
}

std::string OutputDirectory::file(const std::string& name) const {
  const std::string p = (fs::path(path_) / name).string();
  check_output_file(p, policy_.inputs);
  return p;
}

AtomicFile::AtomicFile(const std::string& path, const std::vector<std::string>& inputs) : path_(path) {
  check_output_file(path_, inputs);
  temporary_ = path_ + ".tmp-" + std::to_string(::getpid());
  // O_EXCL with O_NOFOLLOW: a planted temporary name (or a link under it) is not followed.
  ::unlink(temporary_.c_str());
  const int fd = ::open(temporary_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0644);
  if (fd < 0) throw OutputError(system_message("cannot create", path_, errno));
  file_ = ::fdopen(fd, "wb");
  if (file_ == nullptr) {
    const int error = errno;
    ::close(fd);
    ::unlink(temporary_.c_str());
    throw OutputError(system_message("cannot open", path_, error));
  }
}

AtomicFile::~AtomicFile() {
  if (file_ != nullptr) std::fclose(file_);
  if (!committed_ && !keep_on_failure_) ::unlink(temporary_.c_str());
}

void AtomicFile::fail(const std::string& what) {
  const int error = errno;
  if (file_ != nullptr) std::fclose(file_);
  file_ = nullptr;
  if (!keep_on_failure_) ::unlink(temporary_.c_str());
  throw OutputError(system_message(what, path_, error));
}

void AtomicFile::write(const char* data, std::size_t size) {
  if (committed_ || file_ == nullptr) throw std::logic_error("AtomicFile::write after commit: '" + path_ + "'");
  if (size > 0 && std::fwrite(data, 1, size, file_) != size) fail("cannot write");
}

void AtomicFile::flush(bool sync) {
  if (committed_ || file_ == nullptr) throw std::logic_error("AtomicFile::flush after commit: '" + path_ + "'");
  if (std::fflush(file_) != 0) fail("cannot write");
  if (sync && ::fsync(::fileno(file_)) != 0) fail("cannot sync");
}

void AtomicFile::commit() {
  if (committed_ || file_ == nullptr) throw std::logic_error("AtomicFile::commit twice: '" + path_ + "'");
  if (std::fflush(file_) != 0) fail("cannot write");
  // Data on disk before the rename makes it visible: otherwise a power cut could leave the real
  // name pointing at an empty file.
  if (::fsync(::fileno(file_)) != 0) fail("cannot sync");
  const int rc = std::fclose(file_);
  file_ = nullptr;
  if (rc != 0) fail("cannot close");
  // Checked again: a link planted at the real name while we wrote is replaced, never followed
  // (rename replaces the link itself), but refusing it says what happened.
  check_output_file(path_, {});
  if (::rename(temporary_.c_str(), path_.c_str()) != 0) fail("cannot rename the complete file to this name");
  committed_ = true;
  // The rename is durable only once the directory entry is.
  const fs::path target(path_);
  const std::string dir = target.has_parent_path() ? target.parent_path().string() : std::string(".");
  const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd < 0) throw OutputError(system_message("cannot open directory", dir, errno));
  const int sync_rc = ::fsync(dfd);
  const int error = errno;
  ::close(dfd);
  if (sync_rc != 0) throw OutputError(system_message("cannot sync directory", dir, error));
}

void write_file_atomically(const std::string& path, const std::string& text, const std::vector<std::string>& inputs) {
  AtomicFile f(path, inputs);
  f.write(text);
  f.commit();
}

}  // namespace odonav
