#pragma once
// The dataset writer, format v1 (docs/DATASET.md), row by row: each file is written through a
// CsvWriter with a bounded buffer, so a drive of any length is written in the same memory.
// write_dataset (odonav/dataset.hpp) is this writer fed from a Dataset in memory.
//
// Which optional columns and files are written must be known before the first row (the header is
// the first line); write_dataset decides them from the rows, a producer such as the simulator knows
// them. Numbers and checks are those of write_dataset: shortest round-trip doubles, angles as the
// degree value whose deg_to_rad is the radian value, longitudes wrapped into [-180, 180], a
// non-finite value or a latitude/pitch outside [-90, 90] deg a DatasetError naming file, row and
// column.
//
// What a directory holds, when:
// - while writing, and after a failed or abandoned writer (an exception, destruction without
//   finish()): no file of this writer under its real name; the rows so far are in
//   `<file>.tmp-<pid>` temporaries, which the writer removes when it is destroyed (a killed process
//   leaves them). The files of an earlier dataset in the directory stay as they were.
// - finish(): every file is flushed and meta.json is written to its temporary first, then the files
//   are renamed into place in the order odometer.csv, gnss.csv, ins.csv, truth.csv, meta.json (a
//   stale ins.csv / truth.csv removed when this dataset has none). Only a failing rename or close in
//   that last step can leave a mixed set (the files renamed before it are the new ones); meta.json,
//   renamed last, is new only when every file is.
#include <cstddef>
#include <memory>
#include <string>

#include "odonav/dataset.hpp"

namespace odonav {

/// The optional columns of truth.csv (t is always written). Absent values (NaN) of a column that is
/// written are empty fields.
struct TruthColumns {
  bool lat_deg = true;
  bool lon_deg = true;
  bool height_m = true;
  bool heading_deg = true;
  bool pitch_deg = true;
  bool roll_deg = true;
  bool k_true = true;
  bool distance_m = true;
};

/// What a DatasetWriter writes besides the required files and columns.
struct DatasetWriterOptions {
  bool gnss_pos_std_m = false;    ///< gnss.csv has a pos_std_m column.
  bool gnss_vel_std_mps = false;  ///< gnss.csv has a vel_std_mps column.
  bool ins = false;               ///< ins.csv is written (else a stale one is removed at finish()).
  bool ins_velocity = false;      ///< ins.csv has ve, vn, vu.
  bool truth = false;             ///< truth.csv is written (else a stale one is removed at finish()).
  TruthColumns truth_columns;

  /// What write_dataset writes for `dataset`: an optional column when some row has a value for it,
  /// ins.csv / truth.csv when the dataset has rows of them.
  static DatasetWriterOptions for_dataset(const Dataset& dataset);
};

/// Rows written so far, per file.
struct DatasetRowCounts {
  std::size_t odometer = 0;
  std::size_t gnss = 0;
  std::size_t ins = 0;
  std::size_t truth = 0;
};

/// Writes one dataset directory row by row; see the file comment for what the directory holds when.
/// Rows of each file are written in the order they are added (each file must be in time order for
/// the reader; the files may be fed interleaved in any way).
class DatasetWriter {
 public:
  /// Creates `dir` (and parents) if missing and opens the temporaries of every file the options ask
  /// for. Throws DatasetError naming the path (a symbolic link, a directory in the way, I/O).
  DatasetWriter(const std::string& dir, const DatasetWriterOptions& options);
  ~DatasetWriter();
  DatasetWriter(const DatasetWriter&) = delete;
  DatasetWriter& operator=(const DatasetWriter&) = delete;

  /// Append one row. Throw DatasetError naming file, row (1-based, the header not counted) and
  /// column for a value that cannot be written, or for a value in a column the options left out (it
  /// would be lost), or for an INS / truth row when that file is not written; on I/O failure too.
  /// After an exception the writer is failed: every further call throws std::logic_error.
  void add(const OdometerSample& row);
  void add(const GnssSample& row);
  void add(const InsSample& row);
  void add(const TruthSample& row);

  /// Writes meta.json and renames every file into place (file comment). Throws DatasetError on a
  /// bad meta (nothing renamed then) or I/O failure; std::logic_error when called twice or after a
  /// failure.
  void finish(const DatasetMeta& meta);

  const std::string& dir() const { return dir_; }
  DatasetRowCounts rows() const;
  /// Bytes of row text the writer holds in memory (the capacity of its CSV buffers): bounded by a
  /// fixed buffer size plus one row per file, whatever the number of rows.
  std::size_t buffer_capacity_bytes() const;

 private:
  struct Files;
  template <class F>
  void guarded(F&& write);
  std::string dir_;
  DatasetWriterOptions options_;
  std::unique_ptr<Files> files_;
  bool failed_ = false;
  bool finished_ = false;
};

}  // namespace odonav
