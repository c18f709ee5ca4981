// The one parser of the dataset CSV files (dataset_rows.hpp): buffered line reading, header
// resolution, row parsing and validation, the bad-row policy, counts and logging, and the time-unit
// check. Every rule of docs/DATASET.md about a file's content lives here.
#include "dataset_rows.hpp"

#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>

#include "dataset_internal.hpp"
#include "odonav/geodesy.hpp"
#include "odonav/wire_time.hpp"
#include "text_util.hpp"

namespace odonav::dataset_detail {

namespace fs = std::filesystem;
using io_detail::format_double;
using io_detail::NumberStatus;
using io_detail::trim;

namespace {

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
    fail(id, std::string(what) + " outside [" + io_detail::format_number(lo) + ", " + io_detail::format_number(hi) +
                 "]: " + in_quotes(text(id)));
  }

  void check_not_negative(int id, const std::optional<double>& value) {
    if (failed_ || !value || *value >= 0.0) return;
    fail(id, "negative standard deviation: " + in_quotes(text(id)));
  }

 private:
  double parse_number(int id) {
    double value = 0.0;
    // parse_double trims the field itself (text(id) would trim it a second time).
    const std::string_view field = has_column(id) ? fields_[field_of_column_[id]] : std::string_view();
    switch (io_detail::parse_double(field, value)) {
      case NumberStatus::kOk: return value;
      case NumberStatus::kEmpty: fail(id, "missing value"); break;
      case NumberStatus::kNotFinite: fail(id, "NaN or infinity is not allowed: " + in_quotes(text(id))); break;
      case NumberStatus::kOutOfRange: fail(id, "number out of range of a double: " + in_quotes(text(id))); break;
      case NumberStatus::kNotNumber: fail(id, "not a number: " + in_quotes(text(id))); break;
    }
    return 0.0;
  }

