#pragma once
// A scratch folder per test (gtest): a fresh directory under the system temp dir named after the
// running test and this process, removed at the end.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>
#include <system_error>

#include "text_files.hpp"

namespace odonav::test {

/// A fresh directory under the system temp dir, named after the running test; removed on exit.
class ScratchDir {
 public:
  ScratchDir() {
    const ::testing::TestInfo* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = std::filesystem::temp_directory_path() /
            ("odonav-" + std::string(info->test_suite_name()) + "-" + info->name() + "-" + std::to_string(::getpid()));
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~ScratchDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;

  const std::filesystem::path& path() const { return path_; }
  std::string str() const { return path_.string(); }
  std::string file(const std::string& name) const { return (path_ / name).string(); }
  std::string operator/(const std::string& name) const { return file(name); }
  /// Writes `content` byte for byte to <dir>/<name>.
  void write(const std::string& name, const std::string& content) const { write_text(path_ / name, content); }
  /// The content of <dir>/<name> ("" if it cannot be read).
  std::string read(const std::string& name) const { return read_text(path_ / name); }

 private:
  std::filesystem::path path_;
};

}  // namespace odonav::test
