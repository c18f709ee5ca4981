#pragma once
// The checkpoint text of the sensor streams a core buffers (odometer and attitude buffers, GNSS
// samples, optional values), shared by every core whose save_state() holds inputs taken in but not
// processed yet (DeadReckoner, SampleBuilder). Lines as checkpoint_value_list writes them: every
// double exact (hex), NaN and infinities kept. Middleware-free.
#include <cstddef>
#include <deque>
#include <optional>
#include <string>
#include <vector>

#include "odonav/checkpoint_file.hpp"
#include "odonav/sensor_samples.hpp"
#include "odonav/stream_buffers.hpp"

namespace odonav {

/// An optional value as a list of 0 or 1 value (checkpoint_value_list), and back: the line must hold
/// at most one value (CheckpointError naming the key otherwise).
std::vector<double> optional_state_values(const std::optional<double>& value);
std::optional<double> read_optional_state_value(CheckpointReader& reader, const std::string& key);

/// GNSS sample as kGnssStateValues doubles: t, lat, lon, h, ve, vn, vu, has pos_std, pos_std, has
/// vel_std, vel_std, fix. gnss_from_state_values throws CheckpointError for a non-integer fix.
inline constexpr std::size_t kGnssStateValues = 12;
void append_gnss_state_values(std::vector<double>& out, const GnssSample& g);
GnssSample gnss_from_state_values(const double* v);
/// A list of GNSS samples under `key`, and back.
std::string gnss_samples_state_line(const std::string& key, const std::deque<GnssSample>& samples);
std::deque<GnssSample> read_gnss_samples_state(CheckpointReader& reader, const std::string& key);

/// OdometerBuffer::State as the lines odometer_entries, odometer_last_accepted, odometer_rejected,
/// odometer_gate, odometer_last_t_s; read back in that order (CheckpointError naming the field).
std::string odometer_buffer_state_lines(const OdometerBuffer::State& state);
OdometerBuffer::State read_odometer_buffer_state(CheckpointReader& reader);

/// AttitudeBuffer::State as the lines attitude_entries, attitude_last_t_s, and back.
std::string attitude_buffer_state_lines(const AttitudeBuffer::State& state);
AttitudeBuffer::State read_attitude_buffer_state(CheckpointReader& reader);

/// StepHistory<Misalignment>::State as the lines <key> (t, heading, pitch per entry) and
/// <key>_last_t_s, and back.
std::string misalignment_history_state_lines(const std::string& key, const StepHistory<Misalignment>::State& state);
StepHistory<Misalignment>::State read_misalignment_history_state(CheckpointReader& reader, const std::string& key);

}  // namespace odonav
