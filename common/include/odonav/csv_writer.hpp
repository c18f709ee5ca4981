#pragma once
// A small CSV writer for odonav's output files: one header row, numbers in the shortest text that
// reads back to the same double (so outputs of two runs can be compared to the last bit), NaN and
// absent values as empty fields. Used by odonav-offline and by the pipeline's recorder alike.
#include <cstdint>
#include <cstdio>
#include <optional>
#include <string>
#include <vector>

namespace odonav {

class CsvWriter {
 public:
  /// Creates (truncates) `path` and writes the header. Throws std::runtime_error naming the path.
  CsvWriter(const std::string& path, std::vector<std::string> columns);
  ~CsvWriter();
  CsvWriter(const CsvWriter&) = delete;
  CsvWriter& operator=(const CsvWriter&) = delete;

  CsvWriter& field(double value);                 ///< NaN -> empty field.
  CsvWriter& field(const std::optional<double>& value);
  CsvWriter& field(int64_t value);
  CsvWriter& field(uint64_t value);
  CsvWriter& field(int value) { return field(static_cast<int64_t>(value)); }
  CsvWriter& field(bool value);                   ///< 1 or 0.
  CsvWriter& field(const std::string& value);     ///< must not contain ',' or a newline.
  CsvWriter& field(const char* value) { return field(std::string(value)); }
  CsvWriter& empty();
  /// Ends the row; throws std::logic_error when the row has the wrong number of fields.
  void end_row();
  /// Flushes and closes; throws std::runtime_error naming the path on an I/O error.
  void close();

  const std::string& path() const { return path_; }
  std::size_t rows() const { return rows_; }

 private:
  void separator();
  void flush_buffer();
  std::string path_;
  std::vector<std::string> columns_;
  std::FILE* file_ = nullptr;
  std::string buffer_;
  std::size_t fields_in_row_ = 0;
  std::size_t rows_ = 0;
};

}  // namespace odonav
