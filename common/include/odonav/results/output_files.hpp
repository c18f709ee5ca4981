#pragma once
// odonav_results: the output files of odonav-offline, and of the distributed pipeline's recorder
// (deploy/launch): the same files and columns from both, so a user can run either and compare them
// directly; odonav-evaluate reads them back. A library of its own (middleware-free, no estimator or
// core inside) so the recorder writes the formats without linking the offline chain.
//
//   misalignment.csv        t, heading_deg, pitch_deg, heading_std_deg, pitch_std_deg, converged,
//                           state, samples_used                        (one row per GNSS epoch)
//   scale_factor.csv        t, k_rls, k_ff_rls, k_lm_rls, k_vff_lm_rls, k_coarse, k_kf_rw,
//                           lambda_vff_lm_rls, estimator, k_m_per_pulse, sigma_m_per_pulse,
//                           forgetting_factor, window_fill, converged, samples_accepted,
//                           samples_rejected, epoch_status               (one row per GNSS epoch)
//     k_<name>: that estimator's K (m/pulse), empty until it has a value or when it did not run;
//     the columns after lambda_vff_lm_rls describe the main (published) estimator.
//   dead_reckoning.csv,     t, lat_deg, lon_deg, height_m, distance_m, k_m_per_pulse, k_source,
//   dead_reckoning_coarse.csv  east_m, north_m, up_m, heading_deg, horizontal_error_m,
//                           error_percent, error_t                      (one row per odometer sample)
//     horizontal_error_m / error_percent: against the GNSS fix of epoch error_t, evaluated once that
//     epoch's hold-off has passed (consumer_rules.hpp) and carried until the next epoch's.
//   navigation_position.csv t, lat_deg, lon_deg, height_m, east_m, north_m, up_m, var_east_m2,
//                           var_north_m2, var_up_m2, status, last_fix_t, distance_since_fix_m
//                           (one row per odometer sample: the GNSS-anchored position of the online
//                           DR; status not_started | anchored | dead_reckoning; the variances and
//                           last_fix_t empty while not_started)
// Numbers are written in the shortest form that reads back to the same double; unknown values are
// empty fields.
#include <memory>
#include <optional>
#include <limits>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "odonav/csv_writer.hpp"

