// Reading a dataset whole (read_dataset) against row by row (DatasetStream + TruthStream): wall time,
// rows and peak RSS of the process. One mode per run, so each run's peak RSS is its own:
//   odonav-bench-dataset-read whole|stream DIR
// The dataset of a drive of any length: odonav-simulator ring --out DIR --duration-s 3600.
#include <sys/resource.h>

#include <chrono>
#include <cstdio>
#include <cstring>
#include <string>

#include "odonav/dataset.hpp"
#include "odonav/dataset_stream.hpp"

namespace {

// A sum over every row, printed, so neither reader's work can be optimised away and both can be
// compared at a glance.
struct Tally {
  std::size_t rows = 0;
  double t_sum_s = 0.0;
  void add(double t_s) {
    ++rows;
    t_sum_s += t_s;
  }
};

Tally read_whole(const std::string& dir) {
  const odonav::Dataset d = odonav::read_dataset(dir, odonav::BadRowPolicy::kFail);
  Tally tally;
  for (const auto& s : d.odometer) tally.add(s.t_s);
  for (const auto& s : d.gnss) tally.add(s.t_s);
  for (const auto& s : d.ins) tally.add(s.t_s);
  for (const auto& s : d.truth) tally.add(s.t_s);
  return tally;
}

Tally read_stream(const std::string& dir) {
  Tally tally;
  odonav::DatasetStream stream(dir, odonav::BadRowPolicy::kFail);
  while (const std::optional<odonav::DatasetEvent> event = stream.next()) tally.add(event->t_s);
  odonav::TruthStream truth(dir, odonav::BadRowPolicy::kFail);
  while (const std::optional<odonav::TruthSample> row = truth.next()) tally.add(row->t_s);
  return tally;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3 || (std::strcmp(argv[1], "whole") != 0 && std::strcmp(argv[1], "stream") != 0)) {
    std::fprintf(stderr, "usage: %s whole|stream DATASET_DIR\n", argv[0]);
    return 2;
  }
  const bool whole = std::strcmp(argv[1], "whole") == 0;
  const auto start = std::chrono::steady_clock::now();
  try {
    const Tally tally = whole ? read_whole(argv[2]) : read_stream(argv[2]);
    const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    std::printf("%s: %zu rows (t sum %.6f) in %.3f s, %.0f rows/s, peak RSS %ld MB\n", argv[1], tally.rows,
                tally.t_sum_s, wall_s, tally.rows / wall_s, usage.ru_maxrss / 1024);
  } catch (const odonav::DatasetError& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
  return 0;
}
