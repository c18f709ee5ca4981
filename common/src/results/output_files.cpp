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
std::optional<double> finite_or_empty(double v) {
  return std::isfinite(v) ? std::optional<double>(v) : std::nullopt;
}

}  // namespace

const std::vector<std::string>& misalignment_columns() {
  static const std::vector<std::string> columns{"t",        "heading_deg", "pitch_deg", "heading_std_deg", "pitch_std_deg",
                                                "converged", "state",      "samples_used"};
  return columns;
}

const std::vector<std::string>& scale_factor_columns() {
  static const std::vector<std::string> columns = [] {
    std::vector<std::string> h{"t"};
    for (const std::string& c : scale_factor_estimator_columns()) h.push_back(c);
    for (const char* c : {"lambda_vff_lm_rls", "estimator", "k_m_per_pulse", "sigma_m_per_pulse", "forgetting_factor",
                          "window_fill", "converged", "samples_accepted", "samples_rejected", "epoch_status",
                          "gnss_latency_s", "gnss_latency_sigma_s", "turn_slip_s_per_rad", "turn_slip_sigma_s_per_rad",
                          "turn_slip_applies"})
      h.push_back(c);
    return h;
  }();
  return columns;
}

const std::vector<std::string>& dead_reckoning_columns() {
  static const std::vector<std::string> columns{"t",      "lat_deg", "lon_deg", "height_m",    "distance_m",
                                                "k_m_per_pulse", "k_source", "east_m", "north_m",
                                                "up_m",   "heading_deg", "horizontal_error_m", "error_percent", "error_t"};
  return columns;
}

const std::vector<std::string>& navigation_position_columns() {
  static const std::vector<std::string> columns{"t",           "lat_deg",     "lon_deg",      "height_m",  "east_m",
                                                "north_m",     "up_m",        "var_east_m2",  "var_north_m2",
                                                "var_up_m2",   "status",      "last_fix_t",   "distance_since_fix_m"};
  return columns;
}

const std::vector<std::string>& scale_factor_estimator_columns() {
  static const std::vector<std::string> columns{"k_rls", "k_ff_rls", "k_lm_rls", "k_vff_lm_rls", "k_coarse", "k_kf_rw"};
  return columns;
}

MisalignmentCsv::MisalignmentCsv(const std::string& path)
    : csv_(path, misalignment_columns()) {}

void MisalignmentCsv::write(const MisalignmentRow& r) {
  csv_.field(r.t_s)
      .field(rad_to_deg(r.heading_rad))
      .field(rad_to_deg(r.pitch_rad))
      .field(finite_or_empty(rad_to_deg(r.heading_std_rad)))
      .field(finite_or_empty(rad_to_deg(r.pitch_std_rad)))
      .field(r.converged)
      .field(r.state)
      .field(r.samples_used);
  csv_.end_row();
}

ScaleFactorCsv::ScaleFactorCsv(const std::string& path) : csv_(path, scale_factor_columns()) {}

void ScaleFactorCsv::write(const ScaleFactorRow& r) {
  csv_.field(r.t_s);
  for (const std::string& column : scale_factor_estimator_columns()) {
    std::optional<double> k;
    // column is "k_" + name; compared in place (no temporary string per column and estimator).
    for (const auto& [name, value] : r.k_by_estimator)
      if (column.size() == name.size() + 2 && column.compare(2, std::string::npos, name) == 0) k = value;
    csv_.field(k);
  }
  csv_.field(r.lambda_vff_lm_rls)
      .field(r.estimator)
      .field(r.k_m_per_pulse)
      .field(r.sigma_m_per_pulse)
      .field(r.forgetting_factor)
      .field(r.window_fill)
      .field(r.converged)
      .field(r.samples_accepted)
      .field(r.samples_rejected)
      .field(r.epoch_status)
      .field(r.gnss_latency_s)
      .field(r.gnss_latency_sigma_s)
      .field(r.turn_slip_s_per_rad)
      .field(r.turn_slip_sigma_s_per_rad)
      .field(r.turn_slip_applies);
  csv_.end_row();
}

DeadReckoningCsv::DeadReckoningCsv(const std::string& path)
    : csv_(path, dead_reckoning_columns()) {}

void DeadReckoningCsv::write(const DeadReckoningRow& r) {
  csv_.field(r.t_s)
      .field(rad_to_deg(r.lat_rad))
      .field(rad_to_deg(r.lon_rad))
      .field(r.height_m)
      .field(r.distance_m)
      .field(r.k_m_per_pulse)
      .field(r.k_source)
      .field(r.east_m)
      .field(r.north_m)
      .field(r.up_m)
      .field(rad_to_deg(r.heading_rad))
      .field(finite_or_empty(r.horizontal_error_m))
      .field(finite_or_empty(r.error_percent))
      .field(finite_or_empty(r.error_t_s));
  csv_.end_row();
}

