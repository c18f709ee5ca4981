#pragma once
// odonav-gateway's middleware-free core, part 1: where the sensor data comes from.
//
// A source is `sim:<scenario>` (the simulator, in-process) or `replay:<dataset dir>` (a dataset
// directory, docs/DATASET.md). Either way the result is an odonav::Dataset holding exactly what
// read_dataset() gives for the dataset files of that drive, so the pipeline fed by the gateway and
// odonav-offline reading `odonav-simulator <scenario> --out DIR` see bit-identical inputs.
// The three sensor streams are then merged into one time-ordered list of events (interleave()).
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "odonav/dataset.hpp"

namespace odonav::gateway {

/// What `--source` names.
struct SourceSpec {
  enum class Kind { kSimulator, kReplay, kCandump };
  Kind kind = Kind::kSimulator;
  /// scenario name (kSimulator), dataset directory (kReplay), candump -L log file (kCandump;
  /// "-" is standard input, read live by node/live_gateway.hpp, not by load_source).
  std::string name;
};

/// Parses "sim:<scenario>", "replay:<dataset dir>" or "candump:<file|->". An empty scenario means "terrain".
/// Throws ConfigError (config.hpp) naming --source and the accepted forms otherwise.
SourceSpec parse_source(const std::string& text);

/// Settings of the simulator source.
struct SimulatorSettings {
  std::uint64_t seed = 1;   ///< noise seed, as odonav-simulator --seed.
  double duration_s = 0.0;  ///< > 0: run length in seconds, as odonav-simulator --duration-s; 0 = natural length.
};

/// Loads the dataset of a source.
/// - kSimulator: simulate(scenario_config(name)) with the seed and duration, then as_recorded().
///   Throws ConfigError for an unknown scenario or an invalid duration (the message lists the names).
/// - kReplay: read_dataset(name, policy, report). Throws DatasetError naming file, line and column.
/// - kCandump: not here (the CAN configuration is needed: load_candump_source, candump_source.hpp).
Dataset load_source(const SourceSpec& source, const SimulatorSettings& sim, BadRowPolicy policy,
                    DatasetReadReport* report = nullptr);

/// The degree value d that the dataset files hold for an angle of `angle_rad` radians: the double
/// nearest rad_to_deg(angle_rad) whose deg_to_rad(d) gives angle_rad back exactly, when one exists
/// within 16 ulps (as write_dataset chooses it); else the closest one found. Any finite angle.
/// Why: a message carrying degrees (GnssFix latitude/longitude) is converted back with deg_to_rad
/// by its consumers; sending this d makes them compute the very radians read_dataset computes.
double recorded_degrees(double angle_rad);

/// The angle as the dataset files give it back: deg_to_rad(recorded_degrees(angle_rad)) (equal to
/// angle_rad for about 91 % of arbitrary doubles, 1 ulp away otherwise).
inline double recorded_radians(double angle_rad) { return deg_to_rad(recorded_degrees(angle_rad)); }

/// The dataset as write_dataset + read_dataset would give it back: every GNSS, INS and truth
/// angle replaced by recorded_radians(). Everything else already round-trips exactly (shortest
/// round-trip decimal form). Used on simulated data so the gateway publishes what odonav-simulator writes.
Dataset as_recorded(Dataset dataset);

/// One sensor sample to publish: which stream and its index in that stream of the dataset.
struct SensorEvent {
  enum class Stream { kOdometer = 0, kIns = 1, kGnss = 2 };
  double t_s = 0.0;  ///< sample (event) time, s on the dataset's time base.
  Stream stream = Stream::kOdometer;
  std::size_t index = 0;
};

/// Every odometer, INS and GNSS sample of `dataset` in time order. Ties (same t_s) are ordered
/// odometer, INS, GNSS, and within a stream by file order, so the order is fully determined.
std::vector<SensorEvent> interleave(const Dataset& dataset);

}  // namespace odonav::gateway
