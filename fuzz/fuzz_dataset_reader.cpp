// libFuzzer target: the dataset reader (read_dataset, docs/DATASET.md) fed whole file images, and what it
// accepts fed on to the sample builder and the dead reckoner.
//
// Input layout: the file images of one dataset directory separated by NUL bytes, in the order
//   odometer.csv \0 gnss.csv \0 ins.csv \0 truth.csv \0 meta.json
// A part that is not there (fewer NULs) is a missing file; a present but empty part an empty file.
// Seeds in fuzz/seeds/dataset_reader/ (see the README there).
//
// Findings: any crash or sanitizer report, any exception other than DatasetError from the reader
// (its documented error), and any broken promise of an accepted dataset: rows in strictly increasing
// finite time, finite required values, latitude and pitch in [-90, 90] deg, counts that add up; and
// the cores must accept whatever the reader accepted (a StreamInputError there would mean the reader
// let through what docs/DATASET.md calls a bad row).
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include <spdlog/spdlog.h>

#include "fuzz_support.hpp"
#include "odonav/dataset.hpp"
#include "odonav/dead_reckoning/dead_reckoner.hpp"
#include "odonav/frames.hpp"
#include "odonav/sample_builder.hpp"

namespace {

const char* const kFiles[] = {"odometer.csv", "gnss.csv", "ins.csv", "truth.csv", "meta.json"};
constexpr std::size_t kFileCount = sizeof(kFiles) / sizeof(kFiles[0]);

[[noreturn]] void broken_promise(const char* what) {
  std::fprintf(stderr, "odonav-fuzz-dataset_reader: accepted dataset breaks a promise: %s\n", what);
  std::abort();
}

void check(bool ok, const char* what) {
  if (!ok) broken_promise(what);
}

template <typename Rows>
void check_increasing_time(const Rows& rows, const char* what) {
  for (std::size_t i = 0; i < rows.size(); ++i) {
    check(std::isfinite(rows[i].t_s), what);
    if (i > 0) check(rows[i].t_s > rows[i - 1].t_s, what);
  }
}

void check_promises(const odonav::Dataset& d, const odonav::DatasetReadReport& report, bool skip_policy) {
  check_increasing_time(d.odometer, "odometer time not finite or not increasing");
  check_increasing_time(d.gnss, "gnss time not finite or not increasing");
  check_increasing_time(d.ins, "ins time not finite or not increasing");
  check_increasing_time(d.truth, "truth time not finite or not increasing");
  for (const auto& o : d.odometer) check(o.direction >= -1 && o.direction <= 1, "odometer direction");
  for (const auto& g : d.gnss) {
    check(std::isfinite(g.position.lat_rad) && std::isfinite(g.position.lon_rad) && std::isfinite(g.position.height_m),
          "gnss position not finite");
    check(std::abs(g.position.lat_rad) <= odonav::kPi / 2.0, "gnss latitude outside [-90, 90] deg");
    check(g.vel_enu_mps.allFinite(), "gnss velocity not finite");
    check(!g.pos_std_m || std::isfinite(*g.pos_std_m), "gnss pos_std_m not finite");
    check(!g.vel_std_mps || std::isfinite(*g.vel_std_mps), "gnss vel_std_mps not finite");
  }
  for (const auto& s : d.ins) {
    const odonav::Attitude& a = s.attitude;
    check(std::isfinite(a.heading_rad) && std::isfinite(a.pitch_rad) && std::isfinite(a.roll_rad),
          "ins attitude not finite");
    check(std::abs(a.pitch_rad) <= odonav::kPi / 2.0, "ins pitch outside [-90, 90] deg");
    check(!s.vel_enu_mps || s.vel_enu_mps->allFinite(), "ins velocity not finite");
  }
  // Each file's report counts exactly the rows the dataset holds.
  auto ends_with = [](const std::string& s, const std::string& tail) {
    return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
  };
  for (const auto& f : report.files) {
    if (ends_with(f.file, "odometer.csv")) check(f.rows_read == d.odometer.size(), "odometer rows_read");
    if (ends_with(f.file, "gnss.csv")) check(f.rows_read == d.gnss.size(), "gnss rows_read");
    if (ends_with(f.file, "ins.csv")) check(f.rows_read == d.ins.size(), "ins rows_read");
    if (ends_with(f.file, "truth.csv")) check(f.rows_read == d.truth.size(), "truth rows_read");
  }
  if (!skip_policy) check(report.total_bad() == 0, "fail policy returned a dataset with bad rows");
}

// Everything the reader accepted must go through the cores without a StreamInputError.
void run_cores(const odonav::Dataset& d) {
  odonav::SampleBuilderParams builder_params;
  builder_params.use_ins = d.has_ins();
  odonav::SampleBuilder builder(builder_params);
  odonav::dead_reckoning::DeadReckonerParams dr_params;
  dr_params.use_ins = d.has_ins();
  odonav::dead_reckoning::DeadReckoner dr(dr_params);
  for (const auto& o : d.odometer) {
    builder.add_odometer(o);
    dr.add_odometer(o);
  }
  for (const auto& g : d.gnss) {
    builder.add_gnss(g);
    dr.add_gnss(g);
  }
  for (const auto& s : d.ins) {
    builder.add_ins(s);
    dr.add_ins(s);
  }
  builder.finish();
  dr.finish();
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  // Bad rows are logged as warnings: silence them, or the fuzzer spends its time writing to stderr.
  spdlog::set_level(spdlog::level::off);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  const std::string dir = odonav::fuzz::scratch_dir() + "/dataset";
  static const bool made = std::filesystem::create_directories(dir);  // once; files are rewritten per input
  (void)made;
  const auto parts = odonav::fuzz::split_at_nul(data, size, kFileCount);
  for (std::size_t i = 0; i < kFileCount; ++i) {
    const std::string path = dir + "/" + kFiles[i];
    if (i < parts.size()) {
      odonav::fuzz::write_file(path, parts[i]);
    } else {
      std::remove(path.c_str());
    }
  }
  for (const odonav::BadRowPolicy policy : {odonav::BadRowPolicy::kFail, odonav::BadRowPolicy::kSkip}) {
    odonav::DatasetReadReport report;
    odonav::Dataset dataset;
    try {
      dataset = odonav::read_dataset(dir, policy, &report);
    } catch (const odonav::DatasetError&) {
      continue;  // the documented answer to a bad dataset
    }
    check_promises(dataset, report, policy == odonav::BadRowPolicy::kSkip);
    run_cores(dataset);
  }
  return 0;
}