NavigationPositionCsv::NavigationPositionCsv(const std::string& path)
    : csv_(path, navigation_position_columns()) {}

void NavigationPositionCsv::write(const NavigationPositionRow& r) {
  csv_.field(r.t_s)
      .field(rad_to_deg(r.lat_rad))
      .field(rad_to_deg(r.lon_rad))
      .field(r.height_m)
      .field(r.east_m)
      .field(r.north_m)
      .field(r.up_m)
      .field(finite_or_empty(r.var_east_m2))
      .field(finite_or_empty(r.var_north_m2))
      .field(finite_or_empty(r.var_up_m2))
      .field(r.status)
      .field(finite_or_empty(r.last_fix_t_s))
      .field(finite_or_empty(r.distance_since_fix_m));
  csv_.end_row();
}

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
      if (c == ',') out.emplace_back();
      else if (c != '\r') out.back() += c;
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

void parse(const CsvLines& t, MisalignmentRow& r) {
  r.t_s = t.number("t");
  r.heading_rad = deg_to_rad(t.number("heading_deg"));
  r.pitch_rad = deg_to_rad(t.number("pitch_deg"));
  r.heading_std_rad = deg_to_rad(t.number("heading_std_deg"));
  r.pitch_std_rad = deg_to_rad(t.number("pitch_std_deg"));
  r.converged = t.number("converged", 0.0) != 0.0;
  r.state = t.text("state");
  r.samples_used = static_cast<uint64_t>(t.number("samples_used", 0.0));
}

void parse(const CsvLines& t, ScaleFactorRow& r) {
  r.t_s = t.number("t");
  r.k_by_estimator.clear();
  for (const std::string& c : scale_factor_estimator_columns())
    if (t.has(c)) r.k_by_estimator.emplace_back(c.substr(2), t.optional_number(c));
  r.lambda_vff_lm_rls = t.optional_number("lambda_vff_lm_rls");
  r.estimator = t.text("estimator");
  r.k_m_per_pulse = t.optional_number("k_m_per_pulse");
  r.sigma_m_per_pulse = t.optional_number("sigma_m_per_pulse");
  r.forgetting_factor = t.number("forgetting_factor", 1.0);
  r.window_fill = t.number("window_fill", 0.0);
  r.converged = t.number("converged", 0.0) != 0.0;
  r.samples_accepted = static_cast<uint64_t>(t.number("samples_accepted", 0.0));
  r.samples_rejected = static_cast<uint64_t>(t.number("samples_rejected", 0.0));
  r.epoch_status = t.text("epoch_status");
  r.gnss_latency_s = t.number("gnss_latency_s", 0.0);
  r.gnss_latency_sigma_s = t.has("gnss_latency_sigma_s") ? t.optional_number("gnss_latency_sigma_s") : std::nullopt;
  r.turn_slip_s_per_rad = t.number("turn_slip_s_per_rad", 0.0);
  r.turn_slip_sigma_s_per_rad =
      t.has("turn_slip_sigma_s_per_rad") ? t.optional_number("turn_slip_sigma_s_per_rad") : std::nullopt;
  r.turn_slip_applies = t.number("turn_slip_applies", 0.0) != 0.0;
}

void parse(const CsvLines& t, DeadReckoningRow& r) {
  r.t_s = t.number("t");
  r.lat_rad = deg_to_rad(t.number("lat_deg"));
  r.lon_rad = deg_to_rad(t.number("lon_deg"));
  r.height_m = t.number("height_m");
  r.distance_m = t.number("distance_m");
  r.k_m_per_pulse = t.number("k_m_per_pulse");
  r.k_source = t.text("k_source");
  r.east_m = t.number("east_m");
  r.north_m = t.number("north_m");
  r.up_m = t.number("up_m");
  r.heading_rad = deg_to_rad(t.number("heading_deg"));
  r.horizontal_error_m = t.number("horizontal_error_m");
  r.error_percent = t.number("error_percent");
  // Files written before the error was evaluated per GNSS epoch have no error_t column.
  r.error_t_s = t.has("error_t") ? t.number("error_t") : std::numeric_limits<double>::quiet_NaN();
}

void parse(const CsvLines& t, NavigationPositionRow& r) {
  r.t_s = t.number("t");
  r.lat_rad = deg_to_rad(t.number("lat_deg"));
  r.lon_rad = deg_to_rad(t.number("lon_deg"));
  r.height_m = t.number("height_m");
  r.east_m = t.number("east_m");
  r.north_m = t.number("north_m");
  r.up_m = t.number("up_m");
  r.var_east_m2 = t.number("var_east_m2");
  r.var_north_m2 = t.number("var_north_m2");
  r.var_up_m2 = t.number("var_up_m2");
  r.status = t.text("status");
  r.last_fix_t_s = t.number("last_fix_t");
  r.distance_since_fix_m = t.number("distance_since_fix_m");
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
