// The checkpoint text of buffered sensor streams (stream_state_text.hpp).
#include "odonav/stream_state_text.hpp"

#include <utility>

namespace odonav {

namespace {
using Values = std::vector<double>;
constexpr std::size_t kMany = 10000000;

void append(Values& out, std::initializer_list<double> v) { out.insert(out.end(), v.begin(), v.end()); }

void append_odometer_entry(Values& out, const OdometerBuffer::Entry& e) {
  append(out,
         {e.t_s, static_cast<double>(e.count), static_cast<double>(e.raw_pulses), static_cast<double>(e.direction)});
}
OdometerBuffer::Entry odometer_entry_of(const double* v) {
  OdometerBuffer::Entry e;
  e.t_s = v[0];
  e.count = static_cast<int64_t>(v[1]);
  e.raw_pulses = static_cast<uint32_t>(v[2]);
  e.direction = static_cast<int>(v[3]);
  if (static_cast<double>(e.count) != v[1] || static_cast<double>(e.raw_pulses) != v[2] || e.direction < -1 ||
      e.direction > 1)
    throw CheckpointError("an odometer entry has a bad count, pulses or direction");
  return e;
}
}  // namespace

std::vector<double> optional_state_values(const std::optional<double>& value) {
  return value ? Values{*value} : Values{};
}

std::optional<double> read_optional_state_value(CheckpointReader& reader, const std::string& key) {
  const Values v = reader.value_list(key);
  if (v.size() > 1) throw CheckpointError("field '" + key + "' holds more than one value");
  return v.empty() ? std::nullopt : std::optional<double>(v[0]);
}

void append_gnss_state_values(std::vector<double>& out, const GnssSample& g) {
  append(out, {g.t_s, g.position.lat_rad, g.position.lon_rad, g.position.height_m, g.vel_enu_mps.x(), g.vel_enu_mps.y(),
               g.vel_enu_mps.z(), g.pos_std_m ? 1.0 : 0.0, g.pos_std_m.value_or(0.0), g.vel_std_mps ? 1.0 : 0.0,
               g.vel_std_mps.value_or(0.0), static_cast<double>(g.fix)});
}

GnssSample gnss_from_state_values(const double* v) {
  GnssSample g;
  g.t_s = v[0];
  g.position = Geodetic{v[1], v[2], v[3]};
  g.vel_enu_mps = Eigen::Vector3d(v[4], v[5], v[6]);
  if (v[7] != 0.0) g.pos_std_m = v[8];
  if (v[9] != 0.0) g.vel_std_mps = v[10];
  g.fix = static_cast<int>(v[11]);
  if (static_cast<double>(g.fix) != v[11]) throw CheckpointError("a GNSS sample's fix quality is not an integer");
  return g;
}

std::string gnss_samples_state_line(const std::string& key, const std::deque<GnssSample>& samples) {
  Values v;
  for (const GnssSample& g : samples) append_gnss_state_values(v, g);
  return checkpoint_value_list(key, v);
}

std::deque<GnssSample> read_gnss_samples_state(CheckpointReader& reader, const std::string& key) {
  const Values v = reader.value_list(key, kGnssStateValues, kGnssStateValues * kMany);
  std::deque<GnssSample> out;
  for (std::size_t i = 0; i < v.size(); i += kGnssStateValues) out.push_back(gnss_from_state_values(&v[i]));
  return out;
}

std::string odometer_buffer_state_lines(const OdometerBuffer::State& od) {
  std::string s;
  Values v;
  for (const auto& e : od.entries) append_odometer_entry(v, e);
  s += checkpoint_value_list("odometer_entries", v);
  v.clear();
  if (od.last_accepted) append_odometer_entry(v, *od.last_accepted);
  s += checkpoint_value_list("odometer_last_accepted", v);
  v.clear();
  if (od.rejected) append_odometer_entry(v, *od.rejected);
  s += checkpoint_value_list("odometer_rejected", v);
  s += checkpoint_value_list("odometer_gate", {od.last_rate_pulses_per_s, static_cast<double>(od.jumps_rejected),
                                               static_cast<double>(od.rebases)});
  s += checkpoint_value_list("odometer_last_t_s", optional_state_values(od.last_t_s));
  return s;
}

OdometerBuffer::State read_odometer_buffer_state(CheckpointReader& r) {
  OdometerBuffer::State od;
  Values v = r.value_list("odometer_entries", 4, 4 * kMany);
  for (std::size_t i = 0; i < v.size(); i += 4) od.entries.push_back(odometer_entry_of(&v[i]));
  v = r.value_list("odometer_last_accepted", 4, 4);
  if (!v.empty()) od.last_accepted = odometer_entry_of(v.data());
  v = r.value_list("odometer_rejected", 4, 4);
  if (!v.empty()) od.rejected = odometer_entry_of(v.data());
  v = r.value_list("odometer_gate", 3, 3);
  if (v.size() != 3) throw CheckpointError("field 'odometer_gate' does not hold 3 values");
  od.last_rate_pulses_per_s = v[0];
  od.jumps_rejected = static_cast<uint64_t>(v[1]);
  od.rebases = static_cast<uint64_t>(v[2]);
  od.last_t_s = read_optional_state_value(r, "odometer_last_t_s");
  return od;
}

std::string attitude_buffer_state_lines(const AttitudeBuffer::State& at) {
  Values v;
  for (const auto& e : at.entries)
    append(v, {e.t_s, e.attitude.heading_rad, e.attitude.pitch_rad, e.attitude.roll_rad});
  return checkpoint_value_list("attitude_entries", v) +
         checkpoint_value_list("attitude_last_t_s", optional_state_values(at.last_t_s));
}

AttitudeBuffer::State read_attitude_buffer_state(CheckpointReader& r) {
  AttitudeBuffer::State at;
  const Values v = r.value_list("attitude_entries", 4, 4 * kMany);
  for (std::size_t i = 0; i < v.size(); i += 4) at.entries.push_back({v[i], Attitude{v[i + 1], v[i + 2], v[i + 3]}});
  at.last_t_s = read_optional_state_value(r, "attitude_last_t_s");
  return at;
}

std::string misalignment_history_state_lines(const std::string& key, const StepHistory<Misalignment>::State& m) {
  Values v;
  for (const auto& [t, e] : m.entries) append(v, {t, e.heading_rad, e.pitch_rad});
  return checkpoint_value_list(key, v) + checkpoint_value_list(key + "_last_t_s", optional_state_values(m.last_t_s));
}

StepHistory<Misalignment>::State read_misalignment_history_state(CheckpointReader& r, const std::string& key) {
  StepHistory<Misalignment>::State m;
  const Values v = r.value_list(key, 3, 3 * kMany);
  for (std::size_t i = 0; i < v.size(); i += 3) m.entries.emplace_back(v[i], Misalignment{v[i + 1], v[i + 2]});
  m.last_t_s = read_optional_state_value(r, key + "_last_t_s");
  return m;
}

}  // namespace odonav
