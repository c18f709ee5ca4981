// The dataset writer, format v1 (docs/DATASET.md): every file is built in memory with CsvWriter and
// checked first, so a bad value leaves no half-written set, and its numbers read back to exactly the
// values given.
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>

#include "dataset_internal.hpp"
#include "odonav/csv_writer.hpp"
#include "odonav/dataset.hpp"
#include "odonav/safe_output.hpp"
#include "text_util.hpp"

namespace odonav {

namespace fs = std::filesystem;
using dataset_detail::join_path;
using dataset_detail::meta_json;
using io_detail::format_double;

namespace {

// The dataset's value rules on top of an in-memory CsvWriter: numbers must be finite (the reader
// rejects anything else, so the file always reads back), angles are written as exact degrees
// (exact_degrees_of), latitude and pitch within a quarter turn, longitudes wrapped. Each failed
// check throws DatasetError naming the file, row and column.
class CheckedCsv {
 public:
  CheckedCsv(const std::string& path, std::vector<std::string> columns)
      : csv_(CsvWriter::InMemory{}, path, std::move(columns)) {}
  void begin_row(std::size_t index) { row_ = index; }
  void end_row() { csv_.end_row(); }
  void number(double value, const char* column) { csv_.field(checked(value, column)); }
  void degrees(double angle_rad, const char* column) { csv_.field(exact_degrees_of(checked(angle_rad, column))); }
  /// A value that may be absent: empty field for nullopt.
  void optional_number(const std::optional<double>& value, const char* column) {
    if (value) number(*value, column);
    else csv_.empty();
  }
  /// An absent value.
  void empty() { csv_.empty(); }
  /// A latitude or pitch: must lie in [-pi/2, pi/2] (the reader rejects anything else).
  void degrees_within_quarter_turn(double angle_rad, const char* column) {
    if (std::isfinite(angle_rad) && std::abs(angle_rad) > deg_to_rad(90.0)) {
      throw DatasetError(csv_.path() + ": cannot write row " + std::to_string(row_ + 1) + ": column '" + column +
                         "' is outside [-90, 90] deg");
    }
    degrees(angle_rad, column);
  }
  /// A longitude: kept as is inside [-pi, pi] (exact round trip), wrapped otherwise.
  void longitude(double lon_rad, const char* column) {
    if (std::isfinite(lon_rad) && std::abs(lon_rad) > kPi) lon_rad = wrap_pi(lon_rad);
    degrees(lon_rad, column);
  }
  void integer(int64_t value) { csv_.field(value); }
  const std::string& text() const { return csv_.text(); }

 private:
  double checked(double value, const char* column) const {
    if (!std::isfinite(value)) {
      throw DatasetError(csv_.path() + ": cannot write row " + std::to_string(row_ + 1) + ": column '" + column +
                         "' is not finite (" + format_double(value) + ")");
    }
    return value;
  }
  CsvWriter csv_;
  std::size_t row_ = 0;
};

// Checked and atomic (safe_output.hpp): never through a link, never a half file under the name.
void write_file(const std::string& path, const std::string& text) {
  try {
    write_file_atomically(path, text);
  } catch (const OutputError& e) {
    throw DatasetError(e.what());
  }
}

void remove_stale(const std::string& path) {
  std::error_code ec;
  fs::remove(path, ec);  // absent is fine; a failure to remove shows up when reading back
}

std::string odometer_csv(const std::string& path, const std::vector<OdometerSample>& rows) {
  CheckedCsv csv(path, {"t", "pulses", "direction"});
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
  CheckedCsv csv(path, columns);
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
  CheckedCsv csv(path, columns);
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
  CheckedCsv csv(path, names);
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

}  // namespace

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
