#pragma once
// Private to odonav_io (not installed): the one parser of the dataset CSV files. LineReader reads a
// file line by line through a fixed buffer; RowReader<Sample> resolves the header and turns each data
// row into a sample with every rule of docs/DATASET.md (validation, bad-row policy, counts, logging). read_dataset (whole files) and DatasetStream / TruthStream (row by row) are
// both built on it, so there is one copy of the parsing and validation code.
#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "odonav/dataset.hpp"

namespace odonav::dataset_detail {

/// Reads a dataset file one line at a time with bounded memory: a read buffer of kReadBufferBytes
/// and, for a line that spans two reads, a copy of at most kMaxDatasetLineBytes + 1 bytes of it (a
/// longer line is counted, not stored). Refuses, naming the path, what is not a regular file and a
/// file over kMaxDatasetFileBytes (at open, and if it grows past it while being read). Skips a
/// leading UTF-8 byte-order mark.
class LineReader {
 public:
  static constexpr std::size_t kReadBufferBytes = 64 * 1024;

  explicit LineReader(const std::string& path);
  ~LineReader();
  LineReader(const LineReader&) = delete;
  LineReader& operator=(const LineReader&) = delete;

  /// The next line, without its '\n' and a '\r' before it; false at the end of the file. `line` is
  /// valid until the next call. `length_bytes` is the line's full length (without '\n' / "\r\n"):
  /// when it exceeds kMaxDatasetLineBytes, `line` holds only its first bytes (at least
  /// kMaxDatasetLineBytes of them).
  bool next(std::string_view& line, std::size_t& length_bytes);
  /// 1-based number of the line last returned (0 before the first).
  std::size_t line_number() const { return line_number_; }
  /// Bytes this reader holds for its buffers (read buffer plus the spanning-line copy): bounded by
  /// kReadBufferBytes + kMaxDatasetLineBytes + 1 whatever the length of the file.
  std::size_t buffered_bytes() const { return kReadBufferBytes + carry_.capacity(); }

 private:
  bool refill();  // false at end of file
  void append_capped(const char* data, std::size_t size);

  std::string path_;
  int fd_ = -1;
  std::unique_ptr<char[]> buffer_;
  std::size_t begin_ = 0, end_ = 0;  // unread bytes of buffer_
  std::string carry_;                // a line spanning reads, capped at kMaxDatasetLineBytes + 1
  std::uintmax_t bytes_read_ = 0;
  std::size_t line_number_ = 0;
  bool at_start_ = true;
  bool at_end_ = false;
};

/// How a RowReader reports: the policy, the report that collects bad rows in detail (may be null),
/// and whether it logs bad rows (a probe that only looks ahead does not).
struct ReadContext {
  BadRowPolicy policy = BadRowPolicy::kFail;
  DatasetReadReport* report = nullptr;
  bool log = true;
};

/// The header of one CSV file, resolved against the known columns.
struct ResolvedHeader {
  std::size_t field_count = 0;
  std::vector<std::string> names;    ///< as written (trimmed)
  std::vector<int> field_of_column;  ///< known column id -> field index, -1 if absent
  std::vector<std::string> unknown;  ///< header names not in the spec
};

/// The rows of one dataset file, one good row at a time. The constructor opens the file and reads up
/// to and including the header (throws DatasetError on a file error: not a regular file, too big, no
/// header, a bad header). next() gives the next good row; a bad row throws DatasetError under kFail,
/// or under kSkip is counted, logged (the first 10 per file, then a total when the file ends) and
/// kept in detail in context.report (the first 100 of the report). The time column is checked for a
/// unit other than seconds (docs/DATASET.md, "Time unit"): the first good row's magnitude, then the
/// median step of the first kUnitCheckRows good rows (not judged in a shorter file); a unit
/// that is not seconds is a DatasetError whatever the policy, thrown when the row that shows it is
/// read. Memory is the LineReader's.
template <typename Sample>
class RowReader {
 public:
  /// Good rows whose t steps the time-unit check looks at.
  static constexpr std::size_t kUnitCheckRows = 8;

  RowReader(const std::string& path, const ReadContext& context);

  /// The next good row; nullopt at the end of the file.
  std::optional<Sample> next();

  const std::string& path() const { return path_; }
  /// Counts so far (rows_read: the good rows parsed) and the ignored columns; complete once next()
  /// has returned nullopt.
  const FileReadReport& file_report() const { return file_report_; }
  /// Bytes held for buffering: the LineReader's and the field list of one row (at most one entry
  /// per byte of a line).
  std::size_t buffered_bytes() const { return lines_.buffered_bytes() + fields_.capacity() * sizeof(std::string_view); }

 private:
  bool read_good_row(Sample& sample);  // false at the end of the file
  void bad_row(std::size_t line, std::string column, std::string reason);
  void note_first_row(double t_s, std::size_t line, std::string_view t_text);  // the time-unit check's input
  void check_time_steps();

  std::string path_;
  ReadContext context_;
  LineReader lines_;
  ResolvedHeader header_;
  FileReadReport file_report_;
  std::vector<std::string_view> fields_;  // reused for every row
  std::optional<double> previous_t_;
  std::size_t previous_t_line_ = 0;
  // The time-unit check: t of the first good rows, until it has run.
  std::array<double, kUnitCheckRows> first_t_{};
  std::size_t first_t_count_ = 0;
  std::size_t first_row_line_ = 0;
  std::string first_t_text_;  // the first good row's t as written
  bool unit_checked_ = false;
  bool ended_ = false;
};

extern template class RowReader<OdometerSample>;
extern template class RowReader<GnssSample>;
extern template class RowReader<InsSample>;
extern template class RowReader<TruthSample>;

/// Throws the file error for fewer than two good rows in a required file (odometer.csv, gnss.csv),
/// naming how many bad rows were skipped when `with_skipped_count`.
void require_two_rows(const std::string& path, std::size_t good_rows, std::size_t bad_rows, bool with_skipped_count);

/// True when `path` exists (as anything: whether it is a regular file is LineReader's to check).
bool file_exists(const std::string& path);

}  // namespace odonav::dataset_detail
