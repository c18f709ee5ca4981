// The output files (odonav/results/output_files.hpp): writers on CsvWriter, and the reader back.
#include "odonav/results/output_files.hpp"

#include <sys/stat.h>

#include <charconv>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <stdexcept>

#include "odonav/frames.hpp"

namespace odonav::results {
namespace {
std::optional<double> finite_or_empty(double v) { return std::isfinite(v) ? std::optional<double>(v) : std::nullopt; }

// The header of a file: the column names of its table.
struct HeaderVisitor {
  std::vector<std::string>& names;
  template <class T>
  void number(const char* n, T&, double, Since = Since::kFirst) {
    names.emplace_back(n);
  }
  template <class T>
  void finite(const char* n, T&, Since = Since::kFirst) {
    names.emplace_back(n);
  }
  template <class T>
  void degrees(const char* n, T&) {
    names.emplace_back(n);
  }
  template <class T>
  void finite_degrees(const char* n, T&) {
    names.emplace_back(n);
  }
  template <class T>
  void optional(const char* n, T&, Since = Since::kFirst) {
    names.emplace_back(n);
  }
  template <class T>
  void text(const char* n, T&) {
    names.emplace_back(n);
  }
  template <class T>
  void flag(const char* n, T&) {
    names.emplace_back(n);
  }
  template <class T>
  void count(const char* n, T&) {
    names.emplace_back(n);
  }
  template <class T>
  void estimators(T&) {
    for (const std::string& c : scale_factor_estimator_columns()) names.push_back(c);
  }
};

// The column names of Row's file, listed once per run.
template <class Row>
const std::vector<std::string>& columns_of() {
  static const std::vector<std::string> columns = [] {
    std::vector<std::string> names;
    Row row;
    visit_columns(row, HeaderVisitor{names});
    return names;
  }();
  return columns;
}

// K (m/pulse) of each estimator that ran, by estimator name (ScaleFactorRow::k_by_estimator).
using KByEstimator = std::vector<std::pair<std::string, std::optional<double>>>;

// The value of a "k_<name>" column of scale_factor.csv: the K of estimator <name>, empty when it did
// not run (the last entry wins). Compared in place: no temporary string per column and estimator.
std::optional<double> k_of_column(const std::string& column, const KByEstimator& k_by_estimator) {
  std::optional<double> k;
  for (const auto& [name, value] : k_by_estimator)
    if (column.size() == name.size() + 2 && column.compare(2, std::string::npos, name) == 0) k = value;
  return k;
}

// One row into a CsvWriter, field by field in the table's order.
struct WriteVisitor {
  CsvWriter& csv;
  void number(const char*, double v, double, Since = Since::kFirst) { csv.field(v); }
  void finite(const char*, double v, Since = Since::kFirst) { csv.field(finite_or_empty(v)); }
  void degrees(const char*, double rad) { csv.field(rad_to_deg(rad)); }
  void finite_degrees(const char*, double rad) { csv.field(finite_or_empty(rad_to_deg(rad))); }
  void optional(const char*, const std::optional<double>& v, Since = Since::kFirst) { csv.field(v); }
  void text(const char*, const std::string& v) { csv.field(v); }
  void flag(const char*, bool v) { csv.field(v); }
  void count(const char*, uint64_t v) { csv.field(v); }
  void estimators(const KByEstimator& k_by_estimator) {
    for (const std::string& column : scale_factor_estimator_columns()) csv.field(k_of_column(column, k_by_estimator));
  }
};

// One row into a JSON object, field by field in the table's order; empty fields are null.
struct JsonVisitor {
  nlohmann::json& j;
  static nlohmann::json known(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); }
  static nlohmann::json known(const std::optional<double>& v) { return v ? known(*v) : nlohmann::json(); }
  void number(const char* n, double v, double, Since = Since::kFirst) { j[n] = known(v); }
  void finite(const char* n, double v, Since = Since::kFirst) { j[n] = known(v); }
  void degrees(const char* n, double rad) { j[n] = known(rad_to_deg(rad)); }
  void finite_degrees(const char* n, double rad) { j[n] = known(rad_to_deg(rad)); }
  void optional(const char* n, const std::optional<double>& v, Since = Since::kFirst) { j[n] = known(v); }
  void text(const char* n, const std::string& v) { j[n] = v; }
  void flag(const char* n, bool v) { j[n] = v; }
  void count(const char* n, uint64_t v) { j[n] = v; }
  void estimators(const KByEstimator& k_by_estimator) {
    for (const std::string& column : scale_factor_estimator_columns())
      j[column] = known(k_of_column(column, k_by_estimator));
  }
};

template <class Row>
nlohmann::json json_of(const Row& row) {
  nlohmann::json j = nlohmann::json::object();
  visit_columns(row, JsonVisitor{j});
  return j;
}

template <class Row>
void write_row(CsvWriter& csv, const Row& row) {
  visit_columns(row, WriteVisitor{csv});
  csv.end_row();
}

}  // namespace

