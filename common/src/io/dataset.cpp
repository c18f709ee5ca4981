// The odonav dataset directory, format v1: reader with every validation rule of docs/DATASET.md, and a
// writer whose output reads back to exactly the values it was given.
#include "odonav/dataset.hpp"

#include <spdlog/spdlog.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <sstream>

#include "text_util.hpp"

namespace odonav {

namespace fs = std::filesystem;
using io_detail::format_degrees_of;
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

namespace {

constexpr std::size_t kMaxDetailedBadRows = 100;   // DatasetReadReport keeps this many in detail
constexpr std::size_t kMaxLoggedBadRowsPerFile = 10;  // then one summary line per file

// ---------------------------------------------------------------------------------------------
// Reading
// ---------------------------------------------------------------------------------------------

struct ColumnSpec {
  const char* name;
  bool required;
};

struct RowError {
  std::string column;
  std::string reason;
};

std::string in_quotes(std::string_view text) { return "'" + std::string(text) + "'"; }

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
      if (earlier == name) throw DatasetError(where + "column '" + name + "' appears twice in the header");
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
                         "' is missing (header: " + std::string(trim(line)) + ")");
    }
  }
  return header;
}

std::string read_whole_file(const std::string& path) {
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
  // A file that grew while being read (or is not seekable) keeps the rest.
  in.clear();
  std::ostringstream rest;
  rest << in.rdbuf();
  content += rest.str();
  return content;
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
  s.position = Geodetic{deg_to_rad(lat_deg), deg_to_rad(lon_deg), row.required_double(gnss::kHeight)};
  s.vel_enu_mps.x() = row.required_double(gnss::kVe);
  s.vel_enu_mps.y() = row.required_double(gnss::kVn);
  s.vel_enu_mps.z() = row.required_double(gnss::kVu);
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
  s.attitude.heading_rad = deg_to_rad(row.required_double(ins::kHeading));
  const double pitch_deg = row.required_double(ins::kPitch);
  row.check_range(ins::kPitch, pitch_deg, -90.0, 90.0, "pitch");
  s.attitude.pitch_rad = deg_to_rad(pitch_deg);
  s.attitude.roll_rad = deg_to_rad(row.required_double(ins::kRoll));
  // The three velocity components come together: all empty (no velocity) or all given.
  const bool any = !row.is_empty(ins::kVe) || !row.is_empty(ins::kVn) || !row.is_empty(ins::kVu);
  if (any) {
    Eigen::Vector3d v;
    v.x() = row.required_double(ins::kVe);
    v.y() = row.required_double(ins::kVn);
    v.z() = row.required_double(ins::kVu);
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
  s.position = Geodetic{deg_to_rad(lat_deg), deg_to_rad(lon_deg), value_or_nan(truth::kHeight)};
  s.attitude.heading_rad = deg_to_rad(value_or_nan(truth::kHeading));
  const double pitch_deg = value_or_nan(truth::kPitch);
  if (!std::isnan(pitch_deg)) row.check_range(truth::kPitch, pitch_deg, -90.0, 90.0, "pitch");
  s.attitude.pitch_rad = deg_to_rad(pitch_deg);
  s.attitude.roll_rad = deg_to_rad(value_or_nan(truth::kRoll));
  s.k_true_m_per_pulse = value_or_nan(truth::kK);
  s.distance_m = value_or_nan(truth::kDistance);
  return s;
}

// Reads a JSON value at a dotted key path into `out` when present and not null.
void read_meta_string(const nlohmann::json& object, const char* key, const std::string& path, std::string& out) {
  const auto it = object.find(key);
  if (it == object.end() || it->is_null()) return;
  if (!it->is_string()) throw DatasetError(path + ": key '" + key + "' must be a string");
  out = it->get<std::string>();
}

std::optional<double> read_meta_number(const nlohmann::json& root, const char* section, const char* key,
                                       const std::string& path) {
  const auto sec = root.find(section);
  if (sec == root.end() || sec->is_null()) return std::nullopt;
  if (!sec->is_object()) throw DatasetError(path + ": key '" + section + "' must be an object");
  const auto it = sec->find(key);
  if (it == sec->end() || it->is_null()) return std::nullopt;
  if (!it->is_number()) {
    throw DatasetError(path + ": key '" + section + "." + key + "' must be a number");
  }
  const double value = it->get<double>();
  if (!std::isfinite(value)) throw DatasetError(path + ": key '" + section + "." + key + "' is not finite");
  return value;
}

DatasetMeta read_meta(const std::string& path) {
  DatasetMeta meta;
  meta.raw_json = read_whole_file(path);
  nlohmann::json root;
  try {
    root = nlohmann::json::parse(meta.raw_json);
  } catch (const nlohmann::json::parse_error& e) {
    // e.what() carries the parser's position ("at line 3, column 5"); byte is the offset.
    throw DatasetError(path + ": malformed JSON (byte " + std::to_string(e.byte) + "): " + e.what());
  }
  if (!root.is_object()) throw DatasetError(path + ": the top level must be a JSON object");
  read_meta_string(root, "format", path, meta.format);
  read_meta_string(root, "vehicle_id", path, meta.vehicle_id);
  read_meta_string(root, "description", path, meta.description);
  meta.k_nominal_m_per_pulse = read_meta_number(root, "odometer", "k_nominal_m_per_pulse", path);
  meta.truth_misalignment_heading_deg = read_meta_number(root, "truth", "misalignment_heading_deg", path);
  meta.truth_misalignment_pitch_deg = read_meta_number(root, "truth", "misalignment_pitch_deg", path);
  if (root.contains("gnss") && root["gnss"].is_object() && root["gnss"].contains("lever_arm_m")) {
    const nlohmann::json& arm = root["gnss"]["lever_arm_m"];
    if (!arm.is_array() || arm.size() != 3 || !arm[0].is_number() || !arm[1].is_number() || !arm[2].is_number())
      throw DatasetError(path + ": key 'gnss.lever_arm_m' must be an array of three numbers [x, y, z] in metres");
    meta.gnss_lever_arm_m = Eigen::Vector3d(arm[0].get<double>(), arm[1].get<double>(), arm[2].get<double>());
    if (!meta.gnss_lever_arm_m->allFinite()) throw DatasetError(path + ": key 'gnss.lever_arm_m' is not finite");
  }
  if (meta.format != "odonav-dataset/1") {
    spdlog::warn("{}: format '{}' is not 'odonav-dataset/1'; reading it as format v1", path, meta.format);
  }
  return meta;
}

void require_two_rows(const std::string& path, std::size_t rows, const ReadContext& context) {
  if (rows >= 2) return;
  std::string text = path + ": " + std::to_string(rows) + " good row(s), at least 2 are needed";
  if (context.report && !context.report->files.empty() && context.report->files.back().rows_bad > 0) {
    text += " (" + std::to_string(context.report->files.back().rows_bad) + " bad row(s) skipped)";
  }
  throw DatasetError(text);
}

// ---------------------------------------------------------------------------------------------
// Writing
// ---------------------------------------------------------------------------------------------

// Builds one CSV file in memory; numbers are checked finite so the file always reads back.
class CsvBuilder {
 public:
  CsvBuilder(std::string path, const std::vector<std::string>& columns) : path_(std::move(path)) {
    text_ = io_detail::join(columns, ",") + "\n";
  }
  void begin_row(std::size_t index) {
    row_ = index;
    first_ = true;
  }
  void end_row() { text_ += '\n'; }
  void number(double value, const char* column) { field(checked(value, column) ? format_double(value) : ""); }
  void degrees(double angle_rad, const char* column) {
    field(checked(angle_rad, column) ? format_degrees_of(angle_rad) : "");
  }
  /// A value that may be absent: empty field for nullopt.
  void optional_number(const std::optional<double>& value, const char* column) {
    if (value) number(*value, column);
    else field("");
  }
  /// An absent value.
  void empty() { field(""); }
  /// A latitude or pitch: must lie in [-pi/2, pi/2] (the reader rejects anything else).
  void degrees_within_quarter_turn(double angle_rad, const char* column) {
    if (std::isfinite(angle_rad) && std::abs(angle_rad) > deg_to_rad(90.0)) {
      throw DatasetError(path_ + ": cannot write row " + std::to_string(row_ + 1) + ": column '" + column +
                         "' is outside [-90, 90] deg");
    }
    degrees(angle_rad, column);
  }
  /// A longitude: kept as is inside [-pi, pi] (exact round trip), wrapped otherwise.
  void longitude(double lon_rad, const char* column) {
    if (std::isfinite(lon_rad) && std::abs(lon_rad) > kPi) lon_rad = wrap_pi(lon_rad);
    degrees(lon_rad, column);
  }
  void integer(long long value) { field(std::to_string(value)); }
  const std::string& text() const { return text_; }
  const std::string& path() const { return path_; }

 private:
  bool checked(double value, const char* column) const {
    if (!std::isfinite(value)) {
      throw DatasetError(path_ + ": cannot write row " + std::to_string(row_ + 1) + ": column '" + column +
                         "' is not finite (" + format_double(value) + ")");
    }
    return true;
  }
  void field(const std::string& text) {
    if (!first_) text_ += ',';
    first_ = false;
    text_ += text;
  }
  std::string path_;
  std::string text_;
  std::size_t row_ = 0;
  bool first_ = true;
};

void write_file(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw DatasetError(path + ": cannot open for writing: " + std::strerror(errno));
  out.write(text.data(), static_cast<std::streamsize>(text.size()));
  out.close();
  if (!out) throw DatasetError(path + ": write failed");
}

void remove_stale(const std::string& path) {
  std::error_code ec;
  fs::remove(path, ec);  // absent is fine; a failure to remove shows up when reading back
}

std::string odometer_csv(const std::string& path, const std::vector<OdometerSample>& rows) {
  CsvBuilder csv(path, {"t", "pulses", "direction"});
  for (std::size_t i = 0; i < rows.size(); ++i) {
    csv.begin_row(i);
    csv.number(rows[i].t_s, "t");
    csv.integer(rows[i].pulses);
    csv.integer(rows[i].direction);
    csv.end_row();
  }
  return csv.text();
}

std::string gnss_csv(const std::string& path, const std::vector<GnssSample>& rows) {
  bool any_pos_std = false, any_vel_std = false;
  for (const GnssSample& s : rows) {
    any_pos_std = any_pos_std || s.pos_std_m.has_value();
    any_vel_std = any_vel_std || s.vel_std_mps.has_value();
  }
  std::vector<std::string> columns{"t", "lat_deg", "lon_deg", "height_m", "ve", "vn", "vu"};
  if (any_pos_std) columns.push_back("pos_std_m");
  if (any_vel_std) columns.push_back("vel_std_mps");
  columns.push_back("fix");
  CsvBuilder csv(path, columns);
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const GnssSample& s = rows[i];
    csv.begin_row(i);
    csv.number(s.t_s, "t");
    csv.degrees_within_quarter_turn(s.position.lat_rad, "lat_deg");
    csv.longitude(s.position.lon_rad, "lon_deg");
    csv.number(s.position.height_m, "height_m");
    csv.number(s.vel_enu_mps.x(), "ve");
    csv.number(s.vel_enu_mps.y(), "vn");
    csv.number(s.vel_enu_mps.z(), "vu");
    if (any_pos_std) csv.optional_number(s.pos_std_m, "pos_std_m");
    if (any_vel_std) csv.optional_number(s.vel_std_mps, "vel_std_mps");
    csv.integer(s.fix);
    csv.end_row();
  }
  return csv.text();
}

