// The dataset reader, format v1: every validation rule of docs/DATASET.md, bad rows failed or
// skipped and counted (BadRowPolicy).
#include <spdlog/spdlog.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>

#include "dataset_internal.hpp"
#include "odonav/dataset.hpp"
#include "text_util.hpp"

namespace odonav {

namespace fs = std::filesystem;
using dataset_detail::join_path;
using dataset_detail::read_meta;
using io_detail::format_double;
using io_detail::NumberStatus;
using io_detail::trim;

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

std::string read_whole_file(const std::string& path) {
  // Only regular files: a directory gives a library error naming nothing, a FIFO or a device
  // (/dev/zero) blocks or grows memory without end.
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
  std::ifstream in(path, std::ios::binary);
  if (!in) throw DatasetError(path + ": cannot open: " + std::strerror(errno));
  // One read into a string sized from the file length: an ostringstream << rdbuf() grows its buffer
  // step by step and then copies it once more into the result (a one-hour dataset is ~90 MB).
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

using dataset_detail::read_whole_file;

constexpr std::size_t kMaxDetailedBadRows = 100;   // DatasetReadReport keeps this many in detail
constexpr std::size_t kMaxLoggedBadRowsPerFile = 10;  // then one summary line per file

struct ColumnSpec {
  const char* name;
  bool required;
};

struct RowError {
  std::string column;
  std::string reason;
};

// A field quoted in a message: at most kMaxQuotedChars, non-printable bytes as \xNN, so a huge or
// binary field cannot flood or garble the terminal.
std::string in_quotes(std::string_view text) { return "'" + io_detail::printable_excerpt(text) + "'"; }

// The fields of one data row, addressed by the id of a known column (its index in the file's
// ColumnSpec list). Accessors record the first problem and return a neutral value afterwards, so a
// row parser reads straight through and the caller checks failed() once.
class RowFields {
 public:
  RowFields(const std::vector<std::string_view>& fields, const std::vector<int>& field_of_column,
            const std::vector<ColumnSpec>& specs)
      : fields_(fields), field_of_column_(field_of_column), specs_(specs) {}

  bool has_column(int id) const { return field_of_column_[id] >= 0; }
  std::string_view text(int id) const {
    return has_column(id) ? trim(fields_[field_of_column_[id]]) : std::string_view();
  }
  bool is_empty(int id) const { return text(id).empty(); }
  bool failed() const { return failed_; }
  const RowError& error() const { return error_; }

  void fail(int id, std::string reason) {
    if (failed_) return;
    failed_ = true;
    error_ = RowError{specs_[id].name, std::move(reason)};
  }

  /// A required finite number.
  double required_double(int id) {
    if (failed_) return 0.0;
    if (is_empty(id)) {
      fail(id, "missing value");
      return 0.0;
    }
    return parse_number(id);
  }

  /// An optional finite number: absent column or empty field give nullopt.
  std::optional<double> optional_double(int id) {
    if (failed_ || is_empty(id)) return std::nullopt;
    const double value = parse_number(id);
    if (failed_) return std::nullopt;
    return value;
  }

  /// An integer in [lo, hi]; `expected` says what is allowed, for the message. Absent column or
  /// empty field give `fallback` unless `required`.
  int64_t integer(int id, bool required, int64_t fallback, int64_t lo, int64_t hi, const char* expected) {
    if (failed_) return fallback;
    if (is_empty(id)) {
      if (required) fail(id, "missing value");
      return fallback;
    }
    int64_t value = 0;
    if (io_detail::parse_int64(text(id), value) != NumberStatus::kOk || value < lo || value > hi) {
      fail(id, std::string("must be ") + expected + ": " + in_quotes(text(id)));
      return fallback;
    }
    return value;
  }

  /// Checks lo <= value <= hi for a value read from column id.
  void check_range(int id, double value, double lo, double hi, const char* what) {
    if (failed_ || (value >= lo && value <= hi)) return;
    fail(id, std::string(what) + " outside [" + io_detail::format_number(lo) + ", " +
                 io_detail::format_number(hi) + "]: " + in_quotes(text(id)));
  }

  void check_not_negative(int id, const std::optional<double>& value) {
    if (failed_ || !value || *value >= 0.0) return;
    fail(id, "negative standard deviation: " + in_quotes(text(id)));
  }

 private:
  double parse_number(int id) {
    double value = 0.0;
    switch (io_detail::parse_double(text(id), value)) {
      case NumberStatus::kOk:
        return value;
      case NumberStatus::kEmpty:
        fail(id, "missing value");
        break;
      case NumberStatus::kNotFinite:
        fail(id, "NaN or infinity is not allowed: " + in_quotes(text(id)));
        break;
      case NumberStatus::kOutOfRange:
        fail(id, "number out of range of a double: " + in_quotes(text(id)));
        break;
      case NumberStatus::kNotNumber:
        fail(id, "not a number: " + in_quotes(text(id)));
        break;
    }
    return 0.0;
  }

  const std::vector<std::string_view>& fields_;
  const std::vector<int>& field_of_column_;
  const std::vector<ColumnSpec>& specs_;
  bool failed_ = false;
  RowError error_;
};

// What every file reader shares: the policy and the report being filled.
struct ReadContext {
  BadRowPolicy policy;
  DatasetReadReport* report;  // may be null
};

// The header of one CSV file, resolved against the known columns.
struct ResolvedHeader {
  std::size_t field_count = 0;
  std::vector<std::string> names;   // as written (trimmed)
  std::vector<int> field_of_column; // known column id -> field index, -1 if absent
  std::vector<std::string> unknown; // header names not in the spec
};

ResolvedHeader resolve_header(const std::string& file, std::size_t line_no, std::string_view line,
                              const std::vector<ColumnSpec>& specs) {
  ResolvedHeader header;
  header.field_of_column.assign(specs.size(), -1);
  const std::vector<std::string_view> fields = io_detail::split_commas(line);
  header.field_count = fields.size();
  for (std::size_t i = 0; i < fields.size(); ++i) {
    const std::string name(trim(fields[i]));
    const std::string where = file + ":" + std::to_string(line_no) + ": ";
    if (name.empty()) {
      throw DatasetError(where + "empty column name in the header at position " + std::to_string(i + 1));
    }
    for (const std::string& earlier : header.names) {
      if (earlier == name) throw DatasetError(where + "column " + in_quotes(name) + " appears twice in the header");
    }
    header.names.push_back(name);
    bool known = false;
    for (std::size_t id = 0; id < specs.size(); ++id) {
      if (name == specs[id].name) {
        header.field_of_column[id] = static_cast<int>(i);
        known = true;
      }
    }
    if (!known) header.unknown.push_back(name);
  }
  for (std::size_t id = 0; id < specs.size(); ++id) {
    if (specs[id].required && header.field_of_column[id] < 0) {
      throw DatasetError(file + ":" + std::to_string(line_no) + ": required column '" + specs[id].name +
                         "' is missing (header: " + io_detail::printable_excerpt(trim(line)) + ")");
    }
  }
  return header;
}

// Reads one CSV file of the dataset. Column 0 of `specs` is always "t". parse_row turns a row's
// fields into a sample (recording any problem in the RowFields); `extra_header_check` may reject
// a header that has every required column but an inconsistent set of optional ones.
template <typename Sample>
std::vector<Sample> read_table(const std::string& path, const std::vector<ColumnSpec>& specs,
                               ReadContext& context, const std::function<Sample(RowFields&)>& parse_row,
                               const std::function<void(const ResolvedHeader&)>& extra_header_check = {}) {
  const std::string content_owner = read_whole_file(path);
  std::string_view content = content_owner;
  if (content.substr(0, 3) == "\xEF\xBB\xBF") content.remove_prefix(3);  // UTF-8 byte-order mark

  FileReadReport file_report;
  file_report.file = path;
  std::vector<Sample> samples;
  std::optional<ResolvedHeader> header;
  std::optional<double> previous_t;
  std::size_t previous_t_line = 0;

  std::size_t pos = 0;
  std::size_t line_no = 0;
  std::vector<std::string_view> fields;
  while (pos < content.size()) {
    const std::size_t newline = content.find('\n', pos);
    std::string_view line =
        content.substr(pos, newline == std::string_view::npos ? std::string_view::npos : newline - pos);
    pos = newline == std::string_view::npos ? content.size() : newline + 1;
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);  // CRLF files
    if (line.size() > kMaxDatasetLineBytes) {
      // Not split into fields: one 50 MB line of commas would otherwise take a gigabyte.
      const BadRow bad{path, line_no, "",
                       "line of " + std::to_string(line.size()) + " bytes, longer than the limit of " +
                           std::to_string(kMaxDatasetLineBytes) + " (starts " + in_quotes(line) + ")"};
      if (!header || context.policy == BadRowPolicy::kFail) throw DatasetError(bad.message());
      ++file_report.rows_bad;
      if (file_report.rows_bad <= kMaxLoggedBadRowsPerFile) spdlog::warn("skipping bad row: {}", bad.message());
      if (context.report && context.report->bad_rows.size() < kMaxDetailedBadRows) context.report->bad_rows.push_back(bad);
      continue;
    }
    const std::string_view trimmed = trim(line);
    if (trimmed.empty() || trimmed.front() == '#') continue;

    if (!header) {
      header = resolve_header(path, line_no, line, specs);
      if (extra_header_check) extra_header_check(*header);
      if (!header->unknown.empty()) {
        file_report.ignored_columns = header->unknown;
        std::vector<std::string> names_in_quotes;
        for (const std::string& name : header->unknown) names_in_quotes.push_back(in_quotes(name));
        spdlog::warn("{}: ignoring unknown column(s) {}", path, io_detail::join(names_in_quotes));
      }
      continue;
    }

    io_detail::split_commas(line, fields);  // reuses one vector for every row of the file
    std::optional<RowError> error;
    Sample sample{};
    if (fields.size() < header->field_count) {
      // A short row (typically a truncated last line): name the first column that has no field.
      error = RowError{header->names[fields.size()], "missing value: the row has " + std::to_string(fields.size()) +
                                                          " fields, the header " +
                                                          std::to_string(header->field_count)};
    } else if (fields.size() > header->field_count) {
      error = RowError{"", "the row has " + std::to_string(fields.size()) + " fields, the header " +
                               std::to_string(header->field_count)};
    } else {
      RowFields row(fields, header->field_of_column, specs);
      sample = parse_row(row);
      if (!row.failed() && previous_t && !(sample.t_s > *previous_t)) {
        row.fail(0, "t does not increase: " + format_double(sample.t_s) + " after " + format_double(*previous_t) +
                        " (line " + std::to_string(previous_t_line) + ")");
      }
      if (row.failed()) error = row.error();
    }

    if (!error) {
      previous_t = sample.t_s;
      previous_t_line = line_no;
      samples.push_back(sample);
      continue;
    }
    const BadRow bad{path, line_no, error->column, error->reason};
    if (context.policy == BadRowPolicy::kFail) throw DatasetError(bad.message());
    ++file_report.rows_bad;
    if (file_report.rows_bad <= kMaxLoggedBadRowsPerFile) spdlog::warn("skipping bad row: {}", bad.message());
    if (context.report && context.report->bad_rows.size() < kMaxDetailedBadRows) {
      context.report->bad_rows.push_back(bad);
    }
  }
  if (!header) throw DatasetError(path + ": no header line (the file is empty or holds only comments)");
  if (file_report.rows_bad > kMaxLoggedBadRowsPerFile) {
    spdlog::warn("{}: {} bad rows skipped in all", path, file_report.rows_bad);
  }
  file_report.rows_read = samples.size();
  if (context.report) context.report->files.push_back(file_report);
  return samples;
}

// Column ids, in the order of the spec lists below.
namespace odo {
enum { kT, kPulses, kDirection };
const std::vector<ColumnSpec> kSpecs{{"t", true}, {"pulses", true}, {"direction", false}};
}  // namespace odo
namespace gnss {
enum { kT, kLat, kLon, kHeight, kVe, kVn, kVu, kPosStd, kVelStd, kFix };
const std::vector<ColumnSpec> kSpecs{{"t", true},        {"lat_deg", true},    {"lon_deg", true},
                                     {"height_m", true}, {"ve", true},         {"vn", true},
                                     {"vu", true},       {"pos_std_m", false}, {"vel_std_mps", false},
                                     {"fix", false}};
}  // namespace gnss
namespace ins {
enum { kT, kHeading, kPitch, kRoll, kVe, kVn, kVu };
const std::vector<ColumnSpec> kSpecs{{"t", true},  {"heading_deg", true}, {"pitch_deg", true},
                                     {"roll_deg", true}, {"ve", false},    {"vn", false},
                                     {"vu", false}};
}  // namespace ins
namespace truth {
enum { kT, kLat, kLon, kHeight, kHeading, kPitch, kRoll, kK, kDistance };
const std::vector<ColumnSpec> kSpecs{{"t", true},           {"lat_deg", false}, {"lon_deg", false},
                                     {"height_m", false},   {"heading_deg", false},  {"pitch_deg", false},
                                     {"roll_deg", false},   {"k_true", false},       {"distance_m", false}};
}  // namespace truth

OdometerSample parse_odometer_row(RowFields& row) {
  OdometerSample s;
  s.t_s = row.required_double(odo::kT);
  s.pulses = static_cast<uint32_t>(
      row.integer(odo::kPulses, true, 0, 0, 4294967295LL, "an integer in [0, 4294967295]"));
  s.direction = static_cast<int>(row.integer(odo::kDirection, false, 1, -1, 1, "-1, 0 or 1"));
  return s;
}

GnssSample parse_gnss_row(RowFields& row) {
  GnssSample s;
  s.t_s = row.required_double(gnss::kT);
  const double lat_deg = row.required_double(gnss::kLat);
  row.check_range(gnss::kLat, lat_deg, -90.0, 90.0, "latitude");
  const double lon_deg = row.required_double(gnss::kLon);
  row.check_range(gnss::kLon, lon_deg, -180.0, 180.0, "longitude");
  const double height_m = row.required_double(gnss::kHeight);
  row.check_range(gnss::kHeight, height_m, kMinHeight_m, kMaxHeight_m, "height (m) of a land vehicle");
  s.position = Geodetic{deg_to_rad(lat_deg), deg_to_rad(lon_deg), height_m};
  s.vel_enu_mps.x() = row.required_double(gnss::kVe);
  s.vel_enu_mps.y() = row.required_double(gnss::kVn);
  s.vel_enu_mps.z() = row.required_double(gnss::kVu);
  for (int id : {gnss::kVe, gnss::kVn, gnss::kVu})
    row.check_range(id, s.vel_enu_mps[id - gnss::kVe], -kMaxVelocityComponent_mps, kMaxVelocityComponent_mps,
                    "velocity (m/s) of a land vehicle");
  s.pos_std_m = row.optional_double(gnss::kPosStd);
  row.check_not_negative(gnss::kPosStd, s.pos_std_m);
  s.vel_std_mps = row.optional_double(gnss::kVelStd);
  row.check_not_negative(gnss::kVelStd, s.vel_std_mps);
  s.fix = static_cast<int>(row.integer(gnss::kFix, false, 1, 0, 9, "an integer 0..9"));
  return s;
}

InsSample parse_ins_row(RowFields& row) {
  InsSample s;
  s.t_s = row.required_double(ins::kT);
  const double heading_deg = row.required_double(ins::kHeading);
  row.check_range(ins::kHeading, heading_deg, -kMaxHeadingMagnitude_deg, kMaxHeadingMagnitude_deg, "heading");
  s.attitude.heading_rad = deg_to_rad(heading_deg);
  const double pitch_deg = row.required_double(ins::kPitch);
  row.check_range(ins::kPitch, pitch_deg, -90.0, 90.0, "pitch");
  s.attitude.pitch_rad = deg_to_rad(pitch_deg);
  const double roll_deg = row.required_double(ins::kRoll);
  row.check_range(ins::kRoll, roll_deg, -kMaxRollMagnitude_deg, kMaxRollMagnitude_deg, "roll");
  s.attitude.roll_rad = deg_to_rad(roll_deg);
  // The three velocity components come together: all empty (no velocity) or all given.
  const bool any = !row.is_empty(ins::kVe) || !row.is_empty(ins::kVn) || !row.is_empty(ins::kVu);
  if (any) {
    Eigen::Vector3d v;
    v.x() = row.required_double(ins::kVe);
    v.y() = row.required_double(ins::kVn);
    v.z() = row.required_double(ins::kVu);
    for (int id : {ins::kVe, ins::kVn, ins::kVu})
      row.check_range(id, v[id - ins::kVe], -kMaxVelocityComponent_mps, kMaxVelocityComponent_mps,
                      "velocity (m/s) of a land vehicle");
    s.vel_enu_mps = v;
  }
  return s;
}

void check_ins_header(const std::string& path, const ResolvedHeader& header) {
  const int present = (header.field_of_column[ins::kVe] >= 0) + (header.field_of_column[ins::kVn] >= 0) +
                      (header.field_of_column[ins::kVu] >= 0);
  if (present != 0 && present != 3) {
    throw DatasetError(path + ": the velocity columns ve, vn, vu must be all present or all absent");
  }
}

TruthSample parse_truth_row(RowFields& row) {
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  TruthSample s;
  s.t_s = row.required_double(truth::kT);
  const auto value_or_nan = [&](int id) { return row.optional_double(id).value_or(kNaN); };
  const double lat_deg = value_or_nan(truth::kLat);
  if (!std::isnan(lat_deg)) row.check_range(truth::kLat, lat_deg, -90.0, 90.0, "latitude");
  const double lon_deg = value_or_nan(truth::kLon);
  if (!std::isnan(lon_deg)) row.check_range(truth::kLon, lon_deg, -180.0, 180.0, "longitude");
  const double height_m = value_or_nan(truth::kHeight);
  if (!std::isnan(height_m)) row.check_range(truth::kHeight, height_m, kMinHeight_m, kMaxHeight_m, "height (m) of a land vehicle");
  s.position = Geodetic{deg_to_rad(lat_deg), deg_to_rad(lon_deg), height_m};
  const double heading_deg = value_or_nan(truth::kHeading);
  if (!std::isnan(heading_deg))
    row.check_range(truth::kHeading, heading_deg, -kMaxHeadingMagnitude_deg, kMaxHeadingMagnitude_deg, "heading");
  s.attitude.heading_rad = deg_to_rad(heading_deg);
  const double pitch_deg = value_or_nan(truth::kPitch);
  if (!std::isnan(pitch_deg)) row.check_range(truth::kPitch, pitch_deg, -90.0, 90.0, "pitch");
  s.attitude.pitch_rad = deg_to_rad(pitch_deg);
  s.attitude.roll_rad = deg_to_rad(value_or_nan(truth::kRoll));
  s.k_true_m_per_pulse = value_or_nan(truth::kK);
  s.distance_m = value_or_nan(truth::kDistance);
  return s;
}

void require_two_rows(const std::string& path, std::size_t rows, const ReadContext& context) {
  if (rows >= 2) return;
  std::string text = path + ": " + std::to_string(rows) + " good row(s), at least 2 are needed";
  if (context.report && !context.report->files.empty() && context.report->files.back().rows_bad > 0) {
    text += " (" + std::to_string(context.report->files.back().rows_bad) + " bad row(s) skipped)";
  }
  throw DatasetError(text);
}

}  // namespace