nlohmann::json row_json(const MisalignmentRow& row) { return json_of(row); }
nlohmann::json row_json(const ScaleFactorRow& row) { return json_of(row); }
nlohmann::json row_json(const DeadReckoningRow& row) { return json_of(row); }
nlohmann::json row_json(const NavigationPositionRow& row) { return json_of(row); }

const std::vector<std::string>& scale_factor_estimator_columns() {
  static const std::vector<std::string> columns{"k_rls", "k_ff_rls", "k_lm_rls", "k_vff_lm_rls", "k_coarse", "k_kf_rw"};
  return columns;
}

const std::vector<std::string>& misalignment_columns() { return columns_of<MisalignmentRow>(); }
const std::vector<std::string>& scale_factor_columns() { return columns_of<ScaleFactorRow>(); }
const std::vector<std::string>& dead_reckoning_columns() { return columns_of<DeadReckoningRow>(); }
const std::vector<std::string>& navigation_position_columns() { return columns_of<NavigationPositionRow>(); }

template <class Row>
RowCsv<Row>::RowCsv(const std::string& path) : csv_(path, columns_of<Row>()) {}
template <class Row>
void RowCsv<Row>::write(const Row& r) {
  write_row(csv_, r);
}
template class RowCsv<MisalignmentRow>;
template class RowCsv<ScaleFactorRow>;
template class RowCsv<DeadReckoningRow>;
template class RowCsv<NavigationPositionRow>;

}  // namespace odonav::results

// ---- reading back --------------------------------------------------------------------------------

namespace odonav::results {
namespace {

// One line of a CSV output file at a time: the header's columns by name, and the current row's
// fields, with errors naming the file, the line and the column.
class CsvLines {
 public:
  explicit CsvLines(const std::string& path) : path_(path), in_(path) {
    if (!in_) throw std::runtime_error(path + ": cannot open");
    std::string line;
    if (!std::getline(in_, line)) throw std::runtime_error(path + ": empty file (no header)");
    split(line, header_);
    for (std::size_t i = 0; i < header_.size(); ++i) index_[header_[i]] = i;
  }
  /// Reads the next non-empty line; false at the end of the file.
  bool next() {
    while (std::getline(in_, line_)) {
      ++line_no_;
      if (line_.empty()) continue;
      split(line_, fields_);
      if (fields_.size() != header_.size())
        throw std::runtime_error(path_ + ":" + std::to_string(line_no_) + ": " + std::to_string(fields_.size()) +
                                 " fields, header has " + std::to_string(header_.size()));
      return true;
    }
    return false;
  }
  const std::string& text(const std::string& column) const {
    auto it = index_.find(column);
    if (it == index_.end()) throw std::runtime_error(path_ + ": missing column '" + column + "'");
    return fields_[it->second];
  }
  bool has(const std::string& column) const { return index_.count(column) > 0; }
  std::optional<double> optional_number(const std::string& column) const {
    const std::string& t = text(column);
    if (t.empty()) return std::nullopt;
    double v = 0.0;
    const auto res = std::from_chars(t.data(), t.data() + t.size(), v);
    if (res.ec != std::errc() || res.ptr != t.data() + t.size())
      throw std::runtime_error(path_ + ":" + std::to_string(line_no_) + ": column '" + column + "': not a number: '" +
                               t + "'");
    return v;
  }
  double number(const std::string& column, double if_empty = std::numeric_limits<double>::quiet_NaN()) const {
    return optional_number(column).value_or(if_empty);
  }

