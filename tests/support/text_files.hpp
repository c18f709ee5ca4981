#pragma once
// Whole text files for the tests and the benchmarks (no gtest in here): read, write, and the last
// lines of a log for a failure message.
#include <cstddef>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace odonav::test {

/// The whole content of a file ("" if it cannot be read).
inline std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

/// Writes `text` byte for byte to `path`, replacing what was there.
inline void write_text(const std::filesystem::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
}

/// The last `lines` lines of a file, each indented with "  | " (for a failure message).
inline std::string tail_of(const std::filesystem::path& path, std::size_t lines = 30) {
  std::vector<std::string> all;
  std::istringstream in(read_text(path));
  for (std::string l; std::getline(in, l);) all.push_back(l);
  std::string out;
  for (std::size_t i = all.size() > lines ? all.size() - lines : 0; i < all.size(); ++i) out += "  | " + all[i] + "\n";
  return out;
}

}  // namespace odonav::test