Dataset read_dataset(const std::string& dir, BadRowPolicy policy, DatasetReadReport* report) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw DatasetError(dir + ": dataset directory does not exist");
  ReadContext context{policy, report};
  Dataset dataset;

  const auto require_file = [&](const std::string& path) {
    if (!fs::exists(path, ec)) throw DatasetError(path + ": required file is missing");
  };

  const std::string odometer_path = join_path(dir, "odometer.csv");
  require_file(odometer_path);
  dataset.odometer =
      read_table<OdometerSample>(odometer_path, odo::kSpecs, context, parse_odometer_row);
  require_two_rows(odometer_path, dataset.odometer.size(), context);

  const std::string gnss_path = join_path(dir, "gnss.csv");
  require_file(gnss_path);
  dataset.gnss = read_table<GnssSample>(gnss_path, gnss::kSpecs, context, parse_gnss_row);
  require_two_rows(gnss_path, dataset.gnss.size(), context);

  const std::string ins_path = join_path(dir, "ins.csv");
  if (fs::exists(ins_path, ec)) {
    dataset.ins = read_table<InsSample>(ins_path, ins::kSpecs, context, parse_ins_row,
                                        [&](const ResolvedHeader& h) { check_ins_header(ins_path, h); });
  }
  const std::string truth_path = join_path(dir, "truth.csv");
  if (fs::exists(truth_path, ec)) {
    dataset.truth = read_table<TruthSample>(truth_path, truth::kSpecs, context, parse_truth_row);
  }
  const std::string meta_path = join_path(dir, "meta.json");
  if (fs::exists(meta_path, ec)) dataset.meta = read_meta(meta_path);
  return dataset;
}

}  // namespace odonav
