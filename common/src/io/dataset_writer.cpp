// The dataset writer, format v1 (docs/DATASET.md), row by row (odonav/dataset_writer.hpp): every
// file goes through a file CsvWriter (bounded buffer, a temporary renamed into place at finish()),
// every value is checked before it is written, and its numbers read back to exactly the values
// given. write_dataset is this writer fed from a Dataset in memory.
#include "odonav/dataset_writer.hpp"

#include <array>
#include <cmath>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <utility>

#include "dataset_internal.hpp"
#include "odonav/csv_writer.hpp"
#include "odonav/safe_output.hpp"
#include "text_util.hpp"

namespace odonav {

namespace fs = std::filesystem;
using dataset_detail::join_path;
using dataset_detail::meta_json;
using io_detail::format_double;

namespace {

// The dataset's value rules on top of a file CsvWriter: numbers must be finite (the reader rejects
// anything else, so the file always reads back), angles are written as exact degrees
// (exact_degrees_of), latitude and pitch within a quarter turn, longitudes wrapped. Each failed
// check throws DatasetError naming the file, row and column.
class CheckedCsv {
 public:
  CheckedCsv(const std::string& path, std::vector<std::string> columns) : csv_(path, std::move(columns)) {}
  /// Starts a row with its time column t (s): every dataset file begins with it.
  void begin_row(double t_s) {
    row_ = csv_.rows();
    number(t_s, "t");
  }
  void end_row() { csv_.end_row(); }
  void number(double value, const char* column) { csv_.field(checked(value, column)); }
  void degrees(double angle_rad, const char* column) { csv_.field(exact_degrees_of(checked(angle_rad, column))); }
  /// A value that may be absent: empty field for nullopt.
  void optional_number(const std::optional<double>& value, const char* column) {
    if (value)
      number(*value, column);
    else
      csv_.empty();
  }
  /// An absent value.
  void empty() { csv_.empty(); }
  /// A latitude or pitch: must lie in [-pi/2, pi/2] (the reader rejects anything else).
  void degrees_within_quarter_turn(double angle_rad, const char* column) {
    if (std::isfinite(angle_rad) && std::abs(angle_rad) > deg_to_rad(90.0)) {
      fail(column, "is outside [-90, 90] deg");
    }
    degrees(angle_rad, column);
  }
  /// A longitude: kept as is inside [-pi, pi] (exact round trip), wrapped otherwise.
  void longitude(double lon_rad, const char* column) {
    if (std::isfinite(lon_rad) && std::abs(lon_rad) > kPi) lon_rad = wrap_pi(lon_rad);
    degrees(lon_rad, column);
  }
  void integer(int64_t value) { csv_.field(value); }
  /// A value given for a column this file does not have: refused rather than silently dropped.
  [[noreturn]] void fail_not_a_column(const char* column) const {
    fail(column, "has a value but the writer was opened without this column (DatasetWriterOptions)");
  }
  [[noreturn]] void fail(const char* column, const std::string& why) const {
    throw DatasetError(csv_.path() + ": cannot write row " + std::to_string(row_ + 1) + ": column '" + column + "' " +
                       why);
  }
  CsvWriter& csv() { return csv_; }
  const CsvWriter& csv() const { return csv_; }

