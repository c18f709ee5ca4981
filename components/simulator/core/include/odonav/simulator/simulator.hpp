#pragma once
// The seeded tracked-vehicle simulator: drives a course, and produces what the odometer, the GNSS
// receiver and the INS would report, plus the ground truth, one sample at a time (SampleSink) or as
// an odonav::Dataset in memory (docs/DATASET.md).
//
// Every field below is a default a user may change; components/simulator/README.md lists them with
// their units and the reasoning behind each value. SI inside: radians, metres, seconds, m/s.
// Deterministic: the same config (seed included) gives a bit-identical dataset with libstdc++.
#include <Eigen/Dense>
#include <cstdint>
#include <string>
#include <vector>

#include "odonav/simulator/course.hpp"
#include "odonav/defaults.hpp"
#include "odonav/dataset.hpp"
#include "odonav/dataset_writer.hpp"
#include "odonav/frames.hpp"
#include "odonav/geodesy.hpp"

namespace odonav::simulator {

/// The base scale factor K is multiplied by `factor` from time t_s on (seconds after start_time_s):
/// a road-surface change or track repair.
struct KStep {
  double t_s = 0.0;
  double factor = 1.0;  ///< > 0; 1.03 is +3 %.
};

/// GNSS outage [start_s, end_s), seconds after start_time_s: rows with fix 0.
struct GnssOutage {
  double start_s = 0.0;
  double end_s = 0.0;
};

/// How the vehicle moves along the road.
enum class DriveKind {
  kProfile,    ///< one way, the driver's SpeedProfile (start, drive, stop).
  kStopAndGo,  ///< the slow robot: legs at 0.6-3 m/s, a stop after each, a reversing manoeuvre
               ///< after every third (slow_robot_plan in simulator.cpp); repeated to fill duration_s.
};

enum class CourseKind {
  kStraight,        ///< one straight road of straight_length_m at straight_heading_rad.
  kTrainingGround,  ///< the closed lap of Course::training_ground(), driven `laps` times clockwise.
};

struct SimulationConfig {
  // --- identity ---
  std::string scenario = "straight";
  std::string description = "straight calibration run";
  std::string vehicle_id = "sim-tracked-01";
  std::uint64_t seed = 1;

  // --- course and driving ---
  CourseKind course = CourseKind::kStraight;
  double straight_length_m = 1800.0;               ///< straight road length (kStraight), m.
  double straight_heading_rad = 30.0 * kDegToRad;  ///< azimuth of the straight road.
  double straight_speed_mps = 10.0;                ///< target speed on the straight road, m/s.
  int laps = 2;                                    ///< laps of a closed course (>= 1).
  /// > 0: make the run this long (seconds): more laps (or a longer straight road) are driven and
  /// the data are cut at start_time_s + duration_s (the vehicle may still be moving). 0: natural
  /// length (laps or road, with the final stop).
  double duration_s = 0.0;
  double standstill_start_s = 5.0;  ///< standing still before driving off, s.
  double standstill_end_s = 5.0;    ///< standing still after the stop, s.
  DriverLimits driver;
  DriveKind drive = DriveKind::kProfile;
  /// false: the course's headings are azimuths from the local north at the vehicle, integrated on
  /// latitude and longitude (a straight road keeps its azimuth: a rhumb line, which spirals into a
  /// pole). true: they are taken from a reference direction carried along the road (parallel
  /// transport, true north at the start), so a straight road is a geodesic wherever it runs, across
  /// longitude 180 and past a pole; the truth is integrated in ECEF, and the INS heading, the
  /// velocity and the lever arm use the azimuth from true north at the vehicle's position.
  bool geodesic_course = false;
  double road_grade = 0.01;              ///< constant slope of the straight road (dh/ds); 0 on laps.
  std::vector<Undulation> hills;         ///< height undulations (amplitude in m).
  std::vector<Undulation> cross_slopes;  ///< ground roll undulations (amplitude in rad).
  /// Body roll on the suspension in turns, rad per m/s^2 of lateral acceleration (outward roll).
  double roll_per_lateral_accel_rad = 0.6 * kDegToRad;
  double roll_time_constant_s = 0.4;  ///< suspension lag of the roll, s.

  // --- place and time ---
  Geodetic start{52.5 * kDegToRad, 13.4 * kDegToRad, 80.0};  ///< INS reference point at the start.
  double start_time_s = 0.0;                                 ///< t of the first row (the dataset's time base), s.
  double truth_rate_hz = 100.0;  ///< truth.csv rate; odometer/INS/GNSS rates must divide it.
  int substeps = 10;             ///< internal integration steps per truth step.

