// The dataset reader, format v1: whole files into vectors through the one row parser
// (dataset_rows.cpp: every validation rule of docs/DATASET.md, bad rows failed or skipped and
// counted), plus the small shared pieces (policy parsing, BadRow messages, read_whole_file for
// meta.json).
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>

#include "dataset_internal.hpp"
#include "dataset_rows.hpp"
#include "odonav/dataset.hpp"

namespace odonav {

namespace fs = std::filesystem;
using dataset_detail::join_path;
using dataset_detail::read_meta;

BadRowPolicy parse_bad_row_policy(const std::string& text) {
  if (text == "fail") return BadRowPolicy::kFail;
  if (text == "skip") return BadRowPolicy::kSkip;
  throw std::invalid_argument("bad-row policy '" + text + "': must be fail or skip");
}

std::string BadRow::message() const {
  std::string text = file + ":" + std::to_string(line) + ": ";
  if (!column.empty()) text += "column '" + column + "': ";
  return text + reason;
}

std::size_t DatasetReadReport::total_bad() const {
  std::size_t total = 0;
  for (const FileReadReport& f : files) total += f.rows_bad;
  return total;
}

namespace dataset_detail {

void check_dataset_file(const std::string& path) {
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (ec && !fs::exists(st)) throw DatasetError(path + ": cannot open: " + ec.message());
  if (fs::is_directory(st)) throw DatasetError(path + ": is a directory, not a dataset file");
  if (!fs::is_regular_file(st))
    throw DatasetError(path + ": not a regular file (a FIFO, socket or device): dataset files must be regular files");
  const std::uintmax_t bytes = fs::file_size(path, ec);
  if (!ec && bytes > kMaxDatasetFileBytes)
    throw DatasetError(path + ": " + std::to_string(bytes) + " bytes, more than the limit of " +
                       std::to_string(kMaxDatasetFileBytes) + " bytes per dataset file: split the recording");
}

std::string read_whole_file(const std::string& path) {
  check_dataset_file(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw DatasetError(path + ": cannot open: " + std::strerror(errno));
  // One read into a string sized from the file length: an ostringstream << rdbuf() grows its buffer
  // step by step and then copies it once more into the result.
  std::string content;
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  if (size > 0) {
    content.resize(static_cast<std::size_t>(size));
    in.seekg(0, std::ios::beg);
    in.read(content.data(), size);
    content.resize(static_cast<std::size_t>(in.gcount()));
  }
  if (in.bad()) throw DatasetError(path + ": read error");
  // A file that grew while being read keeps the rest, up to the limit.
  in.clear();
  char buffer[1 << 16];
  while (in.read(buffer, sizeof buffer) || in.gcount() > 0) {
    content.append(buffer, static_cast<std::size_t>(in.gcount()));
    if (content.size() > kMaxDatasetFileBytes)
      throw DatasetError(path + ": grew past the limit of " + std::to_string(kMaxDatasetFileBytes) +
                         " bytes per dataset file while being read");
  }
  return content;
}

}  // namespace dataset_detail

namespace {

// Every good row of one file, read through the one parser (dataset_rows.cpp); the file's counts go
// to the report once the file has been read.
template <typename Sample>
std::vector<Sample> read_table(const std::string& path, const dataset_detail::ReadContext& context) {
  dataset_detail::RowReader<Sample> rows(path, context);
  std::vector<Sample> samples;
  while (std::optional<Sample> sample = rows.next()) samples.push_back(*sample);
  if (context.report) context.report->files.push_back(rows.file_report());
  return samples;
}

}  // namespace

Dataset read_dataset(const std::string& dir, BadRowPolicy policy, DatasetReadReport* report) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw DatasetError(dir + ": dataset directory does not exist");
  const dataset_detail::ReadContext context{policy, report, true};
  Dataset dataset;

  const auto require_file = [&](const std::string& path) {
    if (!fs::exists(path, ec)) throw DatasetError(path + ": required file is missing");
  };
  // The skipped-row count in the "at least 2" message comes from the report, when there is one.
  const auto bad_rows_of_last_file = [&]() -> std::size_t {
    return report && !report->files.empty() ? report->files.back().rows_bad : 0;
  };

  const std::string odometer_path = join_path(dir, "odometer.csv");
  require_file(odometer_path);
  dataset.odometer = read_table<OdometerSample>(odometer_path, context);
  dataset_detail::require_two_rows(odometer_path, dataset.odometer.size(), bad_rows_of_last_file(), report != nullptr);

  const std::string gnss_path = join_path(dir, "gnss.csv");
  require_file(gnss_path);
  dataset.gnss = read_table<GnssSample>(gnss_path, context);
  dataset_detail::require_two_rows(gnss_path, dataset.gnss.size(), bad_rows_of_last_file(), report != nullptr);

  const std::string ins_path = join_path(dir, "ins.csv");
  if (fs::exists(ins_path, ec)) dataset.ins = read_table<InsSample>(ins_path, context);
  const std::string truth_path = join_path(dir, "truth.csv");
  if (fs::exists(truth_path, ec)) dataset.truth = read_table<TruthSample>(truth_path, context);
  const std::string meta_path = join_path(dir, "meta.json");
  if (fs::exists(meta_path, ec)) dataset.meta = read_meta(meta_path);
  return dataset;
}

}  // namespace odonav
