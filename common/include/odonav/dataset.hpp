#pragma once
// The odonav dataset directory, format v1 (docs/DATASET.md): the directory in memory, reader,
// writer (row by row: odonav/dataset_stream.hpp and odonav/dataset_writer.hpp). The row types (OdometerSample, GnssSample,
// InsSample, TruthSample) are the cores' sensor samples, in odonav/sensor_samples.hpp.
//
// Files hold degrees, metres, m/s; the types hold SI with radians. Time t_s is seconds on the
// one time base shared by every file of the directory.
#include <Eigen/Dense>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "odonav/sensor_samples.hpp"

namespace odonav {

/// meta.json. Every key optional.
struct DatasetMeta {
  std::string format = "odonav-dataset/1";
  std::string vehicle_id;
  std::string description;
  std::optional<double> k_nominal_m_per_pulse;
  /// "odometer": {"k_nominal_sigma_percent": s}: the nominal K's one-sigma, % of it, (0, 100]
  /// (kDefaultNominalKRelSigma when absent; --nominal-k-sigma-percent overrides it).
  std::optional<double> k_nominal_sigma_percent;
  std::optional<double> truth_misalignment_heading_deg;
  std::optional<double> truth_misalignment_pitch_deg;
  /// "gnss": {"lever_arm_m": [x, y, z]}: the GNSS antenna in the INS body frame (forward-left-up, m)
  /// from the INS reference point: installation geometry measured on the vehicle (configuration, not
  /// truth). odonav-offline uses it when --lever-arm is not given.
  std::optional<Eigen::Vector3d> gnss_lever_arm_m;
  /// The whole meta.json text as read (so writers can carry unknown keys through); empty if none.
  std::string raw_json;
};

/// Input bounds of the reader (docs/DATASET.md, "Limits"): a dataset file larger than this is refused
/// (about 20 h of 100 Hz odometer, INS and 10 Hz GNSS); a line longer than this is a bad row (a
/// real row has well under 1000 bytes).
inline constexpr std::uintmax_t kMaxDatasetFileBytes = std::uintmax_t{2} << 30;  // 2 GiB
inline constexpr std::size_t kMaxDatasetLineBytes = 64 * 1024;

/// Physical limits of a ground vehicle's data (docs/DATASET.md, "Physical limits"): a value outside
/// them is a bad row (or, in meta.json and --lever-arm, an error), because no recording of a land
/// vehicle can hold it and an estimator would turn it into a result that looks fine and is not.
inline constexpr double kMinHeight_m = -1000.0;  ///< WGS-84 ellipsoidal; the Dead Sea shore is about -400 m.
inline constexpr double kMaxHeight_m = 10000.0;
inline constexpr double kMaxVelocityComponent_mps = 500.0;  ///< per ENU component (GNSS, INS).
inline constexpr double kMaxHeadingMagnitude_deg = 720.0;   ///< headings are taken modulo 360 within this.
inline constexpr double kMaxRollMagnitude_deg = 180.0;
inline constexpr double kMaxLeverArmComponent_m = 20.0;  ///< GNSS antenna from the INS, per axis.

/// A whole dataset directory in memory.
struct Dataset {
  std::vector<OdometerSample> odometer;
  std::vector<GnssSample> gnss;
  std::vector<InsSample> ins;      ///< empty when ins.csv is absent (degraded mode).
  std::vector<TruthSample> truth;  ///< empty when truth.csv is absent.
  DatasetMeta meta;
  bool has_ins() const { return !ins.empty(); }
  bool has_truth() const { return !truth.empty(); }
};

/// What to do with a bad row (docs/DATASET.md "Bad rows and file errors"): stop with an error, or skip it and count it.
enum class BadRowPolicy { kFail, kSkip };

/// Parses "fail" / "skip"; throws std::invalid_argument naming the value otherwise.
BadRowPolicy parse_bad_row_policy(const std::string& text);

/// One rejected row: where and why. Message format: "<file>:<line>: column '<col>': <reason>".
struct BadRow {
  std::string file;
  std::size_t line = 0;  ///< 1-based line number in the file.
  std::string column;    ///< header name of the offending column (empty when the whole row is bad).
  std::string reason;
  std::string message() const;
};

/// Counts per file, and the first bad rows in detail.
struct FileReadReport {
  std::string file;
  std::size_t rows_read = 0;                 ///< good rows kept.
  std::size_t rows_bad = 0;                  ///< rows rejected.
  std::vector<std::string> ignored_columns;  ///< unknown header names (warned once).
};
/// Bad rows a DatasetReadReport keeps in detail (the rest are only counted).
inline constexpr std::size_t kMaxDetailedBadRows = 100;
struct DatasetReadReport {
  std::vector<FileReadReport> files;
  std::vector<BadRow> bad_rows;  ///< at most the first 100 in detail; counts are in files.
  std::size_t total_bad() const;
};

/// Thrown on a bad dataset under BadRowPolicy::kFail, a missing required file or column, or an
/// unreadable meta.json. what() names the file, and line and column where they apply.
class DatasetError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Reads a dataset directory. Validates every rule of docs/DATASET.md. Throws DatasetError.
/// In detail (docs/DATASET.md lists these too): fields may carry surrounding spaces; an empty optional field means absent
/// (direction 1, fix 1, no std, NaN in truth); INS ve/vn/vu come all or none (header and row);
/// pitch must lie in [-90, 90] deg; a duplicate or empty header name is a file error. A row with
/// more fields than the header is a BadRow with an empty column; with fewer, it names the first
/// missing column. Bad rows are logged (spdlog warn, the first 10 per file, then a count). A t column
/// that looks like nanoseconds, microseconds or milliseconds (docs/DATASET.md, "Time unit") is a
/// DatasetError under either policy. To read a dataset row by row in bounded memory, with the same
/// rules: DatasetStream (odonav/dataset_stream.hpp).
Dataset read_dataset(const std::string& dir, BadRowPolicy policy, DatasetReadReport* report = nullptr);

/// Writes a dataset directory (created if missing): odometer.csv, gnss.csv, ins.csv when present,
/// truth.csv when present, meta.json. Numbers written with enough digits to read back exactly
/// (t with 1 us resolution or better; angles to 1e-9 deg). Throws DatasetError on I/O failure.
/// Details: doubles are written in shortest round-trip form, so read_dataset gives back the same
/// bits; an angle is written as the degree value d with deg_to_rad(d) == the radian value whenever
/// such a d exists (always for values that were read from a file; for arbitrary radians about 9 %
/// have none and come back within 1 ulp). Optional columns (pos_std_m, vel_std_mps, INS ve/vn/vu,
/// each truth column) are written only when some row has them; absent values are empty fields.
/// A longitude outside [-pi, pi] is wrapped; a latitude or pitch outside [-pi/2, pi/2] or a
/// non-finite value is a DatasetError naming file, row and column, and then no file is written
/// under its real name. A stale ins.csv / truth.csv is removed when the dataset has none. meta.json
/// carries the unknown keys of meta.raw_json; the known keys come from the struct. This is
/// DatasetWriter (odonav/dataset_writer.hpp) with DatasetWriterOptions::for_dataset, fed file by
/// file; to write a dataset row by row as it is produced, use DatasetWriter directly.
void write_dataset(const std::string& dir, const Dataset& dataset);
}  // namespace odonav
