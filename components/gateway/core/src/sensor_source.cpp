#include "odonav/gateway/sensor_source.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "odonav/simulator/simulator.hpp"
#include "odonav/config.hpp"

namespace odonav::gateway {

SourceSpec parse_source(const std::string& text) {
  const auto colon = text.find(':');
  const std::string kind = colon == std::string::npos ? text : text.substr(0, colon);
  const std::string name = colon == std::string::npos ? std::string() : text.substr(colon + 1);
  SourceSpec s;
  if (kind == "sim" && colon != std::string::npos) {
    s.kind = SourceSpec::Kind::kSimulator;
    s.name = name.empty() ? "terrain" : name;
    return s;
  }
  if (kind == "replay" && colon != std::string::npos && !name.empty()) {
    s.kind = SourceSpec::Kind::kReplay;
    s.name = name;
    return s;
  }
  if (kind == "candump" && colon != std::string::npos && !name.empty()) {
    s.kind = SourceSpec::Kind::kCandump;
    s.name = name;
    return s;
  }
  throw ConfigError("--source: '" + text +
                    "' is neither sim:<scenario> (e.g. sim:terrain), replay:<dataset dir> nor candump:<log file|->");
}

Dataset load_source(const SourceSpec& source, const SimulatorSettings& sim, BadRowPolicy policy,
                    DatasetReadReport* report) {
  if (source.kind == SourceSpec::Kind::kReplay) return read_dataset(source.name, policy, report);
  if (source.kind == SourceSpec::Kind::kCandump)
    throw std::invalid_argument("load_source: a candump source is loaded by load_candump_source");
  simulator::SimulationConfig cfg;
  try {
    cfg = simulator::scenario_config(source.name);
    cfg.seed = sim.seed;
    cfg.duration_s = sim.duration_s;
    simulator::validate(cfg);
  } catch (const std::invalid_argument& e) {
    throw ConfigError("--source sim:" + source.name + ": " + e.what());
  }
  return as_recorded(simulator::simulate(cfg));
}

double recorded_degrees(double angle_rad) { return exact_degrees_of(angle_rad); }

namespace {
void record_attitude(Attitude& a) {
  a.heading_rad = recorded_radians(a.heading_rad);
  a.pitch_rad = recorded_radians(a.pitch_rad);
  a.roll_rad = recorded_radians(a.roll_rad);
}
void record_position(Geodetic& p) {
  p.lat_rad = recorded_radians(p.lat_rad);
  p.lon_rad = recorded_radians(p.lon_rad);
}
}  // namespace

Dataset as_recorded(Dataset d) {
  for (GnssSample& g : d.gnss) record_position(g.position);
  for (InsSample& i : d.ins) record_attitude(i.attitude);
  for (TruthSample& t : d.truth) {
    record_position(t.position);
    record_attitude(t.attitude);
  }
  return d;
}

std::vector<SensorEvent> interleave(const Dataset& d) {
  std::vector<SensorEvent> events;
  events.reserve(d.odometer.size() + d.ins.size() + d.gnss.size());
  for (std::size_t i = 0; i < d.odometer.size(); ++i)
    events.push_back({d.odometer[i].t_s, SensorEvent::Stream::kOdometer, i});
  for (std::size_t i = 0; i < d.ins.size(); ++i) events.push_back({d.ins[i].t_s, SensorEvent::Stream::kIns, i});
  for (std::size_t i = 0; i < d.gnss.size(); ++i) events.push_back({d.gnss[i].t_s, SensorEvent::Stream::kGnss, i});
  std::sort(events.begin(), events.end(), [](const SensorEvent& a, const SensorEvent& b) {
    if (a.t_s != b.t_s) return a.t_s < b.t_s;
    if (a.stream != b.stream) return static_cast<int>(a.stream) < static_cast<int>(b.stream);
    return a.index < b.index;
  });
  return events;
}

}  // namespace odonav::gateway