 private:
  static void split(const std::string& line, std::vector<std::string>& out) {
    out.assign(1, std::string());
    for (char c : line) {
      if (c == ',')
        out.emplace_back();
      else if (c != '\r')
        out.back() += c;
    }
  }
  std::string path_;
  std::ifstream in_;
  std::vector<std::string> header_;
  std::map<std::string, std::size_t> index_;
  std::string line_;
  std::vector<std::string> fields_;
  std::size_t line_no_ = 1;
};

// One row from the current line of a file, by column name (the file's own column order).
struct ReadVisitor {
  const CsvLines& t;
  void number(const char* n, double& v, double if_empty, Since since = Since::kFirst) {
    v = present(n, since) ? t.number(n, if_empty) : if_empty;
  }
  void finite(const char* n, double& v, Since since = Since::kFirst) {
    number(n, v, std::numeric_limits<double>::quiet_NaN(), since);
  }
  void degrees(const char* n, double& rad) { rad = deg_to_rad(t.number(n)); }
  void finite_degrees(const char* n, double& rad) { degrees(n, rad); }
  void optional(const char* n, std::optional<double>& v, Since since = Since::kFirst) {
    v = present(n, since) ? t.optional_number(n) : std::nullopt;
  }
  void text(const char* n, std::string& v) { v = t.text(n); }
  void flag(const char* n, bool& v) { v = t.number(n, 0.0) != 0.0; }
  void count(const char* n, uint64_t& v) { v = static_cast<uint64_t>(t.number(n, 0.0)); }
  void estimators(std::vector<std::pair<std::string, std::optional<double>>>& k_by_estimator) {
    k_by_estimator.clear();
    for (const std::string& c : scale_factor_estimator_columns())
      if (t.has(c)) k_by_estimator.emplace_back(c.substr(2), t.optional_number(c));
  }
  // A column older files lack is read as empty when absent; any other is required (text() names it).
  bool present(const char* n, Since since) const { return since == Since::kFirst || t.has(n); }
};

template <class Row>
void parse(const CsvLines& t, Row& r) {
  visit_columns(r, ReadVisitor{t});
}

template <class Row>
std::vector<Row> read_all(const std::string& path) {
  OutputFileReader reader(path);
  std::vector<Row> rows;
  Row r;
  while (reader.next(r)) rows.push_back(r);
  return rows;
}

}  // namespace

struct OutputFileReader::Impl {
  explicit Impl(const std::string& path) : lines(path) {}
  CsvLines lines;
};

OutputFileReader::OutputFileReader(const std::string& path) : impl_(std::make_unique<Impl>(path)) {}
OutputFileReader::~OutputFileReader() = default;
OutputFileReader::OutputFileReader(OutputFileReader&&) noexcept = default;
OutputFileReader& OutputFileReader::operator=(OutputFileReader&&) noexcept = default;

template <class Row>
bool OutputFileReader::read(Row& row) {
  if (!impl_->lines.next()) return false;
  parse(impl_->lines, row);
  return true;
}
bool OutputFileReader::next(MisalignmentRow& row) { return read(row); }
bool OutputFileReader::next(ScaleFactorRow& row) { return read(row); }
bool OutputFileReader::next(DeadReckoningRow& row) { return read(row); }
bool OutputFileReader::next(NavigationPositionRow& row) { return read(row); }

bool output_file_exists(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0;
}

OutputRows read_output_rows(const std::string& dir) {
  OutputRows out;
  out.misalignment = read_all<MisalignmentRow>(dir + "/misalignment.csv");
  out.scale_factor = read_all<ScaleFactorRow>(dir + "/scale_factor.csv");
  out.dead_reckoning = read_all<DeadReckoningRow>(dir + "/dead_reckoning.csv");
  if (output_file_exists(dir + "/dead_reckoning_coarse.csv"))
    out.dead_reckoning_coarse = read_all<DeadReckoningRow>(dir + "/dead_reckoning_coarse.csv");
  if (output_file_exists(dir + "/navigation_position.csv"))
    out.navigation_position = read_all<NavigationPositionRow>(dir + "/navigation_position.csv");
  return out;
}

}  // namespace odonav::results

namespace odonav::results {
void write_output_rows(const std::string& dir, const OutputRows& rows) {
  MisalignmentCsv mis(dir + "/misalignment.csv");
  for (const auto& r : rows.misalignment) mis.write(r);
  mis.close();
  ScaleFactorCsv sf(dir + "/scale_factor.csv");
  for (const auto& r : rows.scale_factor) sf.write(r);
  sf.close();
  DeadReckoningCsv dr(dir + "/dead_reckoning.csv");
  for (const auto& r : rows.dead_reckoning) dr.write(r);
  dr.close();
  if (!rows.dead_reckoning_coarse.empty()) {
    DeadReckoningCsv coarse(dir + "/dead_reckoning_coarse.csv");
    for (const auto& r : rows.dead_reckoning_coarse) coarse.write(r);
    coarse.close();
  }
  if (!rows.navigation_position.empty()) {
    NavigationPositionCsv nav(dir + "/navigation_position.csv");
    for (const auto& r : rows.navigation_position) nav.write(r);
    nav.close();
  }
}
}  // namespace odonav::results