std::string ins_csv(const std::string& path, const std::vector<InsSample>& rows) {
  bool any_velocity = false;
  for (const InsSample& s : rows) any_velocity = any_velocity || s.vel_enu_mps.has_value();
  std::vector<std::string> columns{"t", "heading_deg", "pitch_deg", "roll_deg"};
  if (any_velocity) columns.insert(columns.end(), {"ve", "vn", "vu"});
  CsvBuilder csv(path, columns);
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const InsSample& s = rows[i];
    csv.begin_row(i);
    csv.number(s.t_s, "t");
    csv.degrees(s.attitude.heading_rad, "heading_deg");
    csv.degrees_within_quarter_turn(s.attitude.pitch_rad, "pitch_deg");
    csv.degrees(s.attitude.roll_rad, "roll_deg");
    if (any_velocity) {
      for (int axis = 0; axis < 3; ++axis) {
        const char* name = axis == 0 ? "ve" : axis == 1 ? "vn" : "vu";
        csv.optional_number(s.vel_enu_mps ? std::optional<double>((*s.vel_enu_mps)[axis]) : std::nullopt, name);
      }
    }
    csv.end_row();
  }
  return csv.text();
}

std::string truth_csv(const std::string& path, const std::vector<TruthSample>& rows) {
  // A column is written when any row has a value for it; absent values (NaN) are empty fields.
  enum class Kind { kNumber, kAngle, kQuarterTurnAngle, kLongitude };
  struct Column {
    const char* name;
    Kind kind;
    std::function<double(const TruthSample&)> get;
  };
  const std::vector<Column> all{
      {"lat_deg", Kind::kQuarterTurnAngle, [](const TruthSample& s) { return s.position.lat_rad; }},
      {"lon_deg", Kind::kLongitude, [](const TruthSample& s) { return s.position.lon_rad; }},
      {"height_m", Kind::kNumber, [](const TruthSample& s) { return s.position.height_m; }},
      {"heading_deg", Kind::kAngle, [](const TruthSample& s) { return s.attitude.heading_rad; }},
      {"pitch_deg", Kind::kQuarterTurnAngle, [](const TruthSample& s) { return s.attitude.pitch_rad; }},
      {"roll_deg", Kind::kAngle, [](const TruthSample& s) { return s.attitude.roll_rad; }},
      {"k_true", Kind::kNumber, [](const TruthSample& s) { return s.k_true_m_per_pulse; }},
      {"distance_m", Kind::kNumber, [](const TruthSample& s) { return s.distance_m; }},
  };
  std::vector<const Column*> used;
  std::vector<std::string> names{"t"};
  for (const Column& c : all) {
    for (const TruthSample& s : rows) {
      if (!std::isnan(c.get(s))) {
        used.push_back(&c);
        names.push_back(c.name);
        break;
      }
    }
  }
  CsvBuilder csv(path, names);
  for (std::size_t i = 0; i < rows.size(); ++i) {
    csv.begin_row(i);
    csv.number(rows[i].t_s, "t");
    for (const Column* c : used) {
      const double value = c->get(rows[i]);
      if (std::isnan(value)) {
        csv.empty();
        continue;
      }
      switch (c->kind) {
        case Kind::kNumber: csv.number(value, c->name); break;
        case Kind::kAngle: csv.degrees(value, c->name); break;
        case Kind::kQuarterTurnAngle: csv.degrees_within_quarter_turn(value, c->name); break;
        case Kind::kLongitude: csv.longitude(value, c->name); break;
      }
    }
    csv.end_row();
  }
  return csv.text();
}