 private:
  double checked(double value, const char* column) const {
    if (!std::isfinite(value)) fail(column, "is not finite (" + format_double(value) + ")");
    return value;
  }
  CsvWriter csv_;
  std::size_t row_ = 0;
};

// truth.csv's optional columns, in file order.
enum class TruthKind { kNumber, kAngle, kQuarterTurnAngle, kLongitude };
struct TruthColumn {
  const char* name;
  TruthKind kind;
  double (*get)(const TruthSample&);
  bool TruthColumns::*enabled;
};
const std::array<TruthColumn, 8> kTruthColumns{{
    {"lat_deg", TruthKind::kQuarterTurnAngle, [](const TruthSample& s) { return s.position.lat_rad; },
     &TruthColumns::lat_deg},
    {"lon_deg", TruthKind::kLongitude, [](const TruthSample& s) { return s.position.lon_rad; }, &TruthColumns::lon_deg},
    {"height_m", TruthKind::kNumber, [](const TruthSample& s) { return s.position.height_m; }, &TruthColumns::height_m},
    {"heading_deg", TruthKind::kAngle, [](const TruthSample& s) { return s.attitude.heading_rad; },
     &TruthColumns::heading_deg},
    {"pitch_deg", TruthKind::kQuarterTurnAngle, [](const TruthSample& s) { return s.attitude.pitch_rad; },
     &TruthColumns::pitch_deg},
    {"roll_deg", TruthKind::kAngle, [](const TruthSample& s) { return s.attitude.roll_rad; }, &TruthColumns::roll_deg},
    {"k_true", TruthKind::kNumber, [](const TruthSample& s) { return s.k_true_m_per_pulse; }, &TruthColumns::k_true},
    {"distance_m", TruthKind::kNumber, [](const TruthSample& s) { return s.distance_m; }, &TruthColumns::distance_m},
}};

std::vector<std::string> gnss_header(const DatasetWriterOptions& o) {
  std::vector<std::string> columns{"t", "lat_deg", "lon_deg", "height_m", "ve", "vn", "vu"};
  if (o.gnss_pos_std_m) columns.push_back("pos_std_m");
  if (o.gnss_vel_std_mps) columns.push_back("vel_std_mps");
  columns.push_back("fix");
  return columns;
}

std::vector<std::string> ins_header(const DatasetWriterOptions& o) {
  std::vector<std::string> columns{"t", "heading_deg", "pitch_deg", "roll_deg"};
  if (o.ins_velocity) columns.insert(columns.end(), {"ve", "vn", "vu"});
  return columns;
}

std::vector<std::string> truth_header(const DatasetWriterOptions& o) {
  std::vector<std::string> columns{"t"};
  for (const TruthColumn& c : kTruthColumns)
    if (o.truth_columns.*c.enabled) columns.push_back(c.name);
  return columns;
}

void remove_stale(const std::string& path) {
  std::error_code ec;
  fs::remove(path, ec);  // absent is fine; a failure to remove shows up when reading back
}

}  // namespace

DatasetWriterOptions DatasetWriterOptions::for_dataset(const Dataset& dataset) {
  DatasetWriterOptions o;
  for (const GnssSample& s : dataset.gnss) {
    o.gnss_pos_std_m = o.gnss_pos_std_m || s.pos_std_m.has_value();
    o.gnss_vel_std_mps = o.gnss_vel_std_mps || s.vel_std_mps.has_value();
  }
  o.ins = dataset.has_ins();
  for (const InsSample& s : dataset.ins) o.ins_velocity = o.ins_velocity || s.vel_enu_mps.has_value();
  o.truth = dataset.has_truth();
  for (const TruthColumn& c : kTruthColumns) {
    bool any = false;
    for (const TruthSample& s : dataset.truth) {
      if (!std::isnan(c.get(s))) {
        any = true;
        break;
      }
    }
    o.truth_columns.*c.enabled = any;
  }
  return o;
}

struct DatasetWriter::Files {
  Files(const std::string& dir, const DatasetWriterOptions& o)
      : odometer(join_path(dir, "odometer.csv"), {"t", "pulses", "direction"}),
        gnss(join_path(dir, "gnss.csv"), gnss_header(o)) {
    if (o.ins) ins.emplace(join_path(dir, "ins.csv"), ins_header(o));
    if (o.truth) truth.emplace(join_path(dir, "truth.csv"), truth_header(o));
  }
  CheckedCsv odometer;
  CheckedCsv gnss;
  std::optional<CheckedCsv> ins;
  std::optional<CheckedCsv> truth;
};

namespace {
// The file of an optional table (ins.csv, truth.csv) a row goes to; DatasetError when the writer was
// opened without it.
CheckedCsv& opened(std::optional<CheckedCsv>& file, const std::string& dir, const char* name, const char* row) {
  if (!file) {
    throw DatasetError(join_path(dir, name) + ": cannot write " + row + ": the writer was opened without " + name +
                       " (DatasetWriterOptions)");
  }
  return *file;
}
}  // namespace

// Runs one write; any exception marks the writer failed, an OutputError (safe_output.hpp: links,
// I/O) becomes the DatasetError this writer promises.
template <class F>
void DatasetWriter::guarded(F&& write) {
  if (failed_) throw std::logic_error(dir_ + ": DatasetWriter used after a failure");
  if (finished_) throw std::logic_error(dir_ + ": DatasetWriter used after finish()");
  try {
    write();
  } catch (const OutputError& e) {
    failed_ = true;
    throw DatasetError(e.what());
  } catch (...) {
    failed_ = true;
    throw;
  }
}

DatasetWriter::DatasetWriter(const std::string& dir, const DatasetWriterOptions& options)
    : dir_(dir), options_(options) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw DatasetError(dir + ": cannot create the dataset directory: " + ec.message());
  try {
    files_ = std::make_unique<Files>(dir, options);
  } catch (const OutputError& e) {
    throw DatasetError(e.what());
  }
}

// Without finish() every CsvWriter's AtomicFile removes its temporary: no file under a real name.
DatasetWriter::~DatasetWriter() = default;

void DatasetWriter::add(const OdometerSample& s) {
  guarded([&] {
    CheckedCsv& csv = files_->odometer;
    csv.begin_row(s.t_s);
    csv.integer(s.pulses);
    csv.integer(s.direction);
    csv.end_row();
  });
}