namespace odonav::results {

/// The estimator columns of scale_factor.csv, in order.
const std::vector<std::string>& scale_factor_estimator_columns();
/// Each file's header (its columns, in order), as its writer writes it.
const std::vector<std::string>& misalignment_columns();
const std::vector<std::string>& scale_factor_columns();
const std::vector<std::string>& dead_reckoning_columns();
const std::vector<std::string>& navigation_position_columns();

/// One misalignment.csv row (angles in radians here, degrees in the file).
struct MisalignmentRow {
  double t_s = 0.0;
  double heading_rad = 0.0;
  double pitch_rad = 0.0;
  double heading_std_rad = 0.0;  ///< NaN/inf when unknown (written empty).
  double pitch_std_rad = 0.0;
  bool converged = false;
  std::string state;
  uint64_t samples_used = 0;
};

/// One scale_factor.csv row.
struct ScaleFactorRow {
  double t_s = 0.0;
  /// K per estimator name (names of scale_factor_estimator_columns() without "k_"); nullopt = empty.
  std::vector<std::pair<std::string, std::optional<double>>> k_by_estimator;
  std::optional<double> lambda_vff_lm_rls;
  std::string estimator;  ///< main estimator
  std::optional<double> k_m_per_pulse;
  std::optional<double> sigma_m_per_pulse;
  double forgetting_factor = 1.0;
  double window_fill = 0.0;
  bool converged = false;
  uint64_t samples_accepted = 0;
  uint64_t samples_rejected = 0;
  std::string epoch_status;
  /// GNSS latency in force [s] and its one-sigma [s]: the online estimate's when it was applied (0
  /// when fixed; nullopt while none was applied).
  double gnss_latency_s = 0.0;
  std::optional<double> gnss_latency_sigma_s;
  /// Track slip in turns (turn_slip.hpp): the gain g [s/rad] (0 without an estimate), its
  /// one-sigma [s/rad] (nullopt = none yet), whether dead reckoning applies it.
  double turn_slip_s_per_rad = 0.0;
  std::optional<double> turn_slip_sigma_s_per_rad;
  bool turn_slip_applies = false;
};

/// One dead_reckoning.csv row (angles in radians here, degrees in the file).
struct DeadReckoningRow {
  double t_s = 0.0;
  double lat_rad = 0.0, lon_rad = 0.0, height_m = 0.0;
  double distance_m = 0.0;
  double k_m_per_pulse = 0.0;
  std::string k_source;
  double east_m = 0.0, north_m = 0.0, up_m = 0.0;
  double heading_rad = 0.0;
  double horizontal_error_m = 0.0;  ///< NaN when no GNSS reference (written empty).
  double error_percent = 0.0;       ///< NaN when undefined (written empty).
  double error_t_s = 0.0;           ///< GNSS epoch the error refers to (s); NaN when none (written empty).
};

/// One navigation_position.csv row (angles in radians here, degrees in the file).
struct NavigationPositionRow {
  double t_s = 0.0;
  double lat_rad = 0.0, lon_rad = 0.0, height_m = 0.0;
  double east_m = 0.0, north_m = 0.0, up_m = 0.0;
  double var_east_m2 = 0.0, var_north_m2 = 0.0, var_up_m2 = 0.0;  ///< NaN = unknown (written empty).
  std::string status;
  double last_fix_t_s = 0.0;          ///< NaN = none yet (written empty).
  double distance_since_fix_m = 0.0;  ///< NaN = none yet (written empty).
};

/// The column table of each row type: one line per column, in file order, naming the column and
/// the row member it holds, with the kind of value. The header, the writer and the reader of every
/// file are made from it (a new column is one line here). visit_columns(row, v) calls, per column,
/// one of these members of v (Row may be const for writing):
///   number(name, double&, if_empty)      the double as is (NaN: empty field); read: empty -> if_empty
///   finite(name, double&)                not finite -> empty field; read: empty -> NaN
///   degrees(name, double& rad)           radians in the row, degrees in the file
///   finite_degrees(name, double& rad)    the same, not finite -> empty field
///   optional(name, std::optional<double>&)   nullopt <-> empty field
///   text(name, std::string&)             no ',' or newline
///   flag(name, bool&)                    1 / 0
///   count(name, uint64_t&)
///   estimators(std::vector<std::pair<std::string, std::optional<double>>>&)
///                                        the k_<name> columns (scale_factor_estimator_columns())
/// A trailing `Since::kLater` marks a column that files of older versions lack (read: as empty).
enum class Since { kFirst, kLater };

template <class Row, class V>
void visit_columns(Row& r, V&& v) {
  static_assert(std::is_same_v<std::remove_const_t<Row>, MisalignmentRow> ||
                    std::is_same_v<std::remove_const_t<Row>, ScaleFactorRow> ||
                    std::is_same_v<std::remove_const_t<Row>, DeadReckoningRow> ||
                    std::is_same_v<std::remove_const_t<Row>, NavigationPositionRow>,
                "visit_columns: not an output row type");
  using R = std::remove_const_t<Row>;
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  if constexpr (std::is_same_v<R, MisalignmentRow>) {
    v.number("t", r.t_s, kNaN);
    v.degrees("heading_deg", r.heading_rad);
    v.degrees("pitch_deg", r.pitch_rad);
    v.finite_degrees("heading_std_deg", r.heading_std_rad);
    v.finite_degrees("pitch_std_deg", r.pitch_std_rad);
    v.flag("converged", r.converged);
    v.text("state", r.state);
    v.count("samples_used", r.samples_used);
  } else if constexpr (std::is_same_v<R, ScaleFactorRow>) {
    v.number("t", r.t_s, kNaN);
    v.estimators(r.k_by_estimator);
    v.optional("lambda_vff_lm_rls", r.lambda_vff_lm_rls);
    v.text("estimator", r.estimator);
    v.optional("k_m_per_pulse", r.k_m_per_pulse);
    v.optional("sigma_m_per_pulse", r.sigma_m_per_pulse);
    v.number("forgetting_factor", r.forgetting_factor, 1.0);
    v.number("window_fill", r.window_fill, 0.0);
    v.flag("converged", r.converged);
    v.count("samples_accepted", r.samples_accepted);
    v.count("samples_rejected", r.samples_rejected);
    v.text("epoch_status", r.epoch_status);
    v.number("gnss_latency_s", r.gnss_latency_s, 0.0);
    v.optional("gnss_latency_sigma_s", r.gnss_latency_sigma_s, Since::kLater);
    v.number("turn_slip_s_per_rad", r.turn_slip_s_per_rad, 0.0);
    v.optional("turn_slip_sigma_s_per_rad", r.turn_slip_sigma_s_per_rad, Since::kLater);
    v.flag("turn_slip_applies", r.turn_slip_applies);
  } else if constexpr (std::is_same_v<R, DeadReckoningRow>) {
    v.number("t", r.t_s, kNaN);
    v.degrees("lat_deg", r.lat_rad);
    v.degrees("lon_deg", r.lon_rad);
    v.number("height_m", r.height_m, kNaN);
    v.number("distance_m", r.distance_m, kNaN);
    v.number("k_m_per_pulse", r.k_m_per_pulse, kNaN);
    v.text("k_source", r.k_source);
    v.number("east_m", r.east_m, kNaN);
    v.number("north_m", r.north_m, kNaN);
    v.number("up_m", r.up_m, kNaN);
    v.degrees("heading_deg", r.heading_rad);
    v.finite("horizontal_error_m", r.horizontal_error_m);
    v.finite("error_percent", r.error_percent);
    v.finite("error_t", r.error_t_s, Since::kLater);
  } else {
    v.number("t", r.t_s, kNaN);
    v.degrees("lat_deg", r.lat_rad);
    v.degrees("lon_deg", r.lon_rad);
    v.number("height_m", r.height_m, kNaN);
    v.number("east_m", r.east_m, kNaN);
    v.number("north_m", r.north_m, kNaN);
    v.number("up_m", r.up_m, kNaN);
    v.finite("var_east_m2", r.var_east_m2);
    v.finite("var_north_m2", r.var_north_m2);
    v.finite("var_up_m2", r.var_up_m2);
    v.text("status", r.status);
    v.finite("last_fix_t", r.last_fix_t_s);
    v.finite("distance_since_fix_m", r.distance_since_fix_m);
  }
}

/// A row as a JSON object with the file's column names and units (degrees where the file has
/// them): what the ground station serves, so a column added to the table reaches its JSON too.
/// An empty field of the file (NaN, nullopt, a k_<name> of an estimator that did not run) is null.
nlohmann::json row_json(const MisalignmentRow& row);
nlohmann::json row_json(const ScaleFactorRow& row);
nlohmann::json row_json(const DeadReckoningRow& row);
nlohmann::json row_json(const NavigationPositionRow& row);

/// The writer of one output file, rows of type Row (MisalignmentRow, ScaleFactorRow,
/// DeadReckoningRow, NavigationPositionRow). The constructor creates the file with its header
/// (throws std::runtime_error naming it).
template <class Row>
class RowCsv {
 public:
  explicit RowCsv(const std::string& path);
  void write(const Row& row);
  void close() { csv_.close(); }
  CsvWriter& csv() { return csv_; }  ///< rows adopted as text, flushes (odonav-recorder)
 private:
  CsvWriter csv_;
};
extern template class RowCsv<MisalignmentRow>;
extern template class RowCsv<ScaleFactorRow>;
extern template class RowCsv<DeadReckoningRow>;
extern template class RowCsv<NavigationPositionRow>;
using MisalignmentCsv = RowCsv<MisalignmentRow>;
using ScaleFactorCsv = RowCsv<ScaleFactorRow>;
using DeadReckoningCsv = RowCsv<DeadReckoningRow>;
using NavigationPositionCsv = RowCsv<NavigationPositionRow>;

/// Everything the output files hold, read back (for odonav-evaluate and the pipeline's summary).
struct OutputRows {
  std::vector<MisalignmentRow> misalignment;
  std::vector<ScaleFactorRow> scale_factor;
  std::vector<DeadReckoningRow> dead_reckoning;
  std::vector<DeadReckoningRow> dead_reckoning_coarse;     ///< empty when the file is absent.
  std::vector<NavigationPositionRow> navigation_position;  ///< empty when the file is absent.
};

/// Reads one output file a row at a time, in memory that does not grow with the file. The
/// constructor opens the file and reads its header; next(row) fills row with the next row (the
/// caller's object is reused) and returns false at the end. Throws std::runtime_error naming the
/// file, and the line and column where they apply, on a missing file, a row with the wrong number of
/// fields, a missing column or a malformed value.
class OutputFileReader {
 public:
  explicit OutputFileReader(const std::string& path);
  ~OutputFileReader();
  OutputFileReader(OutputFileReader&&) noexcept;
  OutputFileReader& operator=(OutputFileReader&&) noexcept;
  bool next(MisalignmentRow& row);        ///< misalignment.csv
  bool next(ScaleFactorRow& row);         ///< scale_factor.csv
  bool next(DeadReckoningRow& row);       ///< dead_reckoning.csv, dead_reckoning_coarse.csv
  bool next(NavigationPositionRow& row);  ///< navigation_position.csv

 private:
  template <class Row>
  bool read(Row& row);
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Whether an (optional) output file exists.
bool output_file_exists(const std::string& path);

/// Reads the output files of a folder (dead_reckoning_coarse.csv, navigation_position.csv optional). Throws
/// std::runtime_error naming the file, line and column on a missing file or a malformed value.
/// OutputFileReader over each file.
OutputRows read_output_rows(const std::string& dir);

/// Writes misalignment.csv, scale_factor.csv, dead_reckoning.csv and (when they have rows)
/// dead_reckoning_coarse.csv and navigation_position.csv into dir (which must exist). Throws std::runtime_error naming the file.
void write_output_rows(const std::string& dir, const OutputRows& rows);
}  // namespace odonav::results
