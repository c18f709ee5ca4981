// libFuzzer target: the whole offline run, reader and processing, on small datasets: read_dataset
// (skipping bad rows, as odonav-offline --on-bad-row=skip), then run_offline (calibration,
// identification, dead reckoning with its consistency checks, the coarse-K pass) and the run's
// diagnosis, as odonav-offline runs them.
//
// Input layout: as fuzz_dataset_reader.cpp (odometer.csv \0 gnss.csv \0 ins.csv \0 truth.csv \0
// meta.json). Seeds in fuzz/seeds/offline_run/ (see the README there): time stamps in nanoseconds,
// microseconds and milliseconds, a negated and a radian INS heading, a GNSS fix 1000 km away.
//
// Findings: any crash or sanitizer report; a run that does not finish within libFuzzer's -timeout
// (a loop bounded by the span of the stamps instead of the data) or grows beyond -rss_limit_mb;
// a StreamInputError from the processing of an accepted dataset (the reader let through what
// docs/DATASET.md calls a bad row); any exception but DatasetError from the reader and
// std::invalid_argument naming a parameter (a meta.json value the components refuse).
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <string>

#include <spdlog/spdlog.h>

#include "fuzz_support.hpp"
#include "odonav/dataset.hpp"
#include "odonav/offline/offline_runner.hpp"
#include "odonav/offline/run_diagnosis.hpp"

namespace {
const char* const kFiles[] = {"odometer.csv", "gnss.csv", "ins.csv", "truth.csv", "meta.json"};
constexpr std::size_t kFileCount = sizeof(kFiles) / sizeof(kFiles[0]);
}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  spdlog::set_level(spdlog::level::off);  // bad rows and warnings: not the fuzzer's business
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  const std::string dir = odonav::fuzz::scratch_dir() + "/offline_run";
  static const bool made = std::filesystem::create_directories(dir);
  (void)made;
  const auto parts = odonav::fuzz::split_at_nul(data, size, kFileCount);
  for (std::size_t i = 0; i < kFileCount; ++i) {
    const std::string path = dir + "/" + kFiles[i];
    if (i < parts.size())
      odonav::fuzz::write_file(path, parts[i]);
    else
      std::remove(path.c_str());
  }
  odonav::Dataset dataset;
  try {
    dataset = odonav::read_dataset(dir, odonav::BadRowPolicy::kSkip);
  } catch (const odonav::DatasetError&) {
    return 0;  // the documented answer to a bad dataset
  }
  odonav::offline::OfflineParams params;
  if (dataset.meta.k_nominal_m_per_pulse) {
    params.dead_reckoning.nominal_k_m_per_pulse = *dataset.meta.k_nominal_m_per_pulse;
  }
  try {
    const odonav::offline::OfflineResult result = odonav::offline::run_offline(dataset, params);
    (void)odonav::offline::diagnose_run(dataset, params, result);
  } catch (const odonav::StreamInputError& e) {
    std::fprintf(stderr, "odonav-fuzz-offline_run: an accepted dataset was refused by the processing: %s\n", e.what());
    std::abort();
  } catch (const std::invalid_argument&) {
    // A parameter from meta.json the components refuse (e.g. a nominal K out of range): named, fine.
  }
  return 0;
}
