// odonav-simulator: writes a simulated dataset directory (docs/DATASET.md) for a named scenario.
//
//   odonav-simulator <straight|ring|terrain|slow_robot|polar_north|south_pole|antimeridian> --out DIR [--seed N] [--gnss-rate 1|2|5|10|20] [--duration-s S] ...
//   odonav-simulator <scenario> --nmea FILE [--nmea-utc-epoch-s S] ...   the GNSS as NMEA 0183 (core/nmea.hpp)
//   (odonav-simulator --help lists every option; --config FILE reads `name = value` lines.)
//
// Exit codes: 0 written, 2 bad command line, 1 simulation or I/O failure.
#include <spdlog/spdlog.h>

#include <cstdint>
#include <filesystem>
#include <iostream>
#include <limits>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

#include "odonav/simulator/nmea.hpp"
#include "odonav/simulator/simulator.hpp"
#include "odonav/config.hpp"
#include "odonav/dataset.hpp"
#include "odonav/dataset_writer.hpp"
#include "odonav/logging.hpp"
#include "odonav/safe_output.hpp"

namespace {

// A simulated drive never replaces a recording: an existing dataset (any of its files present) or
// a non-empty directory that is not an odonav output directory is refused unless forced.
void check_dataset_destination(const std::string& dir, bool force) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!force && fs::is_directory(dir, ec)) {
    for (const char* name : {"odometer.csv", "gnss.csv", "ins.csv", "truth.csv", "meta.json"})
      if (fs::exists(fs::path(dir) / name, ec))
        throw odonav::OutputError("refusing to write into '" + dir + "': it already holds a dataset (" + name +
                                  "); choose a new directory or pass --force");
  }
  odonav::OutputPolicy policy;
  policy.force = force;
  const odonav::OutputDirectory checked(dir, policy);
}

}  // namespace