// Sets section.key to value, or removes it (and an emptied section) when value is nullopt.
void set_meta_number(nlohmann::json& root, const char* section, const char* key, const std::optional<double>& value) {
  if (value) {
    if (!root.contains(section) || !root[section].is_object()) root[section] = nlohmann::json::object();
    root[section][key] = *value;
    return;
  }
  if (root.contains(section) && root[section].is_object()) {
    root[section].erase(key);
    if (root[section].empty()) root.erase(section);
  }
}

std::string meta_json(const std::string& path, const DatasetMeta& meta) {
  nlohmann::json root = nlohmann::json::object();
  if (!meta.raw_json.empty()) {
    try {
      root = nlohmann::json::parse(meta.raw_json);
    } catch (const nlohmann::json::parse_error& e) {
      throw DatasetError(path + ": cannot carry meta.raw_json, it is malformed JSON: " + e.what());
    }
    if (!root.is_object()) throw DatasetError(path + ": cannot carry meta.raw_json, it is not a JSON object");
  }
  root["format"] = meta.format;
  const auto set_string = [&](const char* key, const std::string& value) {
    if (value.empty()) root.erase(key);
    else root[key] = value;
  };
  set_string("vehicle_id", meta.vehicle_id);
  set_string("description", meta.description);
  set_meta_number(root, "odometer", "k_nominal_m_per_pulse", meta.k_nominal_m_per_pulse);
  set_meta_number(root, "truth", "misalignment_heading_deg", meta.truth_misalignment_heading_deg);
  set_meta_number(root, "truth", "misalignment_pitch_deg", meta.truth_misalignment_pitch_deg);
  if (meta.gnss_lever_arm_m) {
    if (!meta.gnss_lever_arm_m->allFinite()) throw DatasetError(path + ": cannot write a non-finite lever arm");
    root["gnss"]["lever_arm_m"] = {meta.gnss_lever_arm_m->x(), meta.gnss_lever_arm_m->y(), meta.gnss_lever_arm_m->z()};
  }
  for (const auto* value : {&meta.k_nominal_m_per_pulse, &meta.truth_misalignment_heading_deg,
                            &meta.truth_misalignment_pitch_deg}) {
    if (*value && !std::isfinite(**value)) throw DatasetError(path + ": cannot write a non-finite number");
  }
  return root.dump(2) + "\n";
}