void DatasetWriter::add(const GnssSample& s) {
  guarded([&] {
    CheckedCsv& csv = files_->gnss;
    csv.begin_row(s.t_s);
    csv.degrees_within_quarter_turn(s.position.lat_rad, "lat_deg");
    csv.longitude(s.position.lon_rad, "lon_deg");
    csv.number(s.position.height_m, "height_m");
    csv.number(s.vel_enu_mps.x(), "ve");
    csv.number(s.vel_enu_mps.y(), "vn");
    csv.number(s.vel_enu_mps.z(), "vu");
    if (options_.gnss_pos_std_m)
      csv.optional_number(s.pos_std_m, "pos_std_m");
    else if (s.pos_std_m)
      csv.fail_not_a_column("pos_std_m");
    if (options_.gnss_vel_std_mps)
      csv.optional_number(s.vel_std_mps, "vel_std_mps");
    else if (s.vel_std_mps)
      csv.fail_not_a_column("vel_std_mps");
    csv.integer(s.fix);
    csv.end_row();
  });
}

void DatasetWriter::add(const InsSample& s) {
  guarded([&] {
    CheckedCsv& csv = opened(files_->ins, dir_, "ins.csv", "an INS row");
    csv.begin_row(s.t_s);
    csv.degrees(s.attitude.heading_rad, "heading_deg");
    csv.degrees_within_quarter_turn(s.attitude.pitch_rad, "pitch_deg");
    csv.degrees(s.attitude.roll_rad, "roll_deg");
    if (options_.ins_velocity) {
      for (int axis = 0; axis < 3; ++axis) {
        const char* name = axis == 0 ? "ve" : axis == 1 ? "vn" : "vu";
        csv.optional_number(s.vel_enu_mps ? std::optional<double>((*s.vel_enu_mps)[axis]) : std::nullopt, name);
      }
    } else if (s.vel_enu_mps) {
      csv.fail_not_a_column("ve");
    }
    csv.end_row();
  });
}

void DatasetWriter::add(const TruthSample& s) {
  guarded([&] {
    CheckedCsv& csv = opened(files_->truth, dir_, "truth.csv", "a truth row");
    csv.begin_row(s.t_s);
    for (const TruthColumn& c : kTruthColumns) {
      const double value = c.get(s);
      if (!(options_.truth_columns.*c.enabled)) {
        if (!std::isnan(value)) csv.fail_not_a_column(c.name);
        continue;
      }
      if (std::isnan(value)) {
        csv.empty();
        continue;
      }
      switch (c.kind) {
        case TruthKind::kNumber: csv.number(value, c.name); break;
        case TruthKind::kAngle: csv.degrees(value, c.name); break;
        case TruthKind::kQuarterTurnAngle: csv.degrees_within_quarter_turn(value, c.name); break;
        case TruthKind::kLongitude: csv.longitude(value, c.name); break;
      }
    }
    csv.end_row();
  });
}

void DatasetWriter::finish(const DatasetMeta& meta) {
  guarded([&] {
    // Everything that can fail on content or a full disk happens before the first rename.
    const std::string meta_path = join_path(dir_, "meta.json");
    const std::string meta_text = meta_json(meta_path, meta);
    Files& f = *files_;
    f.odometer.csv().flush();
    f.gnss.csv().flush();
    if (f.ins) f.ins->csv().flush();
    if (f.truth) f.truth->csv().flush();
    AtomicFile meta_file(meta_path);
    meta_file.write(meta_text);
    meta_file.flush(false);
    // The renames, meta.json last.
    f.odometer.csv().close();
    f.gnss.csv().close();
    if (f.ins)
      f.ins->csv().close();
    else
      remove_stale(join_path(dir_, "ins.csv"));
    if (f.truth)
      f.truth->csv().close();
    else
      remove_stale(join_path(dir_, "truth.csv"));
    meta_file.commit();
    finished_ = true;
  });
}

DatasetRowCounts DatasetWriter::rows() const {
  DatasetRowCounts n;
  n.odometer = files_->odometer.csv().rows();
  n.gnss = files_->gnss.csv().rows();
  if (files_->ins) n.ins = files_->ins->csv().rows();
  if (files_->truth) n.truth = files_->truth->csv().rows();
  return n;
}

std::size_t DatasetWriter::buffer_capacity_bytes() const {
  std::size_t bytes = files_->odometer.csv().buffer_capacity_bytes() + files_->gnss.csv().buffer_capacity_bytes();
  if (files_->ins) bytes += files_->ins->csv().buffer_capacity_bytes();
  if (files_->truth) bytes += files_->truth->csv().buffer_capacity_bytes();
  return bytes;
}

void write_dataset(const std::string& dir, const Dataset& dataset) {
  // File by file, as the rows come: the first bad value found is the one the in-memory writer
  // found, and it leaves no file of this dataset under its real name.
  DatasetWriter writer(dir, DatasetWriterOptions::for_dataset(dataset));
  for (const OdometerSample& s : dataset.odometer) writer.add(s);
  for (const GnssSample& s : dataset.gnss) writer.add(s);
  for (const InsSample& s : dataset.ins) writer.add(s);
  for (const TruthSample& s : dataset.truth) writer.add(s);
  writer.finish(dataset.meta);
}

}  // namespace odonav
