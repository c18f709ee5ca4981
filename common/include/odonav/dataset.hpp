#pragma once
// The odonav dataset directory, format v1 (docs/DATASET.md): types, reader, writer.
//
// Files hold degrees, metres, m/s; these types hold SI with radians. Time t_s is seconds on the
// one time base shared by every file of the directory.
#include <Eigen/Dense>
#include <cstdint>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "odonav/frames.hpp"
#include "odonav/geodesy.hpp"

namespace odonav {

/// One odometer.csv row. pulses is the raw accumulated uint32 counter (wraps 4294967295 -> 0).
struct OdometerSample {
  double t_s = 0.0;
  uint32_t pulses = 0;
  int direction = 1;  ///< +1 forward (default), -1 reversing, 0 unknown.
};

/// One gnss.csv row. Position WGS-84, velocity in local ENU (m/s).
struct GnssSample {
  double t_s = 0.0;
  Geodetic position;
  Eigen::Vector3d vel_enu_mps = Eigen::Vector3d::Zero();
  std::optional<double> pos_std_m;    ///< one-sigma horizontal accuracy if given.
  std::optional<double> vel_std_mps;  ///< one-sigma velocity accuracy if given.
  int fix = 1;                        ///< NMEA GGA quality; 0 and 6 are not a reference.
  /// True when the row may be used as a reference (fix not 0 or 6).
  bool valid() const { return fix != 0 && fix != 6; }
};

/// One ins.csv row. Attitude of the body (see frames.hpp); optional ENU velocity (m/s).
struct InsSample {
  double t_s = 0.0;
  Attitude attitude;
  std::optional<Eigen::Vector3d> vel_enu_mps;
};

/// One truth.csv row. Columns other than t are optional in the file: absent ones read as NaN.
struct TruthSample {
  double t_s = 0.0;
  Geodetic position{std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN(),
                    std::numeric_limits<double>::quiet_NaN()};
  Attitude attitude{std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN(),
                    std::numeric_limits<double>::quiet_NaN()};
  double k_true_m_per_pulse = std::numeric_limits<double>::quiet_NaN();
  double distance_m = std::numeric_limits<double>::quiet_NaN();
};

/// meta.json. Every key optional.
struct DatasetMeta {
  std::string format = "odonav-dataset/1";
  std::string vehicle_id;
  std::string description;
  std::optional<double> k_nominal_m_per_pulse;
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
inline constexpr double kMinHeight_m = -1000.0;       ///< WGS-84 ellipsoidal; the Dead Sea shore is about -400 m.
inline constexpr double kMaxHeight_m = 10000.0;
inline constexpr double kMaxVelocityComponent_mps = 500.0;  ///< per ENU component (GNSS, INS).
inline constexpr double kMaxHeadingMagnitude_deg = 720.0;   ///< headings are taken modulo 360 within this.
inline constexpr double kMaxRollMagnitude_deg = 180.0;
inline constexpr double kMaxLeverArmComponent_m = 20.0;     ///< GNSS antenna from the INS, per axis.

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
  std::size_t line = 0;   ///< 1-based line number in the file.
  std::string column;     ///< header name of the offending column (empty when the whole row is bad).
  std::string reason;
  std::string message() const;
};

/// Counts per file, and the first bad rows in detail.
struct FileReadReport {
  std::string file;
  std::size_t rows_read = 0;   ///< good rows kept.
  std::size_t rows_bad = 0;    ///< rows rejected.
  std::vector<std::string> ignored_columns;  ///< unknown header names (warned once).
};
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
/// missing column. Bad rows are logged (spdlog warn, the first 10 per file, then a count).
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
/// non-finite value is a DatasetError naming file, row and column, and then nothing is written.
/// A stale ins.csv / truth.csv is removed when the dataset has none. meta.json carries the unknown
/// keys of meta.raw_json; the known keys come from the struct.
void write_dataset(const std::string& dir, const Dataset& dataset);

/// Counter increment from `from` to `to`, modulo 2^32 (a wrap is not a jump).
inline uint32_t pulse_increment(uint32_t from, uint32_t to) { return to - from; }

}  // namespace odonav
