// DatasetStream and TruthStream (odonav/dataset_stream.hpp): the dataset files through the one row
// parser (dataset_rows.cpp), merged by t_s with a few rows held per file.
#include "odonav/dataset_stream.hpp"

#include <array>
#include <filesystem>
#include <memory>
#include <utility>

#include "dataset_internal.hpp"
#include "dataset_rows.hpp"

namespace odonav {

using dataset_detail::file_exists;
using dataset_detail::join_path;
using dataset_detail::ReadContext;
using dataset_detail::RowReader;

namespace {

void require_directory(const std::string& dir) {
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) throw DatasetError(dir + ": dataset directory does not exist");
}

// One file of the stream: its reader, the good rows read ahead (at most kAhead, oldest first), and
// its entry in the report, whose counts follow the reader's.
template <typename Sample>
class Source {
 public:
  static constexpr std::size_t kAhead = 2;  // "at least 2 good rows" is checked by reading two ahead

  /// Opens `path` (header checked) and adds its entry to `report`.
  void open(const std::string& path, const ReadContext& context, DatasetReadReport& report) {
    rows_.emplace(path, context);
    report_ = &report;
    report_index_ = report.files.size();
    report.files.push_back(rows_->file_report());
  }
  bool is_open() const { return rows_.has_value(); }

  /// Reads ahead until `count` rows are held or the file ends; the number held.
  std::size_t fill(std::size_t count) {
    while (rows_ && !ended_ && held_ < count) {
      std::optional<Sample> row = rows_->next();
      sync_report();
      if (!row) {
        ended_ = true;
        break;
      }
      ahead_[(first_ + held_) % kAhead] = *row;
      ++held_;
    }
    return held_;
  }
  /// The oldest row held, or null.
  const Sample* head() const { return held_ > 0 ? &ahead_[first_] : nullptr; }
  Sample pop() {
    const Sample row = ahead_[first_];
    first_ = (first_ + 1) % kAhead;
    --held_;
    return row;
  }
  std::size_t bad_rows() const { return rows_ ? rows_->file_report().rows_bad : 0; }
  std::size_t buffered_bytes() const { return (rows_ ? rows_->buffered_bytes() : 0) + sizeof(ahead_); }

 private:
  void sync_report() {
    FileReadReport& entry = report_->files[report_index_];
    entry.rows_read = rows_->file_report().rows_read;
    entry.rows_bad = rows_->file_report().rows_bad;
  }

  std::optional<RowReader<Sample>> rows_;
  std::array<Sample, kAhead> ahead_{};
  std::size_t first_ = 0, held_ = 0;
  bool ended_ = false;
  DatasetReadReport* report_ = nullptr;
  std::size_t report_index_ = 0;
};

}  // namespace

// ---------------------------------------------------------------------------------------------------
// DatasetStream

struct DatasetStream::Impl {
  DatasetReadReport own_report;
  DatasetReadReport* report = nullptr;
  Source<OdometerSample> odometer;
  Source<GnssSample> gnss;
  Source<InsSample> ins;
  DatasetMeta meta;
  bool has_ins = false;
  bool has_truth = false;
};

DatasetStream::DatasetStream(const std::string& dir, BadRowPolicy policy, DatasetReadReport* report)
    : impl_(std::make_unique<Impl>()) {
  Impl& s = *impl_;
  s.report = report ? report : &s.own_report;
  const ReadContext context{policy, s.report, true};
  require_directory(dir);

  // The same checks, in the same order, as read_dataset.
  const auto open_required = [&](auto& source, const char* name) {
    const std::string path = join_path(dir, name);
    if (!file_exists(path)) throw DatasetError(path + ": required file is missing");
    source.open(path, context, *s.report);
    dataset_detail::require_two_rows(path, source.fill(2), source.bad_rows(), report != nullptr);
  };
  open_required(s.odometer, "odometer.csv");
  open_required(s.gnss, "gnss.csv");

  const std::string ins_path = join_path(dir, "ins.csv");
  if (file_exists(ins_path)) {
    s.ins.open(ins_path, context, *s.report);
    s.has_ins = s.ins.fill(1) > 0;
  }
  const std::string truth_path = join_path(dir, "truth.csv");
  if (file_exists(truth_path)) {
    // A look at the header and the first good row only, quietly: TruthStream reads, counts and
    // logs the file's rows.
    RowReader<TruthSample> probe(truth_path, ReadContext{policy, nullptr, false});
    s.has_truth = probe.next().has_value();
  }
  const std::string meta_path = join_path(dir, "meta.json");
  if (file_exists(meta_path)) s.meta = dataset_detail::read_meta(meta_path);
}