  const std::vector<std::string_view>& fields_;
  const std::vector<int>& field_of_column_;
  const std::vector<ColumnSpec>& specs_;
  bool failed_ = false;
  RowError error_;
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

// Column ids, in the order of the spec lists below.
namespace odo {
enum { kT, kPulses, kDirection };
const std::vector<ColumnSpec> kSpecs{{"t", true}, {"pulses", true}, {"direction", false}};
}  // namespace odo
namespace gnss {
enum { kT, kLat, kLon, kHeight, kVe, kVn, kVu, kPosStd, kVelStd, kFix };
const std::vector<ColumnSpec> kSpecs{
    {"t", true},  {"lat_deg", true}, {"lon_deg", true},    {"height_m", true},     {"ve", true},
    {"vn", true}, {"vu", true},      {"pos_std_m", false}, {"vel_std_mps", false}, {"fix", false}};
}  // namespace gnss
namespace ins {
enum { kT, kHeading, kPitch, kRoll, kVe, kVn, kVu };
const std::vector<ColumnSpec> kSpecs{{"t", true},   {"heading_deg", true}, {"pitch_deg", true}, {"roll_deg", true},
                                     {"ve", false}, {"vn", false},         {"vu", false}};
}  // namespace ins
namespace truth {
enum { kT, kLat, kLon, kHeight, kHeading, kPitch, kRoll, kK, kDistance };
const std::vector<ColumnSpec> kSpecs{{"t", true},         {"lat_deg", false},     {"lon_deg", false},
                                     {"height_m", false}, {"heading_deg", false}, {"pitch_deg", false},
                                     {"roll_deg", false}, {"k_true", false},      {"distance_m", false}};
}  // namespace truth

OdometerSample parse_odometer_row(RowFields& row) {
  OdometerSample s;
  s.t_s = row.required_double(odo::kT);
  s.pulses =
      static_cast<uint32_t>(row.integer(odo::kPulses, true, 0, 0, 4294967295LL, "an integer in [0, 4294967295]"));
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
  // Longitude 180 is read as -180 (the same meridian): every position odonav holds is in [-180, 180).
  s.position = Geodetic{deg_to_rad(lat_deg), deg_to_rad(normalize_lon_deg(lon_deg)), height_m};
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
  if (!std::isnan(height_m))
    row.check_range(truth::kHeight, height_m, kMinHeight_m, kMaxHeight_m, "height (m) of a land vehicle");
  s.position = Geodetic{deg_to_rad(lat_deg), deg_to_rad(normalize_lon_deg(lon_deg)), height_m};
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

// What differs between the four files: columns, row parser, an extra header rule, and what the
// time-unit check assumes about the file's rate.
template <typename Sample>
struct FileRules;

template <>
struct FileRules<OdometerSample> {
  static const std::vector<ColumnSpec>& specs() { return odo::kSpecs; }
  static OdometerSample parse(RowFields& row) { return parse_odometer_row(row); }
  static void check_header(const std::string&, const ResolvedHeader&) {}
  static constexpr bool kCheckStep = true;
  static constexpr double kTypicalStep_s = 0.02;  // 10-100 Hz
};
template <>
struct FileRules<GnssSample> {
  static const std::vector<ColumnSpec>& specs() { return gnss::kSpecs; }
  static GnssSample parse(RowFields& row) { return parse_gnss_row(row); }
  static void check_header(const std::string&, const ResolvedHeader&) {}
  static constexpr bool kCheckStep = true;
  static constexpr double kTypicalStep_s = 0.3;  // 1-20 Hz
};
template <>
struct FileRules<InsSample> {
  static const std::vector<ColumnSpec>& specs() { return ins::kSpecs; }
  static InsSample parse(RowFields& row) { return parse_ins_row(row); }
  static void check_header(const std::string& path, const ResolvedHeader& header) { check_ins_header(path, header); }
  static constexpr bool kCheckStep = true;
  static constexpr double kTypicalStep_s = 0.01;  // 10-200 Hz
};
template <>
struct FileRules<TruthSample> {
  static const std::vector<ColumnSpec>& specs() { return truth::kSpecs; }
  static TruthSample parse(RowFields& row) { return parse_truth_row(row); }
  static void check_header(const std::string&, const ResolvedHeader&) {}
  // A reference may be sparse (surveyed points far apart): only the magnitude of t is checked.
  static constexpr bool kCheckStep = false;
  static constexpr double kTypicalStep_s = 0.1;  // not used: steps are not checked
};

// The time-unit check (docs/DATASET.md, "Time unit").
// No time base odonav accepts (GNSS time of week, UNIX seconds, seconds since the start) reaches
// 1e11 s (the year 5138 in UNIX time), while milliseconds, microseconds and nanoseconds since 1970
// are above 1e11, 1e14 and 1e17 from 1973 on.
constexpr double kMinEpochMilliseconds = 1e11;
constexpr double kMinEpochMicroseconds = 1e14;
constexpr double kMinEpochNanoseconds = 1e17;
// No sensor stream of a drive is sampled less than once per 1000 s, while a 1 Hz stream stamped in
// ms, us or ns steps by 1e3, 1e6 or 1e9.
constexpr double kMinImplausibleStep_s = 1000.0;

struct TimeUnit {
  const char* name;
  double seconds;
};
constexpr TimeUnit kSubsecondUnits[] = {{"milliseconds", 1e-3}, {"microseconds", 1e-6}, {"nanoseconds", 1e-9}};

// The unit that turns `step` into the step closest (by ratio) to the file's typical step.
const char* unit_for_step(double step, double typical_step_s) {
  const TimeUnit* best = &kSubsecondUnits[0];
  double best_distance = std::numeric_limits<double>::infinity();
  for (const TimeUnit& unit : kSubsecondUnits) {
    const double distance = std::abs(std::log10(step * unit.seconds / typical_step_s));
    if (distance < best_distance) {
      best_distance = distance;
      best = &unit;
    }
  }
  return best->name;
}

}  // namespace

// ---------------------------------------------------------------------------------------------------
// LineReader

LineReader::LineReader(const std::string& path) : path_(path) {
  check_dataset_file(path);
  // O_NONBLOCK: should the path have become a FIFO since the check, open() must not wait for a writer.
  fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd_ < 0) throw DatasetError(path + ": cannot open: " + std::strerror(errno));
  struct stat opened {};
  if (::fstat(fd_, &opened) != 0 || !S_ISREG(opened.st_mode)) {
    ::close(fd_);
    throw DatasetError(path + ": not a regular file (a FIFO, socket or device): dataset files must be regular files");
  }
  buffer_.reset(new char[kReadBufferBytes]);
}

