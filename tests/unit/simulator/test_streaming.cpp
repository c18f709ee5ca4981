// The streaming simulator and writer: simulate(config, sink) into a DatasetWriter gives the files
// that simulate(config) + write_dataset give, byte for byte; the samples arrive in time order; the
// writer's memory stays at its fixed buffers along the drive.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <unistd.h>

#include "odonav/simulator/simulator.hpp"
#include "odonav/dataset.hpp"
#include "odonav/dataset_writer.hpp"
#include "scratch_dir.hpp"

using namespace odonav;
using namespace odonav::simulator;

namespace {

namespace fs = std::filesystem;

std::vector<std::string> file_names(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

// Writes every sample to a DatasetWriter and records the largest buffer it held.
struct WriterSink : SampleSink {
  explicit WriterSink(DatasetWriter& w) : writer(w) {}
  DatasetWriter& writer;
  std::size_t max_buffer_bytes = 0;
  template <class Sample>
  void put(const Sample& s) {
    writer.add(s);
    max_buffer_bytes = std::max(max_buffer_bytes, writer.buffer_capacity_bytes());
  }
  void add(const TruthSample& s) override { put(s); }
  void add(const OdometerSample& s) override { put(s); }
  void add(const InsSample& s) override { put(s); }
  void add(const GnssSample& s) override { put(s); }
};

// Streams `config` to one directory and writes simulate(config) with write_dataset to another;
// every file must be the same bytes.
void expect_streamed_equals_collected(const SimulationConfig& config, const std::string& name) {
  const test::ScratchDir scratch;
  const fs::path streamed = scratch.path() / "streamed", collected = scratch.path() / "collected";
  DatasetWriter writer(streamed.string(), dataset_writer_options(config));
  WriterSink sink(writer);
  writer.finish(simulate(config, sink));
  write_dataset(collected.string(), simulate(config));

  const std::vector<std::string> names = file_names(collected);
  EXPECT_EQ(file_names(streamed), names);
  EXPECT_NE(std::find(names.begin(), names.end(), "truth.csv"), names.end());
  for (const std::string& f : names) {
    const std::string a = test::read_text(streamed / f), b = test::read_text(collected / f);
    EXPECT_EQ(a.size(), b.size()) << name << " " << f;
    EXPECT_TRUE(a == b) << name << " " << f << " differs";
  }
  // The writer's memory did not follow the drive (several MB of text were written).
  EXPECT_GT(fs::file_size(streamed / "truth.csv"), 4u * 1000 * 1000);
  EXPECT_LE(sink.max_buffer_bytes, 4u * 2u * (64u * 1024u + 1024u));
}

}  // namespace

TEST(StreamingSimulator, TerrainWithGnssLatencyStreamsTheFilesOfSimulatePlusWriteDataset) {
  // K steps, slip, an outage, velocity outliers, 10 Hz GNSS stamped 0.2 s late.
  SimulationConfig config = scenario_config("terrain");
  config.gnss_latency_s = 0.2;
  config.seed = 8;
  expect_streamed_equals_collected(config, "terrain");
}

TEST(StreamingSimulator, SlowRobotWithoutInsStreamsTheFilesOfSimulatePlusWriteDataset) {
  // Reversing manoeuvres (direction -1), 50 Hz odometer, 1 Hz GNSS, no ins.csv.
  expect_streamed_equals_collected(scenario_config("slow_robot"), "slow_robot");
}

TEST(StreamingSimulator, SamplesArriveInStampOrderTruthOdometerInsGnssAtEqualStamps) {
  struct OrderSink : SampleSink {
    double last_t_s = -1.0;
    int last_kind = 0;
    std::size_t n = 0, out_of_order = 0, gnss = 0;
    void put(double t_s, int kind) {
      if (t_s < last_t_s || (t_s == last_t_s && kind < last_kind)) ++out_of_order;
      last_t_s = t_s;
      last_kind = kind;
      ++n;
    }
    void add(const TruthSample& s) override { put(s.t_s, 0); }
    void add(const OdometerSample& s) override { put(s.t_s, 1); }
    void add(const InsSample& s) override { put(s.t_s, 2); }
    void add(const GnssSample& s) override {
      put(s.t_s, 3);
      ++gnss;
    }
  };
  for (double latency_s : {0.0, 0.25}) {
    SimulationConfig config = scenario_config("straight");
    config.duration_s = 60.0;
    config.gnss_latency_s = latency_s;
    OrderSink sink;
    simulate(config, sink);
    const Dataset ds = simulate(config);
    EXPECT_EQ(sink.out_of_order, 0u) << "latency " << latency_s;
    EXPECT_EQ(sink.gnss, ds.gnss.size());  // also the rows stamped after the last truth row
    EXPECT_EQ(sink.n, ds.truth.size() + ds.odometer.size() + ds.ins.size() + ds.gnss.size());
  }
}