DatasetStream::~DatasetStream() = default;
DatasetStream::DatasetStream(DatasetStream&&) noexcept = default;
DatasetStream& DatasetStream::operator=(DatasetStream&&) noexcept = default;

const DatasetMeta& DatasetStream::meta() const { return impl_->meta; }
bool DatasetStream::has_ins() const { return impl_->has_ins; }
bool DatasetStream::has_truth() const { return impl_->has_truth; }
const DatasetReadReport& DatasetStream::report() const { return *impl_->report; }

std::size_t DatasetStream::buffered_bytes() const {
  return impl_->odometer.buffered_bytes() + impl_->gnss.buffered_bytes() + impl_->ins.buffered_bytes();
}

std::optional<DatasetEvent> DatasetStream::next() {
  Impl& s = *impl_;
  // A file's next row is read only now, once its previous row has been given out: a bad row is
  // met when the stream reaches it.
  s.gnss.fill(1);
  s.ins.fill(1);
  s.odometer.fill(1);
  // The earliest head; on equal t_s the first in this order wins: GNSS, INS, odometer.
  const GnssSample* gnss = s.gnss.head();
  const InsSample* ins = s.ins.head();
  const OdometerSample* odometer = s.odometer.head();
  DatasetEvent event;
  if (gnss && (!ins || gnss->t_s <= ins->t_s) && (!odometer || gnss->t_s <= odometer->t_s)) {
    event.kind = DatasetStreamKind::kGnss;
    event.gnss = s.gnss.pop();
    event.t_s = event.gnss.t_s;
  } else if (ins && (!odometer || ins->t_s <= odometer->t_s)) {
    event.kind = DatasetStreamKind::kIns;
    event.ins = s.ins.pop();
    event.t_s = event.ins.t_s;
  } else if (odometer) {
    event.kind = DatasetStreamKind::kOdometer;
    event.odometer = s.odometer.pop();
    event.t_s = event.odometer.t_s;
  } else {
    return std::nullopt;
  }
  return event;
}

// ---------------------------------------------------------------------------------------------------
// TruthStream

struct TruthStream::Impl {
  DatasetReadReport own_report;
  DatasetReadReport* report = nullptr;
  Source<TruthSample> truth;
};

TruthStream::TruthStream(const std::string& dir, BadRowPolicy policy, DatasetReadReport* report)
    : impl_(std::make_unique<Impl>()) {
  Impl& s = *impl_;
  s.report = report ? report : &s.own_report;
  require_directory(dir);
  const std::string path = join_path(dir, "truth.csv");
  if (file_exists(path)) s.truth.open(path, ReadContext{policy, s.report, true}, *s.report);
}

TruthStream::~TruthStream() = default;
TruthStream::TruthStream(TruthStream&&) noexcept = default;
TruthStream& TruthStream::operator=(TruthStream&&) noexcept = default;

bool TruthStream::has_file() const { return impl_->truth.is_open(); }
const DatasetReadReport& TruthStream::report() const { return *impl_->report; }
std::size_t TruthStream::buffered_bytes() const { return impl_->truth.buffered_bytes(); }

std::optional<TruthSample> TruthStream::next() {
  if (impl_->truth.fill(1) == 0) return std::nullopt;
  return impl_->truth.pop();
}

// ---------------------------------------------------------------------------------------------------
// One file on its own

namespace {
template <typename Sample>
std::function<std::optional<Sample>()> file_rows(const std::string& dir, const char* name, BadRowPolicy policy) {
  struct State {
    DatasetReadReport report;  // the Source's entry; nothing reads it
    Source<Sample> rows;
  };
  require_directory(dir);
  auto state = std::make_shared<State>();
  const std::string path = join_path(dir, name);
  if (file_exists(path)) state->rows.open(path, ReadContext{policy, nullptr, false}, state->report);
  return [state]() -> std::optional<Sample> {
    if (state->rows.fill(1) == 0) return std::nullopt;
    return state->rows.pop();
  };
}
}  // namespace

std::function<std::optional<GnssSample>()> gnss_rows(const std::string& dir, BadRowPolicy policy) {
  return file_rows<GnssSample>(dir, "gnss.csv", policy);
}

std::function<std::optional<InsSample>()> ins_rows(const std::string& dir, BadRowPolicy policy) {
  return file_rows<InsSample>(dir, "ins.csv", policy);
}

std::function<std::optional<TruthSample>()> truth_rows(const std::string& dir, BadRowPolicy policy) {
  return file_rows<TruthSample>(dir, "truth.csv", policy);
}

}  // namespace odonav