int main(int argc, char** argv) {
  const odonav::simulator::SimulationConfig base;  // defaults shown in the usage; the scenario may change some
  odonav::Options opts("odonav-simulator",
                       "Simulates a tracked vehicle (odometer, GNSS, INS, truth) on a named scenario and "
                       "writes a dataset directory (docs/DATASET.md). Deterministic for a given seed.");
  opts.add_positional("scenario", "straight, ring, terrain, slow_robot, polar_north, south_pole or antimeridian");
  opts.add_string("out", "",
                  "dataset directory to write (created if missing; never an existing dataset or a "
                  "non-empty foreign directory, see --force); required unless --nmea is given");
  opts.add_bool("force", false, "write into an existing dataset or non-empty directory (replacing its files)");
  opts.add_string("nmea", "",
                  "also (or only) write the GNSS as NMEA 0183 GGA, RMC, VTG and GST sentences, one fix "
                  "per GNSS row, to this file (for gpsfake / gpsd)");
  opts.add_double("nmea-utc-epoch-s", odonav::simulator::NmeaSettings{}.utc_epoch_s,
                  "--nmea: UTC of t = 0, s since 1970 (a fix at t is reported at this + t)", 0.0, 4e9);
  opts.add_int("seed", 1, "random seed of the sensor noise", 0, std::numeric_limits<int64_t>::max());
  opts.add_choice("gnss-rate", "default", {"default", "1", "2", "5", "10", "20"},
                  "GNSS rate, Hz (default: the scenario's, 10 Hz except slow_robot's 1 Hz)");
  opts.add_double("duration-s", 0.0,
                  "run length, s; more laps (or a longer road) are driven and the data cut "
                  "there (0: the scenario's natural length)",
                  0.0, 604800.0);
  opts.add_int("laps", base.laps, "laps of the ring/terrain course", 1, 10000);
  opts.add_double("standstill-end-s", base.standstill_end_s,
                  "standing still after the final stop, s (a drive that ends by braking to a standstill)", 0.0, 3600.0);
  opts.add_double("gnss-latency-s", 0.0, "GNSS time-stamp latency, s (stamp = measurement time + latency)", 0.0, 9.99);
  opts.add_double("k-true", base.k_true_m_per_pulse, "true scale factor at the start, m/pulse", 1e-5, 1.0);
  opts.add_double("misalignment-heading-deg", odonav::rad_to_deg(base.misalignment.heading_rad),
                  "odometer axis turned left of the INS forward axis, deg", -10.0, 10.0);
  opts.add_double("misalignment-pitch-deg", odonav::rad_to_deg(base.misalignment.pitch_rad),
                  "odometer axis pointing up relative to the INS forward axis, deg", -10.0, 10.0);
  opts.add_double("start-time-s", 0.0, "t of the first row, s", 0.0, 1e10);
  opts.add_string("log-level", "",
                  "trace, debug, info, warn, error, critical, off (default: ODONAV_LOG_LEVEL or info)");

  odonav::simulator::SimulationConfig cfg;
  std::string out_dir, nmea_path;
  odonav::simulator::NmeaSettings nmea;
  try {
    if (opts.parse(argc, argv) == odonav::ParseResult::kHelp) return 0;
    odonav::setup_logging("odonav-simulator", opts.get_string("log-level"));
    cfg = odonav::simulator::scenario_config(opts.get_string("scenario"));
    out_dir = opts.get_string("out");
    nmea_path = opts.get_string("nmea");
    nmea.utc_epoch_s = opts.get_double("nmea-utc-epoch-s");
    if (out_dir.empty() && nmea_path.empty())
      throw odonav::ConfigError("--out: a dataset directory is required (or --nmea FILE)");
    cfg.seed = static_cast<std::uint64_t>(opts.get_int("seed"));
    if (opts.get_string("gnss-rate") != "default") cfg.gnss_rate_hz = std::stod(opts.get_string("gnss-rate"));
    cfg.duration_s = opts.get_double("duration-s");
    if (opts.was_set("laps")) cfg.laps = static_cast<int>(opts.get_int("laps"));
    if (opts.was_set("standstill-end-s")) cfg.standstill_end_s = opts.get_double("standstill-end-s");
    cfg.gnss_latency_s = opts.get_double("gnss-latency-s");
    if (opts.was_set("k-true")) cfg.k_true_m_per_pulse = opts.get_double("k-true");
    if (opts.was_set("misalignment-heading-deg")) {
      cfg.misalignment.heading_rad = odonav::deg_to_rad(opts.get_double("misalignment-heading-deg"));
    }
    if (opts.was_set("misalignment-pitch-deg")) {
      cfg.misalignment.pitch_rad = odonav::deg_to_rad(opts.get_double("misalignment-pitch-deg"));
    }
    cfg.start_time_s = opts.get_double("start-time-s");
    odonav::simulator::validate(cfg);
  } catch (const std::exception& e) {  // ConfigError, unknown scenario, invalid config
    std::cerr << "odonav-simulator: " << e.what() << "\n(odonav-simulator --help for the usage)\n";
    return 2;
  }
  try {
    if (!out_dir.empty()) check_dataset_destination(out_dir, opts.get_bool("force"));
    // The samples go to the files as they are produced: memory does not grow with the drive.
    struct Sink : odonav::simulator::SampleSink {
      std::unique_ptr<odonav::DatasetWriter> dataset;
      std::unique_ptr<odonav::AtomicFile> nmea_file;
      odonav::simulator::NmeaSettings nmea;
      std::size_t fixes = 0;
      std::optional<odonav::TruthSample> first_truth, last_truth;
      void add(const odonav::TruthSample& s) override {
        if (!first_truth) first_truth = s;
        last_truth = s;
        if (dataset) dataset->add(s);
      }
      void add(const odonav::OdometerSample& s) override {
        if (dataset) dataset->add(s);
      }
      void add(const odonav::InsSample& s) override {
        if (dataset) dataset->add(s);
      }
      void add(const odonav::GnssSample& s) override {
        if (dataset) dataset->add(s);
        if (nmea_file) {
          // One fix per GNSS row, at the GNSS rate; CR LF ends each sentence as NMEA 0183 requires.
          for (const std::string& sentence : odonav::simulator::nmea_sentences(s, nmea)) {
            nmea_file->write(sentence);
            nmea_file->write("\r\n", 2);
          }
          ++fixes;
        }
      }
    } sink;
    sink.nmea = nmea;
    if (!nmea_path.empty()) sink.nmea_file = std::make_unique<odonav::AtomicFile>(nmea_path);
    if (!out_dir.empty())
      sink.dataset = std::make_unique<odonav::DatasetWriter>(out_dir, odonav::simulator::dataset_writer_options(cfg));
    const odonav::DatasetMeta meta = odonav::simulator::simulate(cfg, sink);
    if (sink.nmea_file) {
      sink.nmea_file->commit();
      spdlog::info("wrote {}: {} fixes as NMEA (UTC of t=0: {} s)", nmea_path, sink.fixes, nmea.utc_epoch_s);
    }
    if (!sink.dataset) return 0;
    sink.dataset->finish(meta);
    const odonav::DatasetRowCounts rows = sink.dataset->rows();
    spdlog::info("wrote {} ({}, seed {}): {:.2f} s, {:.1f} m; rows: {} odometer, {} gnss, {} ins, {} truth", out_dir,
                 cfg.scenario, cfg.seed, sink.last_truth->t_s - sink.first_truth->t_s, sink.last_truth->distance_m,
                 rows.odometer, rows.gnss, rows.ins, rows.truth);
  } catch (const std::exception& e) {
    std::cerr << "odonav-simulator: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