std::string join_path(const std::string& dir, const char* file) { return (fs::path(dir) / file).string(); }

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

void write_dataset(const std::string& dir, const Dataset& dataset) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw DatasetError(dir + ": cannot create the dataset directory: " + ec.message());
  // Every file is built (and checked) in memory first, so a bad value leaves no half-written set.
  const std::string odometer_path = join_path(dir, "odometer.csv");
  const std::string gnss_path = join_path(dir, "gnss.csv");
  const std::string ins_path = join_path(dir, "ins.csv");
  const std::string truth_path = join_path(dir, "truth.csv");
  const std::string meta_path = join_path(dir, "meta.json");
  const std::string odometer_text = odometer_csv(odometer_path, dataset.odometer);
  const std::string gnss_text = gnss_csv(gnss_path, dataset.gnss);
  const std::string ins_text = dataset.has_ins() ? ins_csv(ins_path, dataset.ins) : "";
  const std::string truth_text = dataset.has_truth() ? truth_csv(truth_path, dataset.truth) : "";
  const std::string meta_text = meta_json(meta_path, dataset.meta);

  write_file(odometer_path, odometer_text);
  write_file(gnss_path, gnss_text);
  // A stale ins.csv / truth.csv from an earlier write would change what the directory means.
  if (dataset.has_ins()) write_file(ins_path, ins_text);
  else remove_stale(ins_path);
  if (dataset.has_truth()) write_file(truth_path, truth_text);
  else remove_stale(truth_path);
  write_file(meta_path, meta_text);
}

}  // namespace odonav
