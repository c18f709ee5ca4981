#pragma once
// A dataset directory (docs/DATASET.md) read row by row instead of whole: the three sensor files
// merged into one stream in event-time order (DatasetStream), and truth.csv on its own
// (TruthStream). Memory does not grow with the length of the files: each file is read through a
// fixed buffer and only a few rows of each are held. The rows are parsed and validated by the same
// code as read_dataset's, so the samples, errors, bad-row counts and log lines are the same.
#include <cstddef>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "odonav/dataset.hpp"
#include "odonav/sensor_samples.hpp"

namespace odonav {

/// The file a DatasetEvent comes from.
enum class DatasetStreamKind { kOdometer, kGnss, kIns };

/// One row of a sensor file. `kind` says which of `odometer`, `gnss`, `ins` holds it; the other two
/// are default-constructed. `t_s` is that sample's t_s.
struct DatasetEvent {
  DatasetStreamKind kind = DatasetStreamKind::kOdometer;
  double t_s = 0.0;
  OdometerSample odometer;
  GnssSample gnss;
  InsSample ins;
};

/// odometer.csv, gnss.csv and ins.csv (when present) as one stream of samples in event-time order.
///
/// At construction, the checks read_dataset makes before it has data are made, in the same order
/// and with the same messages: the directory exists; odometer.csv is there, a regular file within
/// the size limit, with a valid header and at least 2 good rows; the same for gnss.csv; ins.csv, if
/// present, with a valid header (its first good row is read: an ins.csv without one is absent, as in
/// read_dataset); truth.csv, if present, with a valid header (has_truth looks for its first good
/// row; the rest is TruthStream's to read); meta.json read and checked. Everything else about a row
/// is found when the row is reached: under BadRowPolicy::kFail next() throws DatasetError naming
/// file, line and column; under kSkip the row is counted and logged as read_dataset does.
///
/// Memory: each file is read through a fixed buffer (a line is at most kMaxDatasetLineBytes), and at
/// most two rows per file are held ahead; the report keeps counts and at most the first 100 bad rows.
/// Not copyable (it owns open files); movable.
class DatasetStream {
 public:
  /// Opens the dataset and makes the checks above. Throws DatasetError. `report`, when given, is
  /// filled as the stream goes (one FileReadReport per sensor file from the start, its counts
  /// growing as rows are read; bad rows in detail as they are met) and must outlive the stream;
  /// without it the stream keeps its own (report()).
  DatasetStream(const std::string& dir, BadRowPolicy policy, DatasetReadReport* report = nullptr);
  ~DatasetStream();
  DatasetStream(DatasetStream&&) noexcept;
  DatasetStream& operator=(DatasetStream&&) noexcept;
  DatasetStream(const DatasetStream&) = delete;
  DatasetStream& operator=(const DatasetStream&) = delete;

  /// meta.json, or the defaults when there is none.
  const DatasetMeta& meta() const;
  /// ins.csv exists and has a good row (an ins.csv with none is absent: degraded mode).
  bool has_ins() const;
  /// truth.csv exists and has a good row (read it with TruthStream).
  bool has_truth() const;

  /// The next sample of the three sensor files in event-time order (a merge of the files by t_s);
  /// nullopt once every file is at its end. Throws DatasetError on a bad row under kFail when the
  /// row is reached (when the file's previous row has been given out).
  ///
  /// Equal t_s in several files: GNSS first, then INS, then odometer, always, so a run is
  /// reproducible. The order does not change the result of a consumer that processes an instant
  /// only once every stream has moved past it (the event-time watermark of the pipeline's cores,
  /// process_until): such a consumer has all samples of t_s before it acts on t_s. A consumer
  /// that acts on each sample as it arrives sees the GNSS epoch before the odometer and INS samples
  /// of the same instant, and must hold it until they come, as it must for a DDS arrival order.
  std::optional<DatasetEvent> next();

  /// The report being filled (the one given to the constructor, or the stream's own).
  const DatasetReadReport& report() const;
  /// Bytes held for reading (buffers and rows held ahead, over every open file): bounded whatever
  /// the length of the files. For tests and diagnostics.
  std::size_t buffered_bytes() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// truth.csv row by row, validated as read_dataset validates it (same errors, counts and logging).
/// A dataset without truth.csv gives an empty stream.
class TruthStream {
 public:
  /// Opens dir/truth.csv when it exists (its header checked). Throws DatasetError when the directory
  /// does not exist or on a file error. `report`: as for DatasetStream (one FileReadReport for
  /// truth.csv when it exists).
  TruthStream(const std::string& dir, BadRowPolicy policy, DatasetReadReport* report = nullptr);
  ~TruthStream();
  TruthStream(TruthStream&&) noexcept;
  TruthStream& operator=(TruthStream&&) noexcept;
  TruthStream(const TruthStream&) = delete;
  TruthStream& operator=(const TruthStream&) = delete;

  /// truth.csv exists (it may still have no good row).
  bool has_file() const;
  /// The next good row; nullopt at the end (at once without truth.csv). Throws DatasetError on a
  /// bad row under kFail.
  std::optional<TruthSample> next();
  /// The report being filled (the one given to the constructor, or the stream's own).
  const DatasetReadReport& report() const;
  /// Bytes held for reading: bounded whatever the length of the file. For tests and diagnostics.
  std::size_t buffered_bytes() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// One sensor file of a dataset row by row, apart from the merged stream, for a reader that looks
/// at it on its own (the summary reads GNSS ahead for outages, INS for the lever arm): gnss.csv or
/// ins.csv (or truth.csv), validated as read_dataset validates it. Quiet: its bad rows are skipped (kSkip) without
/// a log line or a report entry, since a DatasetStream over the same directory reports them; under
/// kFail a bad row throws DatasetError when it is reached. Each call of the function returns the
/// next good row, nullopt at the end (at once when the file does not exist). Memory as TruthStream.
std::function<std::optional<GnssSample>()> gnss_rows(const std::string& dir, BadRowPolicy policy);
std::function<std::optional<InsSample>()> ins_rows(const std::string& dir, BadRowPolicy policy);
/// truth.csv alike (TruthStream reports and logs its bad rows; this does not).
std::function<std::optional<TruthSample>()> truth_rows(const std::string& dir, BadRowPolicy policy);

}  // namespace odonav
