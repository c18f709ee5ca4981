// Throughput of odonav-offline's stages on a one-hour 100 Hz drive, in odometer epochs per second:
// read (CSV parsing and validation), process (calibration, every estimator side by side, two DR
// runs, conversion to output rows), write (the four CSV files), summary (evaluation against truth),
// and all of them in a row as the tool runs them.
//
// Dataset: --dataset=DIR, or $ODONAV_BENCH_DATASET, else the simulator's ring at 3600 s, seed 1
// (`odonav-simulator ring --duration-s 3600`), generated once into $TMPDIR/odonav-bench-ring3600.
// Outputs go to a temporary folder that is removed at the end. Rates are per second of CPU time
// of the process (user + system, so the kernel's share of reading and writing counts): on a shared,
// loaded machine that is the figure that does not depend on what the neighbours do; the wall time
// is printed beside it.
// Run: build/bin/odonav-bench-offline [--dataset=DIR] [Google Benchmark flags]
#include <benchmark/benchmark.h>

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <string>

#include "odonav/simulator/simulator.hpp"
#include "odonav/dataset.hpp"
#include "odonav/offline/offline_runner.hpp"
#include "odonav/offline/summary.hpp"

namespace {

namespace fs = std::filesystem;

std::string g_dataset_dir;
std::string g_out_dir;

// The dataset and what each stage needs from the previous one, made once.
struct Prepared {
  odonav::Dataset dataset;
  odonav::offline::OfflineParams params;
  odonav::results::OutputRows rows;
};

odonav::offline::OfflineParams params_for(const odonav::Dataset& d) {
  // As odonav-offline's defaults: lever arm and nominal K from meta.json.
  odonav::offline::OfflineParams p;
  if (d.meta.gnss_lever_arm_m) {
    p.dead_reckoning.lever_arm_body_m = d.meta.gnss_lever_arm_m;
    p.calibration.lever_arm_body_m = d.meta.gnss_lever_arm_m;
    p.identification.builder.lever_arm_body_m = d.meta.gnss_lever_arm_m;
  }
  p.dead_reckoning.nominal_k_m_per_pulse = d.meta.k_nominal_m_per_pulse.value_or(0.0125);
  return p;
}

const Prepared& prepared() {
  static const Prepared p = [] {
    Prepared out;
    out.dataset = odonav::read_dataset(g_dataset_dir, odonav::BadRowPolicy::kFail);
    out.params = params_for(out.dataset);
    out.rows = odonav::offline::to_output_rows(odonav::offline::run_offline(out.dataset, out.params),
                                               out.params.identification.estimator_name);
    return out;
  }();
  return p;
}

void set_rate(benchmark::State& state) {
  state.counters["epochs_per_s"] = benchmark::Counter(
      static_cast<double>(prepared().dataset.odometer.size()) * static_cast<double>(state.iterations()),
      benchmark::Counter::kIsRate);
  state.counters["epochs"] = static_cast<double>(prepared().dataset.odometer.size());
}

void BM_OfflineRead(benchmark::State& state) {
  prepared();
  for (auto _ : state) {
    const odonav::Dataset d = odonav::read_dataset(g_dataset_dir, odonav::BadRowPolicy::kFail);
    benchmark::DoNotOptimize(d.odometer.data());
  }
  set_rate(state);
}

void BM_OfflineProcess(benchmark::State& state) {
  const Prepared& p = prepared();
  for (auto _ : state) {
    const odonav::results::OutputRows rows = odonav::offline::to_output_rows(
        odonav::offline::run_offline(p.dataset, p.params), p.params.identification.estimator_name);
    benchmark::DoNotOptimize(rows.dead_reckoning.data());
  }
  set_rate(state);
}

void BM_OfflineWrite(benchmark::State& state) {
  const Prepared& p = prepared();
  for (auto _ : state) odonav::results::write_output_rows(g_out_dir, p.rows);
  set_rate(state);
}

void BM_OfflineSummary(benchmark::State& state) {
  const Prepared& p = prepared();
  odonav::offline::SummaryOptions options;
  options.dataset_name = "bench";
  for (auto _ : state) {
    const nlohmann::json s = odonav::offline::make_summary(p.dataset, p.rows, options);
    benchmark::DoNotOptimize(&s);
  }
  set_rate(state);
}

// Everything odonav-offline does with a dataset, in a row (its own coarse S/N, no --coarse-k-from).
void BM_OfflineTotal(benchmark::State& state) {
  prepared();
  odonav::offline::SummaryOptions options;
  options.dataset_name = "bench";
  for (auto _ : state) {
    const odonav::Dataset d = odonav::read_dataset(g_dataset_dir, odonav::BadRowPolicy::kFail);
    const odonav::offline::OfflineParams params = params_for(d);
    const odonav::results::OutputRows rows =
        odonav::offline::to_output_rows(odonav::offline::run_offline(d, params), params.identification.estimator_name);
    odonav::results::write_output_rows(g_out_dir, rows);
    const nlohmann::json s = odonav::offline::make_summary(d, rows, options);
    benchmark::DoNotOptimize(&s);
  }
  set_rate(state);
}

BENCHMARK(BM_OfflineRead)->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK(BM_OfflineProcess)->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK(BM_OfflineWrite)->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK(BM_OfflineSummary)->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK(BM_OfflineTotal)->Unit(benchmark::kMillisecond)->MinTime(2.0);

std::string temp_dir() {
  const char* t = std::getenv("TMPDIR");
  return t && *t ? t : "/tmp";
}

}  // namespace

int main(int argc, char** argv) {
  // Our own flag first; the rest goes to Google Benchmark.
  std::vector<char*> args;
  for (int i = 0; i < argc; ++i) {
    const std::string a = argv[i];
    if (a.rfind("--dataset=", 0) == 0)
      g_dataset_dir = a.substr(10);
    else
      args.push_back(argv[i]);
  }
  if (g_dataset_dir.empty() && std::getenv("ODONAV_BENCH_DATASET")) g_dataset_dir = std::getenv("ODONAV_BENCH_DATASET");
  try {
    if (g_dataset_dir.empty()) {
      g_dataset_dir = temp_dir() + "/odonav-bench-ring3600";
      if (!fs::exists(g_dataset_dir + "/odometer.csv")) {
        std::cerr << "odonav-bench-offline: simulating ring, 3600 s, seed 1 into " << g_dataset_dir << "\n";
        odonav::simulator::SimulationConfig cfg = odonav::simulator::scenario_config("ring");
        cfg.duration_s = 3600.0;
        odonav::write_dataset(g_dataset_dir, odonav::simulator::simulate(cfg));
      }
    }
    g_out_dir = temp_dir() + "/odonav-bench-offline-out-" + std::to_string(::getpid());
    fs::create_directories(g_out_dir);
  } catch (const std::exception& e) {
    std::cerr << "odonav-bench-offline: " << e.what() << "\n";
    return 1;
  }
  std::cerr << "odonav-bench-offline: dataset " << g_dataset_dir << "\n";
  int bench_argc = static_cast<int>(args.size());
  benchmark::Initialize(&bench_argc, args.data());
  int rc = 0;
  try {
    benchmark::RunSpecifiedBenchmarks();
  } catch (const std::exception& e) {
    std::cerr << "odonav-bench-offline: " << e.what() << "\n";
    rc = 1;
  }
  benchmark::Shutdown();
  std::error_code ec;
  fs::remove_all(g_out_dir, ec);
  return rc;
}
