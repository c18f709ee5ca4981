#pragma once
// odonav's one CSV writer: one header row, numbers in the shortest text that reads back to the same
// double (std::to_chars round-trip form, so outputs of two runs can be compared to the last bit), NaN
// and absent values as empty fields, no quoting (fields never hold ',' or a newline). Used by the
// output files of odonav-offline and of the pipeline's recorder (odonav/results/output_files.hpp)
// and by the dataset writer (odonav/dataset_writer.hpp, docs/DATASET.md), row by row to temporaries
// that take their real names only when the whole dataset is written.
// A file writer writes through AtomicFile (odonav/safe_output.hpp): every write checked, the real
// name only for a complete, closed file; a writer destroyed without close() (an exception, a failed
// run) leaves the previous file untouched. A killed process leaves its rows in `<path>.tmp-<pid>`.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace odonav {

class CsvWriter {
 public:
  /// Tag of the in-memory constructor.
  struct InMemory {};

  /// Opens `<path>.tmp-<pid>` and writes the header; `path` itself is replaced at close(). Throws
  /// OutputError (a std::runtime_error) naming the path, also when `path` is a symbolic link, a
  /// directory or one of `inputs` (check_output_file).
  CsvWriter(const std::string& path, std::vector<std::string> columns, const std::vector<std::string>& inputs = {});
  /// Writes nothing to disk: the whole file (header and rows) accumulates in text(). `path` only
  /// names the file in messages (and is what the caller writes text() to later).
  CsvWriter(InMemory, const std::string& path, std::vector<std::string> columns);
  ~CsvWriter();
  CsvWriter(const CsvWriter&) = delete;
  CsvWriter& operator=(const CsvWriter&) = delete;

  CsvWriter& field(double value);  ///< NaN -> empty field.
  CsvWriter& field(const std::optional<double>& value);
  CsvWriter& field(int64_t value);
  CsvWriter& field(uint64_t value);
  CsvWriter& field(int value) { return field(static_cast<int64_t>(value)); }
  CsvWriter& field(bool value);                ///< 1 or 0.
  CsvWriter& field(const std::string& value);  ///< must not contain ',' or a newline.
  CsvWriter& field(const char* value) { return field(std::string(value)); }
  CsvWriter& empty();
  /// Ends the row; throws std::logic_error when the row has the wrong number of fields.
  void end_row();
  /// Appends `rows` complete rows already in this file's format (`text`: each ends with '\n', none
  /// is the header), e.g. the rows of an unfinished recording carried over into a new file.
  void append_rows(const std::string& text, std::size_t rows);
  /// Writes every ended row to the temporary file, so that a killed process leaves them there;
  /// `sync` also forces them to the disk (fsync), against a power cut. OutputError on failure.
  void flush(bool sync = false);
  /// A file writer destroyed without close(), or failing, leaves its temporary with the rows
  /// written so far (AtomicFile::keep_on_failure) instead of removing it.
  void keep_on_failure();
  /// Flushes, closes and renames the complete file to `path`; throws OutputError naming the path on
  /// an I/O error (then `path` keeps its previous content). Does nothing for an in-memory writer.
  void close();

  const std::string& path() const { return path_; }
  std::size_t rows() const { return rows_; }
  /// Bytes reserved for text not yet written: a file writer writes its buffer out once it passes
  /// 64 KiB, so this stays below about twice that plus one row however many rows are written; an
  /// in-memory writer holds the whole file.
  std::size_t buffer_capacity_bytes() const { return buffer_.capacity(); }
  /// The text of an in-memory writer so far (header, then every ended row). Throws
  /// std::logic_error for a file writer (its text is on disk).
  const std::string& text() const;

 private:
  void separator();
  void flush_buffer();
  std::string path_;
  std::vector<std::string> columns_;
  std::unique_ptr<class AtomicFile> file_;
  bool in_memory_ = false;
  std::string buffer_;  ///< file writer: not yet written; in-memory writer: the whole text.
  std::size_t fields_in_row_ = 0;
  std::size_t rows_ = 0;
};

}  // namespace odonav