LineReader::~LineReader() {
  if (fd_ >= 0) ::close(fd_);
}

bool LineReader::refill() {
  begin_ = end_ = 0;
  if (at_end_) return false;
  // Fill the buffer as far as the file allows (a regular file gives short reads only at its end),
  // so the byte-order mark check below sees the first three bytes together.
  while (end_ < kReadBufferBytes) {
    const ssize_t n = ::read(fd_, buffer_.get() + end_, kReadBufferBytes - end_);
    if (n < 0) {
      if (errno == EINTR) continue;
      throw DatasetError(path_ + ": read error: " + std::strerror(errno));
    }
    if (n == 0) {
      at_end_ = true;
      break;
    }
    end_ += static_cast<std::size_t>(n);
  }
  bytes_read_ += end_;
  if (bytes_read_ > kMaxDatasetFileBytes)
    throw DatasetError(path_ + ": grew past the limit of " + std::to_string(kMaxDatasetFileBytes) +
                       " bytes per dataset file while being read");
  if (at_start_) {
    at_start_ = false;
    if (end_ >= 3 && std::memcmp(buffer_.get(), "\xEF\xBB\xBF", 3) == 0) begin_ = 3;  // UTF-8 byte-order mark
  }
  return begin_ < end_;
}

void LineReader::append_capped(const char* data, std::size_t size) {
  constexpr std::size_t kCap = kMaxDatasetLineBytes + 1;  // room for a '\r' after a line at the limit
  if (carry_.size() >= kCap) return;
  if (carry_.capacity() < kCap) carry_.reserve(kCap);
  carry_.append(data, std::min(size, kCap - carry_.size()));
}

bool LineReader::next(std::string_view& line, std::size_t& length_bytes) {
  carry_.clear();
  std::size_t length = 0;
  char last = '\0';
  bool any = false;  // a byte or a '\n' of this line was seen
  bool in_buffer = false;
  while (true) {
    if (begin_ == end_ && !refill()) break;
    const char* const data = buffer_.get() + begin_;
    const std::size_t available = end_ - begin_;
    const void* const newline = std::memchr(data, '\n', available);
    const std::size_t take = newline ? static_cast<std::size_t>(static_cast<const char*>(newline) - data) : available;
    any = true;
    if (take > 0) last = data[take - 1];
    if (newline && length == 0) {
      // The whole line is in the buffer: no copy.
      line = std::string_view(data, take);
      length = take;
      in_buffer = true;
      begin_ += take + 1;
      break;
    }
    append_capped(data, take);
    length += take;
    begin_ += take + (newline ? 1 : 0);
    if (newline) break;
  }
  if (!any) return false;
  if (!in_buffer) line = carry_;
  ++line_number_;
  if (length > 0 && last == '\r') {  // CRLF files
    --length;
    if (line.size() > length) line = line.substr(0, length);
  }
  length_bytes = length;
  return true;
}

// ---------------------------------------------------------------------------------------------------
// RowReader

