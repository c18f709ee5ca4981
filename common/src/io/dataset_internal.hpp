#pragma once
// Private helpers of the dataset reader, writer and meta.json code (dataset_reader.cpp,
// dataset_writer.cpp, dataset_meta.cpp); not installed, not included outside common/src/io.
// The format itself: docs/DATASET.md.
#include <filesystem>
#include <string>

#include "odonav/dataset.hpp"

namespace odonav::dataset_detail {

/// dir/file as one path string.
inline std::string join_path(const std::string& dir, const char* file) {
  return (std::filesystem::path(dir) / file).string();
}

/// The whole content of a file, in one read (meta.json; the CSV files are read line by line by
/// dataset_rows.hpp's LineReader). Throws DatasetError naming the path when it cannot be opened or
/// read.
/// A dataset file may be read: it exists, is a regular file (a directory gives a library error naming
/// nothing, a FIFO or a device such as /dev/zero blocks or never ends) and is within
/// kMaxDatasetFileBytes. Throws DatasetError naming the path and the problem.
void check_dataset_file(const std::string& path);
std::string read_whole_file(const std::string& path);

/// Reads meta.json (every key optional; unknown keys kept in raw_json). Throws DatasetError naming
/// the path and the key on malformed JSON or a key of the wrong type.
DatasetMeta read_meta(const std::string& path);

/// The text of meta.json for `meta`: the unknown keys of meta.raw_json carried through, the known
/// keys from the struct. `path` names the file in errors. Throws DatasetError on a non-finite number
/// or a malformed raw_json.
std::string meta_json(const std::string& path, const DatasetMeta& meta);

}  // namespace odonav::dataset_detail