  // --- odometer ---
  double odometer_rate_hz = 100.0;
  /// Nominal K of a sprocket pulse counter: pi * 0.6526 m pitch diameter / 164 pulses per rev.
  double k_nominal_m_per_pulse = kDefaultNominalK_m_per_pulse;
  double k_true_m_per_pulse =
      kDefaultNominalK_m_per_pulse * 1.015;  ///< true K at the start (+1.5 %: worn, stretched track).
  std::vector<KStep> k_steps;
  /// Counter value at the start; 2^32 - 10^5 so every default run crosses the wrap.
  std::uint32_t counter_start = 4294967296ull - 100000ull;
  /// Track slip in turns: extra pulses per metre = gain * (|yaw rate| - threshold), capped.
  double turn_slip_per_radps = 0.0;
  double turn_slip_threshold_radps = 0.05;
  double turn_slip_max = 0.0;

  // --- installation ---
  Misalignment misalignment{0.8 * kDegToRad, -0.5 * kDegToRad};  ///< odometer axis w.r.t. INS body.
  Eigen::Vector3d lever_arm_m{-0.5, 0.3, 2.2};  ///< GNSS antenna from the INS reference point, body FLU, m.

  // --- GNSS ---
  double gnss_rate_hz = 10.0;
  double gnss_latency_s = 0.0;         ///< stamp = measurement time + latency, s (>= 0).
  double gnss_pos_gm_std_m = 1.4;      ///< Gauss-Markov (correlated) part, per horizontal axis, m.
  double gnss_pos_gm_tau_s = 60.0;     ///< its correlation time, s.
  double gnss_pos_white_std_m = 0.54;  ///< white part, per horizontal axis, m.
  double gnss_vertical_factor = 1.5;   ///< vertical position noise = factor * horizontal.
  double gnss_vel_std_mps = 0.05;      ///< white, per horizontal axis (ENU), m/s.
  double gnss_vel_up_std_mps = 0.03;   ///< white, up axis, m/s.
  std::vector<GnssOutage> gnss_outages;
  int gnss_velocity_outliers = 0;  ///< isolated epochs with a large horizontal velocity error.
  double gnss_outlier_min_mps = 3.0;
  double gnss_outlier_max_mps = 10.0;

  // --- INS ---
  bool has_ins = true;  ///< false: no ins.csv (a vehicle without INS).
  double ins_rate_hz = 100.0;
  double ins_heading_bias_rad = 0.02 * kDegToRad;
  double ins_heading_noise_rad = 0.01 * kDegToRad;  ///< white, one sigma.
  double ins_tilt_noise_rad = 0.005 * kDegToRad;    ///< white, pitch and roll, one sigma.
};

/// Names of the built-in scenarios: "straight", "ring", "terrain", "slow_robot", "polar_north",
/// "south_pole", "antimeridian".
std::vector<std::string> scenario_names();

/// The configuration of a named scenario (see README.md). Throws std::invalid_argument listing the
/// known names for an unknown one.
SimulationConfig scenario_config(const std::string& name);

/// Checks every field; throws std::invalid_argument naming the field and the valid range.
void validate(const SimulationConfig& config);

/// Receives the simulated samples one at a time (simulate(config, sink)).
class SampleSink {
 public:
  virtual ~SampleSink() = default;
  virtual void add(const TruthSample& sample) = 0;
  virtual void add(const OdometerSample& sample) = 0;
  virtual void add(const InsSample& sample) = 0;  ///< never called when config.has_ins is false.
  virtual void add(const GnssSample& sample) = 0;
};

/// Runs the simulation, handing every sample to `sink` as it is produced, and returns the meta
/// (meta.raw_json is the whole meta.json, with a "simulation" object: scenario, seed, k_steps,
/// gnss_outages, outlier epochs, lever_arm_m, gnss_latency_s, ins_heading_bias_deg, laps).
/// Order: by stamp t_s; at equal stamps truth, odometer, INS, then GNSS (a GNSS row is stamped its
/// measurement time plus gnss_latency_s and arrives when the truth reaches that stamp; rows stamped
/// after the last truth row arrive at the end). Each sensor's rows are in time order.
/// Memory does not grow with the length of the drive: three truth rows, the GNSS rows waiting for
/// their stamp (latency times rate), the outlier candidates as runs of epochs, and the speed
/// profile, whose grid is generated as it is read (SpeedProfile). Only the slow robot's stop-and-go
/// plan is a list of phases that lengthens with the drive (a few kB per hour).
/// Exceptions thrown by the sink propagate (the samples so far have been delivered); throws
/// std::invalid_argument on a bad config before the first sample.
DatasetMeta simulate(const SimulationConfig& config, SampleSink& sink);

/// The same simulation collected into memory: simulate(config, sink) into a Dataset.
Dataset simulate(const SimulationConfig& config);

/// The columns and files of a simulated dataset (every GNSS row has pos_std_m and vel_std_mps, the
/// INS reports attitude only, every truth column is filled), for writing it with DatasetWriter as
/// it is produced: the files are those write_dataset writes for simulate(config).
DatasetWriterOptions dataset_writer_options(const SimulationConfig& config);

}  // namespace odonav::simulator
