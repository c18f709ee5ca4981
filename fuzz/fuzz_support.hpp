#pragma once
// What the fuzz targets share: a private scratch directory per fuzzing process (the readers under
// test take file paths, so each input is written to a file there first), and splitting one fuzz
// input into several file images.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace odonav::fuzz {

/// A directory created once per process under $TMPDIR (or /tmp), removed at exit. Throws
/// std::runtime_error when it cannot be created (an environment problem, not a finding).
const std::string& scratch_dir();

/// Writes `bytes` to `path` exactly (binary, truncating). Throws std::runtime_error on failure.
void write_file(const std::string& path, std::string_view bytes);

/// Splits data[0..size) at every NUL byte into at most max_parts parts; the last part keeps any
/// further NULs. "a\0b" -> {"a", "b"}; "" -> {""}.
std::vector<std::string_view> split_at_nul(const uint8_t* data, std::size_t size, std::size_t max_parts);

}  // namespace odonav::fuzz