template <typename Sample>
RowReader<Sample>::RowReader(const std::string& path, const ReadContext& context)
    : path_(path), context_(context), lines_(path) {
  file_report_.file = path;
  std::string_view line;
  std::size_t length = 0;
  while (lines_.next(line, length)) {
    if (length > kMaxDatasetLineBytes) {
      // Before the header even a skipped row cannot be told from a header: a file error.
      throw DatasetError(BadRow{path_, lines_.line_number(), "",
                                "line of " + std::to_string(length) + " bytes, longer than the limit of " +
                                    std::to_string(kMaxDatasetLineBytes) + " (starts '" +
                                    io_detail::printable_excerpt(line, length) + "')"}
                             .message());
    }
    const std::string_view trimmed = trim(line);
    if (trimmed.empty() || trimmed.front() == '#') continue;
    header_ = resolve_header(path_, lines_.line_number(), line, FileRules<Sample>::specs());
    FileRules<Sample>::check_header(path_, header_);
    if (!header_.unknown.empty()) {
      file_report_.ignored_columns = header_.unknown;
      std::vector<std::string> names_in_quotes;
      for (const std::string& name : header_.unknown) names_in_quotes.push_back(in_quotes(name));
      spdlog::warn("{}: ignoring unknown column(s) {}", path_, io_detail::join(names_in_quotes));
    }
    return;
  }
  throw DatasetError(path_ + ": no header line (the file is empty or holds only comments)");
}

template <typename Sample>
void RowReader<Sample>::bad_row(std::size_t line, std::string column, std::string reason) {
  BadRow bad{path_, line, std::move(column), std::move(reason)};
  if (context_.policy == BadRowPolicy::kFail) throw DatasetError(bad.message());
  ++file_report_.rows_bad;
  if (context_.log && file_report_.rows_bad <= kMaxLoggedBadRowsPerFile) {
    spdlog::warn("skipping bad row: {}", bad.message());
  }
  if (context_.report && context_.report->bad_rows.size() < kMaxDetailedBadRows) {
    context_.report->bad_rows.push_back(std::move(bad));
  }
}

template <typename Sample>
bool RowReader<Sample>::read_good_row(Sample& sample) {
  std::string_view line;
  std::size_t length = 0;
  while (lines_.next(line, length)) {
    const std::size_t line_no = lines_.line_number();
    if (length > kMaxDatasetLineBytes) {
      // Not split into fields: one 50 MB line of commas would otherwise take a gigabyte.
      bad_row(line_no, "",
              "line of " + std::to_string(length) + " bytes, longer than the limit of " +
                  std::to_string(kMaxDatasetLineBytes) + " (starts '" + io_detail::printable_excerpt(line, length) +
                  "')");
      continue;
    }
    const std::string_view trimmed = trim(line);
    if (trimmed.empty() || trimmed.front() == '#') continue;

    io_detail::split_commas(line, fields_);
    if (fields_.size() < header_.field_count) {
      // A short row (typically a truncated last line): name the first column that has no field.
      bad_row(line_no, header_.names[fields_.size()],
              "missing value: the row has " + std::to_string(fields_.size()) + " fields, the header " +
                  std::to_string(header_.field_count));
      continue;
    }
    if (fields_.size() > header_.field_count) {
      bad_row(line_no, "",
              "the row has " + std::to_string(fields_.size()) + " fields, the header " +
                  std::to_string(header_.field_count));
      continue;
    }
    RowFields row(fields_, header_.field_of_column, FileRules<Sample>::specs());
    sample = FileRules<Sample>::parse(row);
    if (!row.failed() && !fits_wire_time(sample.t_s)) {
      // A first row in ms/us/ns since 1970 gets the unit message (note_first_row throws it), not a
      // bad row per line.
      if (!unit_checked_ && first_t_count_ == 0 && std::abs(sample.t_s) >= kMinEpochMilliseconds) {
        note_first_row(sample.t_s, line_no, row.text(0));
      }
      row.fail(0, "t " + format_double(sample.t_s) +
                      " s is beyond what a DDS stamp carries (int32 seconds, -2147483648 to 2147483647 s: "
                      "UNIX time up to 2038-01-19)");
    }
    if (!row.failed() && previous_t_ && !(sample.t_s > *previous_t_)) {
      row.fail(0, "t does not increase: " + format_double(sample.t_s) + " after " + format_double(*previous_t_) +
                      " (line " + std::to_string(previous_t_line_) + ")");
    }
    if (row.failed()) {
      bad_row(line_no, row.error().column, row.error().reason);
      continue;
    }
    previous_t_ = sample.t_s;
    previous_t_line_ = line_no;
    ++file_report_.rows_read;
    if (!unit_checked_) note_first_row(sample.t_s, line_no, row.text(0));
    return true;
  }
  if (!unit_checked_) check_time_steps();
  if (!ended_) {
    ended_ = true;
    if (context_.log && file_report_.rows_bad > kMaxLoggedBadRowsPerFile) {
      spdlog::warn("{}: {} bad rows skipped in all", path_, file_report_.rows_bad);
    }
  }
  return false;
}

