#include "odonav/csv_writer.hpp"

#include <charconv>
#include <cmath>
#include <stdexcept>

#include "odonav/safe_output.hpp"
#include "odonav/shortest_double.hpp"
#include "text_util.hpp"

namespace odonav {

CsvWriter::CsvWriter(const std::string& path, std::vector<std::string> columns, const std::vector<std::string>& inputs)
    : CsvWriter(InMemory{}, path, std::move(columns)) {
  in_memory_ = false;
  file_ = std::make_unique<AtomicFile>(path, inputs);
}

CsvWriter::CsvWriter(InMemory, const std::string& path, std::vector<std::string> columns)
    : path_(path), columns_(std::move(columns)), in_memory_(true) {
  for (std::size_t i = 0; i < columns_.size(); ++i) {
    if (i) buffer_ += ',';
    buffer_ += columns_[i];
  }
  buffer_ += '\n';
}

const std::string& CsvWriter::text() const {
  if (!in_memory_) throw std::logic_error(path_ + ": text() of a CsvWriter that writes to a file");
  return buffer_;
}

// Without close() the AtomicFile discards its temporary: a half-written file never takes the name.
CsvWriter::~CsvWriter() = default;

void CsvWriter::separator() {
  if (fields_in_row_++) buffer_ += ',';
}

CsvWriter& CsvWriter::field(double value) {
  // The separator and the same shortest round-trip text as io_detail::format_double, appended at
  // once: this is the hottest line of odonav-offline's output stage (and of the dataset writer).
  char text[kShortestDoubleMaxChars + 1];
  char* end = text;
  if (fields_in_row_++) *end++ = ',';
  if (std::isfinite(value)) end = write_shortest_double(end, value);
  buffer_.append(text, static_cast<std::size_t>(end - text));
  return *this;
}

CsvWriter& CsvWriter::field(const std::optional<double>& value) { return value ? field(*value) : empty(); }

CsvWriter& CsvWriter::field(int64_t value) {
  separator();
  char text[24];
  buffer_.append(text, std::to_chars(text, text + sizeof text, value).ptr);
  return *this;
}

CsvWriter& CsvWriter::field(uint64_t value) {
  separator();
  char text[24];
  buffer_.append(text, std::to_chars(text, text + sizeof text, value).ptr);
  return *this;
}

CsvWriter& CsvWriter::field(bool value) {
  separator();
  buffer_ += value ? '1' : '0';
  return *this;
}

CsvWriter& CsvWriter::field(const std::string& value) {
  separator();
  buffer_ += value;
  return *this;
}

CsvWriter& CsvWriter::empty() {
  separator();
  return *this;
}

void CsvWriter::end_row() {
  if (fields_in_row_ != columns_.size())
    throw std::logic_error(path_ + ": row " + std::to_string(rows_ + 1) + " has " + std::to_string(fields_in_row_) +
                           " fields, header has " + std::to_string(columns_.size()));
  buffer_ += '\n';
  fields_in_row_ = 0;
  ++rows_;
  if (!in_memory_ && buffer_.size() > (1u << 16)) flush_buffer();
}

void CsvWriter::append_rows(const std::string& text, std::size_t rows) {
  if (fields_in_row_ != 0) throw std::logic_error(path_ + ": append_rows inside a row");
  if (!text.empty() && text.back() != '\n') throw std::logic_error(path_ + ": append_rows of an incomplete row");
  buffer_ += text;
  rows_ += rows;
  if (!in_memory_ && buffer_.size() > (1u << 16)) flush_buffer();
}

void CsvWriter::keep_on_failure() {
  if (file_) file_->keep_on_failure();
}

void CsvWriter::flush(bool sync) {
  if (!file_) return;
  flush_buffer();
  file_->flush(sync);
}

void CsvWriter::flush_buffer() {
  if (!file_ || buffer_.empty()) return;
  file_->write(buffer_);  // throws OutputError naming the path
  buffer_.clear();        // keeps its capacity: the next rows reuse it
}

void CsvWriter::close() {
  if (!file_) return;
  flush_buffer();
  const std::unique_ptr<AtomicFile> file = std::move(file_);
  file->commit();
}

}  // namespace odonav