template <typename Sample>
std::optional<Sample> RowReader<Sample>::next() {
  Sample sample{};
  if (read_good_row(sample)) return sample;
  return std::nullopt;
}

template <typename Sample>
void RowReader<Sample>::note_first_row(double t_s, std::size_t line, std::string_view t_text) {
  if (first_t_count_ == 0) {
    first_row_line_ = line;
    first_t_text_ = io_detail::printable_excerpt(t_text);
    const double magnitude = std::abs(t_s);
    if (magnitude >= kMinEpochMilliseconds) {
      const char* unit = magnitude >= kMinEpochNanoseconds    ? "nanoseconds"
                         : magnitude >= kMinEpochMicroseconds ? "microseconds"
                                                              : "milliseconds";
      throw DatasetError(path_ + ":" + std::to_string(line) + ": column 't': " + first_t_text_ + " looks like " + unit +
                         " since 1970; odonav expects seconds (docs/DATASET.md)");
    }
  }
  first_t_[first_t_count_++] = t_s;
  if (first_t_count_ == kUnitCheckRows) check_time_steps();
}

template <typename Sample>
void RowReader<Sample>::check_time_steps() {
  unit_checked_ = true;
  if (!FileRules<Sample>::kCheckStep || first_t_count_ < kUnitCheckRows) return;
  std::array<double, kUnitCheckRows - 1> steps{};
  const std::size_t n = first_t_count_ - 1;
  for (std::size_t i = 0; i < n; ++i) steps[i] = first_t_[i + 1] - first_t_[i];
  std::nth_element(steps.begin(), steps.begin() + n / 2, steps.begin() + n);
  const double median_step = steps[n / 2];
  if (median_step < kMinImplausibleStep_s) return;
  throw DatasetError(path_ + ":" + std::to_string(first_row_line_) + ": column 't': " + first_t_text_ +
                     " then steps of " + io_detail::format_number(median_step) + " (the median of the first " +
                     std::to_string(first_t_count_) + " rows) look like " +
                     unit_for_step(median_step, FileRules<Sample>::kTypicalStep_s) +
                     "; odonav expects seconds (docs/DATASET.md)");
}

template class RowReader<OdometerSample>;
template class RowReader<GnssSample>;
template class RowReader<InsSample>;
template class RowReader<TruthSample>;

void require_two_rows(const std::string& path, std::size_t good_rows, std::size_t bad_rows, bool with_skipped_count) {
  if (good_rows >= 2) return;
  std::string text = path + ": " + std::to_string(good_rows) + " good row(s), at least 2 are needed";
  if (with_skipped_count && bad_rows > 0) text += " (" + std::to_string(bad_rows) + " bad row(s) skipped)";
  throw DatasetError(text);
}

bool file_exists(const std::string& path) {
  std::error_code ec;
  return fs::exists(path, ec);
}

}  // namespace odonav::dataset_detail
